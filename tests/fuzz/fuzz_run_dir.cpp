// libFuzzer target: the run-directory importer (drivers::formats::read_run_dir, then to_recording as `noisemon import`
// does) with one of its files replaced by the fuzz bytes and the others valid. Built three times, the file
// chosen by FUZZ_RUN_DIR_FILE ("run.json", "pressure.csv" or "mics.wav").
#include <cmath>
#include <exception>

#include "cli/formats/recording.hpp"
#include "drivers/formats/run_dir.hpp"
#include "fuzz_util.hpp"
#include "valid_inputs.hpp"

using noisemon::fuzz::fail;

namespace {

const std::filesystem::path& run_dir() {
  static const std::filesystem::path dir = [] {
    const auto d = noisemon::fuzz::scratch_dir() / "run";
    std::filesystem::create_directories(d);
    noisemon::fuzz::write_file(d / "run.json", noisemon::fuzz::run_json());
    noisemon::fuzz::write_file(d / "pressure.csv", noisemon::fuzz::pressure_csv());
    noisemon::fuzz::write_file(d / "mics.wav", noisemon::fuzz::mics_wav());
    return d;
  }();
  return dir;
}

bool all_finite(const auto& v) {
  for (const auto x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

// What an accepted run directory promises its users (drivers/formats/run_dir.hpp).
void check_accepted(const noisemon::drivers::formats::RunDir& r) {
  const std::size_t n = r.time_s.size();
  if (r.crank_deg.size() != n || r.pressure_pa.size() != n) fail("pressure columns of different lengths");
  if (!all_finite(r.time_s) || !all_finite(r.crank_deg) || !all_finite(r.pressure_pa)) fail("non-finite pressure data");
  for (std::size_t i = 1; i < n; ++i)
    if (!(r.crank_deg[i] > r.crank_deg[i - 1])) fail("crank angle not strictly increasing");
  if (r.mic_count == 0 ? !r.mic_pa.empty() : r.mic_pa.size() % r.mic_count != 0)
    fail("microphone samples not whole frames");
  if (r.mic_count > 0 && (r.mic_positions_m.size() != r.mic_count || !(r.mic_rate_hz > 0))) fail("microphone layout");
  if (!all_finite(r.mic_pa)) fail("non-finite microphone samples");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& dir = run_dir();
  noisemon::fuzz::write_file(dir / FUZZ_RUN_DIR_FILE, data, size);
  noisemon::drivers::formats::RunDir run;
  try {
    run = noisemon::drivers::formats::read_run_dir(dir);
  } catch (const std::exception& e) {
    // The file at fault is named: the fuzzed one, or for run.json possibly a file it points to.
    const std::string_view what = e.what();
    if (std::string_view(FUZZ_RUN_DIR_FILE) == "run.json" && what.find(dir.string()) != std::string_view::npos)
      return 0;
    noisemon::fuzz::require_names(what, FUZZ_RUN_DIR_FILE);
    return 0;
  }
  check_accepted(run);
  try {
    const noisemon::cli::formats::Recording rec = noisemon::cli::formats::to_recording(run, 1'700'000'000'000'000);
    if (rec.crank_deg.size() != rec.frames() || rec.mics_pa.size() != rec.frames() * rec.info.mic_count)
      fail("recording streams of different lengths");
    if (!all_finite(rec.pressure_pa) || !all_finite(rec.crank_deg) || !all_finite(rec.mics_pa))
      fail("non-finite samples in the recording");
  } catch (const std::exception&) {
    // a clean refusal of data the resampler cannot use
  }
  return 0;
}
