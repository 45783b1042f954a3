#include "drivers/aligned_stream.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace noisemon::drivers {
namespace {

constexpr std::size_t kBatch = 1024;  // scans per resampler call
constexpr double kRealignS = 0.05;    // a jump of the mapping larger than this restarts the stream (50 ms)
constexpr double kMaxSlew = 200e-6;   // the fastest the placing bends towards the tracker (0.02 %: no level moves)
constexpr double kAgreeS = 50e-6;     // the locking pulses lie this close to their fitted line
constexpr double kWaitForReferenceS = 1.0;  // a pulse waits this long for its crank instant to be posted
constexpr double kOriginSigmaS = 2e-3;      // how well the wall time of a capture's start places its scan 0
// A host reading is late by at most a read period (+-1.7 sigma of the uniform) and the scheduler's delay: beyond 4
// sigma it is refused, and so is every reading of a stream that is not paced by its crystal (a file, a virtual
// device, read as fast as it decodes), which stays at the nominal rate.
constexpr double kHostGateSigmas = 4.0;
// Readings count from a second after a (re)start: by then a stream read faster than its rate is seconds ahead of
// the host and refused, where the first readings' lateness would still hide it.
constexpr double kHostSettleS = 1.0;

ClockTracker::Options tracker_options(const AlignedStreamAssembler::Options& o) {
  ClockTracker::Options t;
  t.nominal_rate_hz = o.card_rate_hz;
  t.initial_sigma_s = kOriginSigmaS;
  t.initial_ppm_sigma = o.ppm_limit;
  return t;
}

// How well one reading of the monotonic clock places the scans it follows: uniform over a read period (when in the
// period the driver woke), plus the scheduler's wake-up latency on a loaded machine.
constexpr double kWakeLatencyS = 2e-4;
double host_sigma_s(double read_period_s) { return read_period_s / std::sqrt(12.0) + kWakeLatencyS; }

}  // namespace

AlignedStreamAssembler::AlignedStreamAssembler(const Options& options)
    : options_(options),
      tracker_(tracker_options(options), 0.0),
      detector_(options.sync_min_swing, 2.0 * options.card_rate_hz),
      resampler_(kPipelineRateHz, options.channels, options.card_rate_hz * (1.0 + 1e-6 * options.ppm_limit)),
      in_(kBatch * options.channels),
      times_(kBatch),
      writer_(options.channels) {
  if (options.channels == 0 || options.channels > SampleBlock::kMaxChannels)
    throw std::invalid_argument("aligned stream needs 1.." + std::to_string(SampleBlock::kMaxChannels) + " channels");
  if (!(options.card_rate_hz >= 1000.0) || !(options.read_period_s > 0.0) || !(options.sync_sigma_s > 0.0))
    throw std::invalid_argument("aligned stream: the rate, the read period and the sync noise must be positive");
}

void AlignedStreamAssembler::restart(std::int64_t origin_utime) {
  const double origin_s = static_cast<double>(origin_utime - options_.epoch_utime) * 1e-6;
  tracker_.reset_at(0.0, origin_s, kOriginSigmaS);
  detector_.reset();
  pulses_.clear();
  acquiring_.clear();
  synced_ = false;
  scans_ = 0;
  batch_ = 0;
  restart_resampler();
}

void AlignedStreamAssembler::restart_resampler() {
  resampler_ = dsp::NonuniformResampler(kPipelineRateHz, options_.channels,
                                        options_.card_rate_hz * (1.0 + 1e-6 * options_.ppm_limit));
  out_.assign((kBatch + 8192) * options_.channels, 0.0);
  fresh_ = true;
  last_time_s_ = -1e300;
}

void AlignedStreamAssembler::add_scan(const double* values, double sync, BlockRing& ring) {
  std::copy_n(values, options_.channels, &in_[batch_ * options_.channels]);
  double edge = 0.0;
  if (options_.reference && detector_.add(sync, static_cast<std::int64_t>(scans_), &edge)) pulses_.push_back(edge);
  ++scans_;
  if (++batch_ == kBatch) run_batch(ring);
}

void AlignedStreamAssembler::observe_host(double host_s) {
  if (synced_ || static_cast<double>(scans_) < kHostSettleS * options_.card_rate_hz) return;
  // The reading came up to a read period after its last scan was captured: its mean lateness is half of that.
  (void)tracker_.observe(static_cast<double>(scans_ - 1), host_s - 0.5 * options_.read_period_s,
                         host_sigma_s(options_.read_period_s), kHostGateSigmas);
}

// Each pending pulse against the crank instant nearest to where the tracker puts it, in order; a pulse whose
// instant may not be posted yet waits (the pipeline reads the crank angle a little after the card's scans).
void AlignedStreamAssembler::match_pulses() {
  std::size_t done = 0;
  for (; done < pulses_.size(); ++done) {
    const double q = pulses_[done];
    const double predicted = tracker_.time_at(q);
    const CrankReference::Match m = options_.reference->nearest(predicted);
    const double age_s = (static_cast<double>(scans_) - q) / options_.card_rate_hz;
    const double half_rev = std::isfinite(m.revolution_s) ? 0.5 * m.revolution_s : 0.0;
    if (!(m.latest_s > predicted + half_rev) && age_s < kWaitForReferenceS) break;  // its instant may yet come
    if (std::isfinite(m.instant_s) && std::abs(m.instant_s - predicted) < half_rev)
      take_pulse(q, m.instant_s);
    else
      ++pulses_rejected_;
  }
  pulses_.erase(pulses_.begin(), pulses_.begin() + static_cast<std::ptrdiff_t>(done));
  if (synced_ && (static_cast<double>(scans_) - last_sync_q_) / options_.card_rate_hz > kSyncLossSeconds) {
    synced_ = false;
    ++sync_losses_;
    acquiring_.clear();
  }
}

void AlignedStreamAssembler::take_pulse(double q, double instant_s) {
  if (synced_) {
    if (tracker_.observe(q, instant_s, options_.sync_sigma_s))
      last_sync_q_ = q;
    else
      ++pulses_rejected_;
    return;
  }
  // Not synced: the latest pulses must lie on one line whose slope is a rate the crystal can have.
  acquiring_.push_back({q, instant_s});
  if (acquiring_.size() > static_cast<std::size_t>(kLockPulses)) acquiring_.erase(acquiring_.begin());
  if (acquiring_.size() < static_cast<std::size_t>(kLockPulses)) return;
  double mq = 0.0, mt = 0.0;
  for (const auto& [pq, pt] : acquiring_) {
    mq += pq / kLockPulses;
    mt += pt / kLockPulses;
  }
  double sqq = 0.0, sqt = 0.0;
  for (const auto& [pq, pt] : acquiring_) {
    sqq += (pq - mq) * (pq - mq);
    sqt += (pq - mq) * (pt - mt);
  }
  const double period = sqt / sqq, nominal = 1.0 / options_.card_rate_hz;
  if (!(std::abs(period / nominal - 1.0) < 1e-6 * options_.ppm_limit)) return;
  for (const auto& [pq, pt] : acquiring_)
    if (std::abs(mt + period * (pq - mq) - pt) > kAgreeS) return;
  const double at = std::max(q, tracker_.last_position());  // the tracker's positions never go back
  tracker_.reset_at(at, mt + period * (at - mq), options_.sync_sigma_s, period, options_.sync_sigma_s / std::sqrt(sqq));
  synced_ = true;
  realign_ = true;
  last_sync_q_ = q;
  acquiring_.clear();
}

// The batch's scan instants: the tracker's at a (re)start and after a lock; otherwise the previous batch's line
// continued, bent towards the tracker by at most kMaxSlew (a correction of the host reference's noise becomes a
// rate change of a few hundred ppm, never a step in the stream).
void AlignedStreamAssembler::place_batch() {
  const double first_q = static_cast<double>(scans_ - batch_);
  const double target = tracker_.time_at(first_q);
  const double continued = last_time_s_ + tracker_.period_s();
  if (!fresh_ && (realign_ || std::abs(target - continued) > kRealignS)) {
    restart_resampler();
    ++realignments_;
  }
  realign_ = false;
  if (fresh_) {
    for (std::size_t i = 0; i < batch_; ++i) times_[i] = tracker_.time_at(first_q + static_cast<double>(i));
    slew_left_s_ = 0.0;
    return;
  }
  const double span = static_cast<double>(batch_) * tracker_.period_s();
  const double correction = std::clamp(target - continued, -kMaxSlew * span, kMaxSlew * span);
  const double step = tracker_.period_s() + correction / static_cast<double>(batch_);
  for (std::size_t i = 0; i < batch_; ++i) times_[i] = continued + step * static_cast<double>(i);
  slew_left_s_ = target - continued - correction;
}

void AlignedStreamAssembler::run_batch(BlockRing& ring) {
  if (batch_ == 0) return;
  if (options_.reference) match_pulses();
  place_batch();
  if (fresh_) settle_until_ = static_cast<std::int64_t>(std::ceil(times_[0] * kPipelineRateHz)) + kSettleFrames;
  fresh_ = false;
  last_time_s_ = times_[batch_ - 1];
  const std::size_t room = out_.size() / options_.channels;
  const std::size_t n = resampler_.process(times_.data(), in_.data(), batch_, out_.data(), room);
  batch_ = 0;
  std::int64_t frame = resampler_.next_output_index() - static_cast<std::int64_t>(n);
  for (std::size_t f = 0; f < n; ++f, ++frame) {
    if (frame < settle_until_ || frame <= last_frame_) continue;
    std::copy_n(&out_[f * options_.channels], options_.channels, writer_.frame(frame, ring));
    last_frame_ = frame;
    ++frames_;
  }
}

void AlignedStreamAssembler::deliver(BlockRing& ring, bool all) {
  run_batch(ring);
  if (all || writer_.pending_frames() >= SampleBlock::kMaxFrames / 2) writer_.flush(ring);
}

double AlignedStreamAssembler::uncertainty_s() const {
  const double sigma = tracker_.sigma_at(static_cast<double>(scans_));
  // Floors the filter does not see: sync edges' errors are correlated (a pulse's phase against the scans moves
  // slowly), and the host readings' mean lateness beyond half a period (the transport's delay) is unknown.
  const double floor = synced_ ? 0.5 * options_.sync_sigma_s : options_.host_delay_uncertainty_s;
  return std::sqrt(sigma * sigma + floor * floor) + std::abs(slew_left_s_);
}

}  // namespace noisemon::drivers
