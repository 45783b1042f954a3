// The interfaces the acquisition sources implement: a stream source (sim, comedi, lcm, log) and an operating-point
// source (CAN), each with its driver threads (SourceBase).
//
// A source owns its driver threads. Each thread resamples its stream to the common 40 kHz grid and pushes
// fixed-size blocks into a lock-free ring; everything downstream of the rings is identical for all sources.
//
// Time base: frame index k of every 40 kHz stream is the instant epoch_utime + k * 25 us, where epoch_utime
// is the source's session epoch (StreamInfo::epoch_utime). Streams are aligned by index, never by arrival.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "dsp/spsc_ring.hpp"

namespace noisemon::drivers {

class CrankReference;  // drivers/crank_reference.hpp

inline constexpr double kPipelineRateHz = 40000.0;

// The utime of 40 kHz frame `frame` (fractional: an instant between frames) of a stream whose frame 0 is at
// epoch_utime, to the nearest microsecond; and the frame nearest to a utime.
inline std::int64_t utime_of_frame(std::int64_t epoch_utime, double frame) {
  return epoch_utime + static_cast<std::int64_t>(std::llround(frame * 1e6 / kPipelineRateHz));
}
inline std::int64_t frame_of_utime(std::int64_t epoch_utime, std::int64_t utime) {
  return std::llround(static_cast<double>(utime - epoch_utime) * kPipelineRateHz / 1e6);
}

// The wall clock as an LCM utime: microseconds since 1970.
inline std::int64_t wall_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A block of consecutive frames of one stream, channels interleaved: data[frame * channels + channel].
struct SampleBlock {
  static constexpr std::size_t kMaxFrames = 256;
  static constexpr std::size_t kMaxChannels = 16;
  std::int64_t first_index = 0;  // frame index on the 40 kHz grid of the first frame
  std::uint32_t frames = 0;
  std::uint32_t channels = 0;
  double data[kMaxFrames * kMaxChannels];
};

// Pressure stream channels.
inline constexpr std::uint32_t kPressureChannel = 0;  // cylinder pressure, Pa (absolute)
inline constexpr std::uint32_t kCrankChannel = 1;     // crank angle, degrees in [-360, 360), 0 = firing TDC;
                                                   // NaN where the angle is not known (encoder fault, before a resync)
inline constexpr std::uint32_t kPressureStreamChannels = 2;

// The crank-angle stream (a source whose pressure is sampled on encoder edges): each edge's sample as taken, before
// the resampling to 40 kHz, so that the combustion figures see the encoder's own resolution. One "frame" per edge,
// in order; a block's first_index is the 40 kHz frame at or before its first edge, and a block spans at most
// kMaxAngleBlockDeg of crank angle (max_edges_per_angle_block): the instants of its edges are known to that.
inline constexpr std::uint32_t kAngleCrankChannel = 0;     // crank angle as on the pressure stream; NaN when not known
inline constexpr std::uint32_t kAnglePressureChannel = 1;  // cylinder pressure, Pa (absolute), as the 40 kHz stream's
inline constexpr std::uint32_t kAngleStreamChannels = 2;
inline constexpr double kMinAngleStepDeg = 0.01, kMaxAngleStepDeg = 6.0;  // the encoder resolutions a stream may have
inline constexpr double kMaxAngleBlockDeg = 90.0;
// The edges a crank-angle block of an encoder of this step holds at most (0 for a step outside the range above).
inline std::uint32_t max_edges_per_angle_block(double step_deg) {
  if (!(step_deg >= kMinAngleStepDeg && step_deg <= kMaxAngleStepDeg)) return 0;
  const auto n = static_cast<std::uint32_t>(kMaxAngleBlockDeg / step_deg + 1e-9);
  return n < 256 ? n : 256;  // SampleBlock::kMaxFrames
}
// The crank-angle stream's step of a session: one edge per encoder edge, when their step is in range; else 0.
inline double angle_step_deg(double edges_per_rev) {
  return edges_per_rev > 0 && max_edges_per_angle_block(360.0 / edges_per_rev) > 0 ? 360.0 / edges_per_rev : 0.0;
}

struct OperatingPoint {
  std::int64_t utime = 0;
  double speed_rpm = 0.0;
  double load_nm = 0.0;
  double soi_deg_btdc = 0.0;       // start of injection, degrees before firing TDC
  double rail_pressure_bar = 0.0;  // NaN when unknown
  bool motored = false;
};

using BlockRing = dsp::SpscRing<SampleBlock>;
using OperatingPointRing = dsp::SpscRing<OperatingPoint>;

// The rings a source writes into; owned by the daemon, handed to Source::start.
struct Streams {
  BlockRing* pressure = nullptr;  // kPressureStreamChannels channels
  BlockRing* mics = nullptr;      // StreamInfo::mic_count channels, Pa
  OperatingPointRing* operating_point = nullptr;
  BlockRing* pressure_angle = nullptr;  // kAngleStreamChannels channels, when StreamInfo::pressure_angle_step_deg > 0
  // The instants the crank passes StreamInfo::sync_angle_deg, when that is a number: posted by the pipeline from
  // the crank angle, read by a microphone front-end that aligns its clock to them.
  CrankReference* crank_reference = nullptr;
};

struct StreamInfo {
  std::int64_t epoch_utime = 0;  // utime of frame index 0
  std::uint32_t mic_count = 0;
  std::vector<std::array<double, 3>> mic_positions_m;  // one per microphone
  double radius_m = 1.75;                              // measurement hemisphere radius
  double acoustic_delay_s = 0.0;  // engine-to-microphone propagation time the processing should remove
  // The converters' rails as 40 kHz values (0: not known): a sample at or beyond them was clipped (overload).
  double pressure_full_scale_pa = 0.0;  // top of the pressure converter's range, Pa (absolute)
  double mic_full_scale_pa = 0.0;       // +- full scale of the microphone converter, Pa
  // What the streams carry, for the band validity flags (0: not known, nothing flagged). A crank-angle-sampled
  // pressure carries up to dsp::crank_angle_passband_hz of its edge rate, which follows the speed.
  double pressure_edges_per_rev = 0.0;  // encoder edges per revolution that clock the pressure samples
  double mic_passband_hz = 0.0;         // upper edge of the microphone converter's passband, Hz
  // > 0: the source may deliver the crank-angle stream (Streams::pressure_angle), one sample per encoder edge this
  // many degrees apart (angle_step_deg(pressure_edges_per_rev)); once its first block has come, the combustion
  // figures are computed from it. 0: they come from the 40 kHz pressure.
  double pressure_angle_step_deg = 0.0;
  // The crank angle of firing TDC on this stream's scale that its processing uses ([combustion] tdc_deg; session_t
  // tdc_deg). 0: the angles are the piston's.
  double tdc_deg = 0.0;
  // A number: the crank angle (degrees after firing TDC, on this stream's scale) of a once-per-revolution sync pulse
  // a microphone front-end samples beside its microphones; the pipeline then posts the instants the crank passes
  // it (Streams::crank_reference). NaN: none.
  double sync_angle_deg = NAN;
};

enum class ThreadState : std::uint8_t { kIdle = 0, kRunning = 1, kStopped = 2, kFailed = 3 };

struct DriverThreadStatus {
  std::string name;
  ThreadState state = ThreadState::kIdle;
  std::uint64_t blocks_written = 0;
  std::string error;  // empty unless kFailed
};

// A named event count of a driver (overruns, restarts, error frames, ...), shown in the status message; or, a gauge,
// a state that may go down (a clock's drift, whether a sync pulse is locked).
struct DriverCounter {
  std::string name;  // "<source>.<what>", e.g. "comedi.pressure.overruns"
  std::int64_t value = 0;
  bool gauge = false;
};

// What every source has: a name, driver threads that stop, their state and their event counters.
class SourceBase {
 public:
  virtual ~SourceBase() = default;
  virtual std::string name() const = 0;
  // Stops and joins the driver threads. Idempotent.
  virtual void stop() = 0;
  // True once every driver thread has produced data (used for the systemd READY notification).
  virtual bool running() const = 0;
  // A snapshot of every driver thread's state (safe from any thread).
  virtual std::vector<DriverThreadStatus> thread_status() const = 0;
  // A snapshot of the driver's event counters (safe from any thread). Sources without any return none.
  virtual std::vector<DriverCounter> counters() const { return {}; }
};

// A stream source, what the pipeline runs on: the pressure with the crank angle and the microphones, and the
// operating points if it has its own (sim, comedi, lcm, log; combined_source.hpp gives it CAN's instead).
class Source : public SourceBase {
 public:
  // Valid after construction (before start): stream layout and time base.
  virtual StreamInfo info() const = 0;
  // Starts the driver threads; they push into the given rings until stop(). Throws on a device error.
  virtual void start(const Streams& streams) = 0;
  // A finite source (a log file) that has delivered all it will: the pipeline then drains and finishes. Live
  // sources never are.
  virtual bool exhausted() const { return false; }
};

// What a microphone source's stream is: StreamInfo's microphone fields (compose_microphones puts them there).
struct MicStreamInfo {
  std::uint32_t mic_count = 0;
  std::vector<std::array<double, 3>> mic_positions_m;  // one per microphone
  double radius_m = 1.75;
  double acoustic_delay_s = 0.0;
  double mic_full_scale_pa = 0.0;  // 0: not known (the microphones' full scales differ)
  double mic_passband_hz = 0.0;
  double sync_angle_deg = NAN;  // StreamInfo::sync_angle_deg
};

// A microphone front-end of its own (an audio interface on its own crystal), whose stream is composed with another
// source's pressure and crank angle (combined_source.hpp).
class MicSource : public SourceBase {
 public:
  virtual MicStreamInfo info() const = 0;
  // Starts the driver thread: 40 kHz blocks of the microphones (Pa) into `mics`, frame k being the instant
  // epoch_utime + k * 25 us on the stream source's clock (by its sync pulse matched to `reference` when it has one,
  // else by the host clock). Throws on a device error.
  virtual void start(BlockRing& mics, std::int64_t epoch_utime, const CrankReference* reference) = 0;
};

// An operating-point source: no streams, only the engine's operating points (CAN).
class OperatingPointSource : public SourceBase {
 public:
  // Starts the driver threads; they push into the ring until stop(). Throws on a device error.
  virtual void start(OperatingPointRing& ring) = 0;
};

}  // namespace noisemon::drivers
