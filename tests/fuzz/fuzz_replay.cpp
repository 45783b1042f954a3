// libFuzzer target: `noisemon replay` (daemon::run_replay) on a log file holding the fuzz bytes, reports
// written to an LCM log and a CSV. A log it cannot use must be refused with an error naming the file.
#include <spdlog/spdlog.h>

#include <exception>

#include "daemon/replay.hpp"
#include "fuzz_util.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);  // skip-and-count warnings would drown libFuzzer's output
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& dir = noisemon::fuzz::scratch_dir();
  noisemon::daemon::ReplayOptions o;
  o.log_path = (dir / "input.lcmlog").string();
  o.out_log = (dir / "reports.lcmlog").string();
  o.csv_path = (dir / "reports.csv").string();
  o.progress = false;
  noisemon::fuzz::write_file(o.log_path, data, size);
  try {
    const noisemon::daemon::ReplaySummary s = noisemon::daemon::run_replay(o);
    if (s.events < s.raw_blocks + s.skipped_damaged + s.skipped_unknown) noisemon::fuzz::fail("summary counts");
  } catch (const std::exception& e) {
    noisemon::fuzz::require_names(e.what(), o.log_path);
  }
  return 0;
}
