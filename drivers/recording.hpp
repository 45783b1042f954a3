// A recording on the pipeline's 40 kHz grid, held in memory: what `noisemon import` makes of run directories
// and cycle tables before writing the raw LCM log, what `noisemon export` makes of a log before writing a run
// directory, and what `noisemon diagnose` analyses. The LCM log form is exactly what noisemond publishes
// (NOISEMON_SESSION, NOISEMON_RAW, NOISEMON_OP), so `noisemon replay` and `noisemond --source lcm` read it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "drivers/run_dir.hpp"
#include "drivers/source.hpp"

namespace noisemon::drivers {

struct Recording {
  std::string condition;             // the run's condition name ("" when unknown)
  std::string source = "import";     // session_t source
  StreamInfo info;                   // epoch, microphones, radius, acoustic delay
  std::int64_t first_index = 0;      // 40 kHz grid index of frame 0 of both streams
  std::vector<double> pressure_pa;   // one per frame
  std::vector<double> crank_deg;     // one per frame, wrapped to [-360, 360) as on the pressure stream
  std::vector<double> mics_pa;       // frames * info.mic_count, frame-major; empty without microphones
  std::vector<OperatingPoint> operating_points;  // at least one; utime on the recording's time base

  std::size_t frames() const { return pressure_pa.size(); }
};

// Run directory -> 40 kHz: the pressure resampled from its encoder samples (dsp::NonuniformResampler), the
// microphones from their WAV rate (dsp::RationalResampler). epoch_utime places the run's time_s = 0.
Recording to_recording(const RunDir& run, std::int64_t epoch_utime);
// 40 kHz -> run directory: one pressure row per frame (crank unwrapped), mics.wav at 40 kHz.
RunDir to_run_dir(const Recording& rec);

struct LogChannels {
  std::string raw = "NOISEMON_RAW";
  std::string operating_point = "NOISEMON_OP";
  std::string session = "NOISEMON_SESSION";
};

// Appends the recordings to one LCM log, one after another (each with its own session message).
void write_recordings_log(const std::filesystem::path& log, const std::vector<Recording>& recordings,
                          const LogChannels& channels = {});
// Reads every session of a raw log back into recordings. Damaged events are skipped and counted (*skipped);
// a log with no session throws std::runtime_error naming the file.
std::vector<Recording> read_recordings_log(const std::filesystem::path& log, const LogChannels& channels = {},
                                           std::int64_t* skipped = nullptr);

}  // namespace noisemon::drivers
