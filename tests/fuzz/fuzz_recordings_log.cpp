// libFuzzer target: reading a raw LCM log back into recordings (cli::formats::read_recordings_log, what
// `noisemon export` and `noisemon diagnose` read). Damaged events are skipped and counted; a log it cannot use
// is refused with an error naming the file.
#include <exception>

#include "cli/formats/recording.hpp"
#include "fuzz_util.hpp"

using noisemon::fuzz::fail;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = noisemon::fuzz::scratch_dir() / "input.lcmlog";
  noisemon::fuzz::write_file(path, data, size);
  try {
    std::int64_t skipped = -1;
    const auto recordings = noisemon::cli::formats::read_recordings_log(path, {}, &skipped);
    if (skipped < 0) fail("skipped count not reported");
    if (recordings.empty()) fail("no recording and no error");
    for (const auto& r : recordings) {
      if (r.crank_deg.size() != r.frames() || r.mics_pa.size() != r.frames() * r.info.mic_count)
        fail("recording streams of different lengths");
      if (r.operating_points.empty()) fail("recording without an operating point");
    }
  } catch (const std::exception& e) {
    noisemon::fuzz::require_names(e.what(), path.string());
  }
  return 0;
}
