// libFuzzer target: the indicating-system cycle-table importer (cli::formats::parse_cycle_table, then
// cycle_table_to_run and to_recording as `noisemon import --cycles-table` does). A table it cannot use must be
// refused with an error naming the file.
#include <cmath>
#include <exception>
#include <string_view>

#include "cli/formats/cycle_table.hpp"
#include "cli/formats/recording.hpp"
#include "fuzz_util.hpp"

using noisemon::fuzz::fail;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string file = "table.txt";
  noisemon::cli::formats::CycleTable table;
  try {
    table =
        noisemon::cli::formats::parse_cycle_table(std::string_view(reinterpret_cast<const char*>(data), size), file);
  } catch (const std::exception& e) {
    noisemon::fuzz::require_names(e.what(), file);
    return 0;
  }
  // What an accepted table promises (cli/formats/cycle_table.hpp).
  const std::size_t rows = table.crank_deg.size();
  if (rows < 2 || table.cycles_bar.empty()) fail("accepted an empty table");
  for (std::size_t i = 0; i < rows; ++i)
    if (!std::isfinite(table.crank_deg[i]) || (i > 0 && !(table.crank_deg[i] > table.crank_deg[i - 1])))
      fail("crank angle not finite and strictly increasing");
  for (const auto& cycle : table.cycles_bar) {
    if (cycle.size() != rows) fail("a cycle column of another length than the crank column");
    for (double p : cycle)
      if (!std::isfinite(p)) fail("non-finite pressure");
  }

  noisemon::cli::formats::CycleTableOptions options;
  options.speed_rpm = 6000;  // fast: fewer 40 kHz frames for the resampler, the same parsing and conversion
  options.condition.name = "fuzz";
  try {
    const auto conversion = noisemon::cli::formats::cycle_table_to_run(table, options, file);
    const auto& run = conversion.run;
    if (run.crank_deg.size() != run.time_s.size() || run.pressure_pa.size() != run.time_s.size())
      fail("run columns of different lengths");
    for (std::size_t i = 1; i < run.crank_deg.size(); ++i)
      if (!(run.crank_deg[i] > run.crank_deg[i - 1]) || !(run.time_s[i] > run.time_s[i - 1]))
        fail("converted crank angle or time not strictly increasing");
    const auto rec = noisemon::cli::formats::to_recording(run, 1'700'000'000'000'000);
    if (rec.crank_deg.size() != rec.frames()) fail("recording streams of different lengths");
    for (double p : rec.pressure_pa)
      if (!std::isfinite(p)) fail("non-finite pressure in the recording");
  } catch (const std::exception& e) {
    noisemon::fuzz::require_names(e.what(), file);
  }
  return 0;
}
