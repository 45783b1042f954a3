// A recording on the pipeline's 40 kHz grid, held in memory: what `noisemon import` makes of run directories
// and cycle tables before writing the raw LCM log, what `noisemon export` makes of a log before writing a run
// directory, and what `noisemon diagnose` analyses. The LCM log form is exactly what noisemond publishes
// (NOISEMON_SESSION, NOISEMON_RAW, NOISEMON_OP), so `noisemon replay` and `noisemond --source lcm` read it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "drivers/formats/raw_stream_decoder.hpp"
#include "drivers/formats/run_dir.hpp"
#include "drivers/source.hpp"

namespace noisemon::cli::formats {

struct Recording {
  std::string condition;            // the run's condition name ("" when unknown)
  std::string source = "import";    // session_t source
  drivers::StreamInfo info;         // epoch, microphones, radius, acoustic delay
  std::int64_t first_index = 0;     // 40 kHz grid index of frame 0 of both streams
  std::vector<double> pressure_pa;  // one per frame
  std::vector<double> crank_deg;    // one per frame, wrapped to [-360, 360) as on the pressure stream
  std::vector<double> mics_pa;      // frames * info.mic_count, frame-major; empty without microphones
  // The crank-angle stream (info.pressure_angle_step_deg > 0): the encoder edges within the frames, frame-major,
  // kEdgeValues values each (angle_edges.hpp); empty without one.
  std::vector<double> angle_edges;
  std::vector<drivers::OperatingPoint> operating_points;  // at least one; utime on the recording's time base

  std::size_t frames() const { return pressure_pa.size(); }
};

// Run directory -> 40 kHz: the pressure resampled from its encoder samples (dsp::NonuniformResampler), the
// microphones from their WAV rate (dsp::RationalResampler). epoch_utime places the run's time_s = 0.
// - Pressure already on the 40 kHz grid (time_s = k / 40000 for consecutive k, as `noisemon export` writes it)
//   and microphones at 40 kHz are copied, not filtered again, so export -> import is lossless.
// - Missing encoder samples (crank steps of 1.5 .. kMaxCrankGapSteps encoder steps) are filled by linear
//   interpolation in time, crank angle and pressure first: the resampler expects samples evenly spaced in angle.
// - The crank channel is the unwrapped crank angle interpolated linearly at each 40 kHz instant, then wrapped.
// - The encoder samples themselves (filled as above) become the crank-angle stream (Recording::angle_edges), when
//   their step is an encoder's (kMinAngleStepDeg ... kMaxAngleStepDeg): the combustion figures are computed on them.
// - Both streams are cut to the stretch where both exist and the resamplers have full support (the first and
//   last few hundred microseconds of the pressure are lost); operating_points holds one point from the
//   run's condition (operating_point_of). Throws RunDirError when nothing is left or the run is inconsistent.
Recording to_recording(const drivers::formats::RunDir& run, std::int64_t epoch_utime);
// The same, freeing the run's sample columns (time_s, crank_deg, pressure_pa, mic_pa) as soon as they are
// resampled: the run keeps its condition and microphone layout, its columns are left empty.
Recording to_recording(drivers::formats::RunDir&& run, std::int64_t epoch_utime);
// The operating point of a run's condition: unknown load, SOI and rail pressure stay NaN; an unknown speed
// (NaN) is measured from the encoder (encoder_speed_rpm: the mean over the run); an unknown `motored` is
// published as false (the message's field is a boolean; RunCondition::motored_known keeps the difference).
drivers::OperatingPoint operating_point_of(const drivers::formats::RunDir& run, std::int64_t utime);
// 40 kHz -> run directory: one pressure row per frame, time_s = 0 at the recording's first frame (mics.wav's
// t = 0), crank unwrapped from the first frame's cycle (cycle 0); mics.wav at 40 kHz. The condition's numbers
// come from the first operating point (a run directory has one condition); unknown ones (NaN) stay unknown
// and are written as null.
drivers::formats::RunDir to_run_dir(const Recording& rec);

using LogChannels = drivers::formats::StreamChannels;

// Progress of long conversions: fraction done, 0..1.
using ProgressFn = std::function<void(double fraction)>;

// Writes the recordings to one LCM log (replacing the file), one after another, each with its own session
// message (repeated every second of recording time, with the operating point, as noisemond does) and its raw
// blocks of at most 256 frames. Recordings must have distinct epochs (a new epoch starts a new run).
void write_recordings_log(const std::filesystem::path& log, const std::vector<Recording>& recordings,
                          const LogChannels& channels = {}, const ProgressFn& progress = {});

// The same, one recording at a time (long imports need not hold every run in memory). The file is created by
// the constructor (throws std::runtime_error naming it when it cannot be) and complete after each write().
class RecordingLogWriter {
 public:
  explicit RecordingLogWriter(const std::filesystem::path& log, const LogChannels& channels = {});
  ~RecordingLogWriter();
  RecordingLogWriter(const RecordingLogWriter&) = delete;
  RecordingLogWriter& operator=(const RecordingLogWriter&) = delete;
  // Throws std::invalid_argument for an inconsistent recording or an epoch already written.
  void write(const Recording& recording, const ProgressFn& progress = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct LogReadStats {
  std::int64_t events = 0;          // well-framed events read
  std::int64_t sessions = 0;        // distinct sessions (epochs)
  std::int64_t other_channels = 0;  // events of channels not read here (reports, status, ...): ignored
  std::int64_t damaged = 0;         // skipped: see read_recordings_log
  std::int64_t pieces_split = 0;    // extra recordings made because a session had a hole
  std::vector<std::string> damage;  // what was wrong with the first damaged events (at most 10)
};

// Reads every session of a raw log back into recordings, in the order of the log. A session (a new epoch,
// microphone layout or condition) starts a new recording; repeated session messages do not.
// Skipped and counted (*skipped, stats->damaged), never used: damaged stretches of the file (bad framing, a
// truncated last event), events that do not decode as their channel's type (wrong fingerprint, foreign type,
// short payload), raw blocks that contradict their session (other epoch, channel count, rate) or themselves
// (utime against first_index, non-finite samples, crank angle outside [-360, 360)), raw blocks before any
// session. Frames missing from a session (skipped blocks) are not invented: the session is split into one
// recording per stretch where both streams are complete. A log with no usable session throws
// std::runtime_error naming the file.
std::vector<Recording> read_recordings_log(const std::filesystem::path& log, const LogChannels& channels = {},
                                           std::int64_t* skipped = nullptr, LogReadStats* stats = nullptr,
                                           const ProgressFn& progress = {});
// The same on a log held in memory (`name` is used in messages).
std::vector<Recording> read_recordings_log(const std::uint8_t* data, std::size_t size, const std::string& name,
                                           const LogChannels& channels = {}, std::int64_t* skipped = nullptr,
                                           LogReadStats* stats = nullptr);

}  // namespace noisemon::cli::formats
