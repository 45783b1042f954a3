// A microphone stream on a front-end's own crystal, put on the pipeline's time base (the encoder's) by a tracked
// clock rather than a nominal rate. Each scan's instant on the pipeline's clock comes from a ClockTracker, and the
// scans go through the crank-angle stream's resampler for samples at uneven instants (dsp::NonuniformResampler),
// so the output's frame k is the sound at frame k of the pressure and crank angle, however far the crystals drift.
//
// The tracker is fed by one of two references:
//  - sync: a once-per-revolution pulse on a spare channel of the same converter (its edges found by
//    SyncPulseDetector) matched to the instants the crank passes the pulse's angle (CrankReference, posted by the
//    pipeline from the encoder's crank angle). A few pulses on one line lock it (the stream is realigned: a short
//    gap); it then follows each pulse to microseconds. A pulse that stops for kSyncLossSeconds, or noise that
//    matches nothing, drops it back to the host reference, counted and flagged (synced() false).
//  - host: the count of scans read by each instant of the host's monotonic clock. Each reading is late by up to
//    a read period and the scheduler's delay; the filter averages them (half a period taken off each), and the
//    stated uncertainty keeps a floor for what no reading shows: the transport's own delay (host_delay_uncertainty_s).
//    The placing of the scans bends towards the tracker at a bounded rate (kMaxSlew) rather than jump with each
//    reading's correction.
// Without a reference the stream is where the host clock puts it, and uncertainty_s() says how well that is known.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "drivers/block_writer.hpp"
#include "drivers/clock_tracker.hpp"
#include "drivers/crank_reference.hpp"
#include "drivers/source.hpp"
#include "drivers/sync_pulse.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers {

class AlignedStreamAssembler {
 public:
  struct Options {
    std::uint32_t channels = 1;                 // microphones (the sync channel is not one of them)
    double card_rate_hz = 48000.0;              // the converter's nominal rate
    std::int64_t epoch_utime = 0;               // the pipeline's frame 0
    const CrankReference* reference = nullptr;  // the sync pulse's crank instants; null: host reference only
    double sync_min_swing = 0.05;               // the sync channel's smallest pulse (its units: full scale 1)
    double sync_sigma_s = 3e-6;                 // one sync edge's timing noise (a fifth of a 48 kHz scan)
    double read_period_s = 0.01;                // the host reads this often (a read's lateness is up to it)
    double host_delay_uncertainty_s = 1e-3;     // how well the transport's delay (USB, the driver) is known
    double ppm_limit = 300.0;                   // how far a crystal may be off its nominal rate
  };
  static constexpr double kSyncLossSeconds = 2.0;  // no matched pulse for this long: back to the host reference
  static constexpr int kLockPulses = 4;            // pulses that agree before the sync reference is trusted
  static constexpr std::int64_t kSettleFrames = dsp::kResamplerSettleFrames;  // output dropped after a (re)start

  explicit AlignedStreamAssembler(const Options& options);

  // Starts over (a start, an overrun): scan 0 was captured at host wall time origin_utime.
  void restart(std::int64_t origin_utime);
  // One scan: the microphones' values and the sync channel's (ignored without a reference).
  void add_scan(const double* values, double sync, BlockRing& ring);
  // A host reading: every scan added so far had been read by host_s (s since the epoch, monotonic).
  void observe_host(double host_s);
  void deliver(BlockRing& ring, bool all);

  [[nodiscard]] bool synced() const { return synced_; }
  [[nodiscard]] double ppm() const { return tracker_.ppm(); }
  [[nodiscard]] double ppm_sigma() const { return tracker_.ppm_sigma(); }
  // 1-sigma uncertainty of where the latest scan is on the pipeline's clock, s.
  [[nodiscard]] double uncertainty_s() const;
  [[nodiscard]] std::uint64_t sync_losses() const { return sync_losses_; }
  [[nodiscard]] std::uint64_t pulses_rejected() const { return pulses_rejected_; }
  [[nodiscard]] std::uint64_t realignments() const { return realignments_; }
  [[nodiscard]] std::uint64_t frames() const { return frames_; }
  [[nodiscard]] std::uint64_t blocks_written() const { return writer_.blocks_written(); }

 private:
  void run_batch(BlockRing& ring);
  void match_pulses();
  void take_pulse(double q, double instant_s);
  void place_batch();
  void restart_resampler();

  Options options_;
  ClockTracker tracker_;
  SyncPulseDetector detector_;
  dsp::NonuniformResampler resampler_;
  std::vector<double> in_, times_, out_;
  std::size_t batch_ = 0;
  std::uint64_t scans_ = 0;                           // since the restart
  std::vector<double> pulses_;                        // sync edges not matched yet (scan positions)
  std::vector<std::pair<double, double>> acquiring_;  // the latest (pulse scan, crank instant) while not synced
  bool synced_ = false, realign_ = false;
  double slew_left_s_ = 0.0;  // how far the placing still is from the tracker
  double last_sync_q_ = 0.0;
  double last_time_s_ = -1e300;    // the latest scan instant given to the resampler
  std::int64_t settle_until_ = 0;  // output frames before this one are dropped
  std::int64_t last_frame_ = -1;   // the latest frame written
  bool fresh_ = true;              // the resampler has had no input since its restart
  BlockWriter writer_;
  std::uint64_t frames_ = 0, sync_losses_ = 0, pulses_rejected_ = 0, realignments_ = 0;
};

}  // namespace noisemon::drivers
