#include "drivers/comedi/comedi_streams.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "dsp/math_constants.hpp"
#include "model/engine_geometry.hpp"

namespace noisemon::drivers::comedi {
namespace {

constexpr std::size_t kEdgeBatch = 1024;   // edges per resampler call
constexpr std::size_t kOutFrames = 8192;   // resampler output room per call (frames)
constexpr std::size_t kHistory = 1 << 15;  // recent edges kept for the crank-angle interpolation
constexpr double kTdcWindowDeg = 30.0;     // pressure rise measured over TDC +- this
constexpr double kFiringRiseRatio = 3.0;   // firing TDC's rise must exceed the other TDC's by this factor
constexpr int kMismatchesToCorrect = 2;    // consecutive contrary phase votes before re-phasing
// Encoder checks only (index_resets_counter):
constexpr double kMaxEdgeGapS = 0.05;   // no edge for this long: the resampler starts afresh (a gap)
constexpr double kMaxBatchSpanS = 0.1;  // a batch spanning this long is resampled at once (slow edges)

std::int64_t floor_mod2(std::int64_t j) { return ((j % 2) + 2) % 2; }
std::int64_t floor_div(std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0 && (a < 0) != (b < 0)) ? 1 : 0); }
// The engine cycle an unwrapped crank angle lies in: [720 k - 360, 720 k + 360).
std::int64_t cycle_of(double theta) { return static_cast<std::int64_t>(std::floor((theta + 360.0) / 720.0)); }

}  // namespace

// ---------------------------------------------------------------------------------------------- edges

namespace {
dsp::NonuniformResampler make_resampler(const EdgeStreamConfig& c) {
  return dsp::NonuniformResampler(kPipelineRateHz, 1, max_edge_rate_hz(c.counts_per_rev, c.counts_per_edge, c.max_rpm));
}
}  // namespace

double max_edge_rate_hz(std::uint32_t counts_per_rev, std::uint32_t counts_per_edge, double max_rpm) {
  if (!(max_rpm > 0.0)) return dsp::NonuniformResampler::kAnyEncoderEdgeRateHz;
  return max_rpm / 60.0 * counts_per_rev / counts_per_edge;
}

EdgeStreamAssembler::EdgeStreamAssembler(const EdgeStreamConfig& config, std::int64_t epoch_utime)
    : config_(config),
      epoch_utime_(epoch_utime),
      tick_mask_((1ULL << std::min<std::uint32_t>(config.timestamp_bits, 32)) - 1),
      resampler_(kPipelineRateHz, 1),
      t_(kEdgeBatch),
      x_(kEdgeBatch),
      out_(kOutFrames),
      history_(kHistory),
      writer_(kPressureStreamChannels) {
  const auto& c = config_;
  auto fail = [](const std::string& what) { throw std::invalid_argument("encoder-clocked streams: " + what); };
  if (c.stream_channels.empty()) fail("no subdevices");
  auto check = [&](const ScanSlot& s, const char* what) {
    if (s.stream >= c.stream_channels.size() || s.channel >= c.stream_channels[s.stream])
      fail(std::string(what) + " is not in any subdevice's channel list");
  };
  check(c.pressure, "pressure");
  check(c.position, "position");
  check(c.timestamp, "timestamp");
  if (c.cam) check(*c.cam, "cam");
  if (c.phase == PhaseSource::kCam && !c.cam) fail("phase from the cam needs a cam channel");
  if (c.counts_per_rev < 4) fail("counts_per_rev must be at least 4");
  if (!(c.timebase_hz > 0.0)) fail("timebase_hz must be positive");
  if (c.timestamp_bits < 8 || c.timestamp_bits > 32)
    fail("timestamp_bits must be in [8, 32] (comedi samples are 32-bit at most)");
  if (c.peg_pa > 0.0 && !(c.peg_window_deg > 0.0 && c.peg_window_deg < 180.0))
    fail("peg_window_deg must be in (0, 180)");
  if (c.max_scan_skew == 0) fail("max_scan_skew must be positive");
  if (c.index_resets_counter) {
    if (c.counts_per_edge == 0 || c.counts_per_rev % c.counts_per_edge != 0 || c.counts_per_rev / c.counts_per_edge < 4)
      fail("counts_per_rev must be a multiple of counts_per_edge, at least 4 edges a revolution");
    if (c.counts_per_rev >= (1u << 30)) fail("counts_per_rev must be below 2^30");
    const std::uint64_t edges = c.counts_per_rev / c.counts_per_edge;
    slack_ = c.counts_per_edge * std::clamp<std::uint64_t>(edges / 32, 2, 64);
    held_.resize(2 * edges + slack_ + kEdgeBatch);  // a revolution awaiting its phase, the open one, a margin
  }
  if (c.peg_pa > 0.0)  // the edges of up to two revolutions wait for their cycle's pegging
    peg_wait_.resize(2 * (c.counts_per_rev / std::max<std::uint32_t>(c.counts_per_edge, 1)) + kEdgeBatch);
  for (std::uint32_t n : c.stream_channels) {
    Fifo f;
    f.channels = n;
    f.values.resize((c.max_scan_skew + 1) * n);
    fifos_.push_back(std::move(f));
  }
  restart(epoch_utime);
}

EdgeStreamAssembler::~EdgeStreamAssembler() = default;

void EdgeStreamAssembler::set_angle_ring(BlockRing* ring) {
  const double step = 360.0 * std::max<std::uint32_t>(config_.counts_per_edge, 1) / config_.counts_per_rev;
  angle_block_edges_ = max_edges_per_angle_block(step);
  if (ring && angle_block_edges_ == 0)
    throw std::invalid_argument("encoder-clocked streams: an encoder step of " + std::to_string(step) +
                                " deg has no crank-angle stream");
  angle_ring_ = ring;
}

void EdgeStreamAssembler::restart(std::int64_t origin_utime) {
  origin_s_ = 1e-6 * static_cast<double>(origin_utime - epoch_utime_);
  for (Fifo& f : fifos_) f.head = f.count = 0;
  have_prev_ = false;
  ticks_ = 0;
  count_ = 0;
  locked_ = false;
  phase_ = 0;
  mismatches_ = 0;
  window_ = Window{};
  last_tdc_ = Tdc{};
  rev_ = Revolution{};
  lost_threshold_ = 0;
  psi_valid_ = true;
  output_ = false;
  release_on_lock_ = false;
  held_head_ = held_n_ = confirmed_n_ = 0;
  peg_known_ = !(config_.peg_pa > 0.0);
  peg_offset_ = peg_prev_offset_ = peg_sum_ = 0.0;
  peg_cycle_ = INT64_MIN;
  peg_wait_head_ = peg_wait_n_ = 0;
  peg_n_ = 0;
  resampler_ = make_resampler(config_);
  batch_ = 0;
  history_end_ = cursor_ = 0;
  have_fed_ = false;
  last_fed_t_ = 0.0;
}

void EdgeStreamAssembler::add_scan(std::uint32_t stream, const double* values, BlockRing& ring) {
  Fifo& in = fifos_[stream];
  const std::size_t capacity = config_.max_scan_skew + 1;
  if (in.count == capacity)
    throw std::runtime_error("encoder-clocked subdevices out of step: subdevice #" + std::to_string(stream) +
                             " delivered " + std::to_string(capacity) +
                             " scans more than another (are both clocked by the same encoder edge?)");
  std::copy_n(values, in.channels, &in.values[((in.head + in.count) % capacity) * in.channels]);
  ++in.count;
  for (;;) {
    for (const Fifo& f : fifos_)
      if (f.count == 0) return;
    auto value = [&](const ScanSlot& s) {
      const Fifo& f = fifos_[s.stream];
      return f.values[f.head * f.channels + s.channel];
    };
    const auto position = static_cast<std::uint64_t>(std::llround(std::max(0.0, value(config_.position))));
    const auto ticks = static_cast<std::uint64_t>(std::llround(std::max(0.0, value(config_.timestamp))));
    const double pressure = value(config_.pressure);
    const double cam = config_.cam ? value(*config_.cam) : 0.0;
    for (Fifo& f : fifos_) {
      f.head = (f.head + 1) % capacity;
      --f.count;
    }
    add_edge(position, ticks, pressure, cam, ring);
  }
}

void EdgeStreamAssembler::add_edge(std::uint64_t position, std::uint64_t ticks_raw, double pressure, double cam,
                                   BlockRing& ring) {
  ++counters_.edges;
  const bool first = !have_prev_;
  if (!advance_time(ticks_raw)) return;
  bool continuous = !first;  // psi follows on from the previous edge's (for the TDC windows)
  if (config_.index_resets_counter)
    continuous = count_checked(static_cast<std::uint32_t>(position & 0xffffffffULL), first, ring) && continuous;
  else
    count_plain(position);
  const double t = origin_s_ + static_cast<double>(ticks_) / config_.timebase_hz;
  const double psi =
      static_cast<double>(count_) * 360.0 / static_cast<double>(config_.counts_per_rev) + config_.index_angle_deg;
  if (psi_valid_) track_phase(psi, pressure, cam, continuous);
  have_prev_ = true;
  prev_psi_ = psi;
  prev_cam_ = cam;
  if (release_on_lock_) {  // the phase was decided again: the revolution confirmed meanwhile gets its angles
    release_on_lock_ = false;
    release_held(confirmed_n_, true, ring);
  }
  if (!gate(psi, pressure)) return;
  const double x = pressure;  // pegged in emit(), with its cycle's offset
  if (!config_.index_resets_counter)
    emit(t, x, psi + 360.0 * phase_, ring);
  else if (rev_.bad)
    emit(t, x, kNaN, ring);
  else
    hold(t, x, psi, ring);
}

// The edge's time from the timebase counter; false for two edges at one instant (a glitch: the edge cannot be
// placed in time and is dropped).
bool EdgeStreamAssembler::advance_time(std::uint64_t ticks_raw) {
  const std::uint64_t raw = ticks_raw & tick_mask_;
  if (!have_prev_) {
    ticks_ = raw;
  } else {
    const std::uint64_t delta =
        config_.timestamp_mode == TimestampMode::kAbsolute ? (raw - prev_ticks_raw_) & tick_mask_ : raw;
    if (delta == 0) {
      ++counters_.encoder_errors;
      return false;
    }
    ticks_ += delta;
  }
  prev_ticks_raw_ = raw;
  return true;
}

// Without the index checks: the position modulo a revolution, a step back of up to half a revolution counted
// backwards (and as an error).
void EdgeStreamAssembler::count_plain(std::uint64_t position) {
  const std::uint64_t cpr = config_.counts_per_rev;
  const std::uint64_t pos = position % cpr;
  if (!have_prev_) {
    count_ = static_cast<std::int64_t>(pos);
  } else {
    auto step = static_cast<std::int64_t>((pos + cpr - prev_position_) % cpr);
    if (step > static_cast<std::int64_t>(cpr / 2)) {  // backwards: reverse rotation or a counting glitch
      step -= static_cast<std::int64_t>(cpr);
      ++counters_.encoder_errors;
    }
    count_ += step;
  }
  prev_position_ = pos;
}

// The index-reset counter, edge by edge (raw: the 32-bit register). Back near 0 after running forward is an
// index: it closes the revolution. A backward step, a jump forward or running on past the index is a fault.
// Returns false when the unwrapped count does not follow on from the previous edge's (re-based at an index).
bool EdgeStreamAssembler::count_checked(std::uint32_t raw, bool first, BlockRing& ring) {
  const std::uint64_t cpr = config_.counts_per_rev;
  const auto prev = static_cast<std::uint32_t>(prev_position_);
  prev_position_ = raw;
  if (first) {  // the part revolution after a (re)start: the counter counts from the last index the card saw
    rev_ = Revolution{};
    count_ = raw;
    lost_threshold_ = (raw / cpr + 1) * cpr + slack_;
    if (raw >= cpr) sync_fault(ring);  // not counting from an index: nothing to follow until one comes
    return false;
  }
  const auto step = static_cast<std::int64_t>(static_cast<std::int32_t>(static_cast<std::uint32_t>(raw - prev)));
  if (step < 0 && raw < slack_ && static_cast<std::uint64_t>(-step) >= cpr / 2)
    return close_revolution(raw, prev, ring);
  if (step < 0 || static_cast<std::uint64_t>(step) > slack_) {
    // Counting down (reverse rotation, a direction fault) or a jump the count cannot follow (a glitch, a wrap
    // of a narrower register): the raw position means nothing until the next index.
    ++counters_.encoder_errors;
    if (step < 0) {
      ++counters_.reverse_steps;
      count_ += step;
    }
    rev_.stepped_back = true;
    if (!rev_.sync_lost) sync_fault(ring);
    return true;
  }
  count_ += step;
  if (rev_.stepped_back) return true;
  if (raw >= cpr && !rev_.extra) {  // more than a revolution before the index: spurious counts (or a lost index)
    rev_.extra = true;
    count_fault(ring);
  }
  if (raw >= lost_threshold_) {  // no index within a revolution and the slack: it was missed
    ++counters_.lost_index;
    lost_threshold_ = (raw / cpr + 1) * cpr + slack_;
    if (!rev_.sync_lost) sync_fault(ring);
  }
  return true;
}

// An index closes the revolution. Exactly a revolution counted and nothing else wrong: its edges go out with
// their angles, or, while the phase is being decided again, wait for it one more revolution (then NaN).
// Otherwise they went or go out with NaN crank. The next revolution opens at this edge.
bool EdgeStreamAssembler::close_revolution(std::uint32_t raw, std::uint32_t prev, BlockRing& ring) {
  const bool exact = static_cast<std::uint64_t>(prev) + config_.counts_per_edge == config_.counts_per_rev;
  if (rev_.by_index) {
    ++counters_.revolutions_checked;
    if (!exact && !rev_.sync_lost) ++counters_.missing_or_extra;
    if (!exact || rev_.fault) ++counters_.revolutions_flagged;
  }
  if (!exact) count_fault(ring);
  if (!rev_.bad) {
    if (locked_) {
      release_held(held_n_, true, ring);
    } else {
      release_held(confirmed_n_, false, ring);
      confirmed_n_ = held_n_;
    }
  }
  const bool was_valid = psi_valid_;
  const bool unchanged = snap_to_index(raw);
  rev_ = Revolution{};
  rev_.by_index = true;
  lost_threshold_ = config_.counts_per_rev + slack_;
  if (!psi_valid_) {  // in step again: the phase is decided from here
    psi_valid_ = true;
    window_ = Window{};
    last_tdc_ = Tdc{};
  }
  return was_valid && unchanged;
}

// The index edge is at the index (ground truth): the unwrapped count snaps to the nearest whole revolution plus
// what the counter read there. More than a quarter revolution off leaves the revolution number, hence the
// phase, in doubt. Returns true when the count was already there.
bool EdgeStreamAssembler::snap_to_index(std::uint32_t raw) {
  const auto cpr = static_cast<std::int64_t>(config_.counts_per_rev);
  const std::int64_t provisional = count_ + config_.counts_per_edge;
  const std::int64_t whole = floor_div(provisional + cpr / 2, cpr) * cpr;
  if (std::abs(provisional - whole) > cpr / 4 && locked_) lose_phase();
  const std::int64_t snapped = whole + raw;
  const bool unchanged = snapped == provisional;
  count_ = snapped;
  return unchanged;
}

// A check of the open revolution failed: what is held goes out with NaN crank, and so does the rest of it.
void EdgeStreamAssembler::count_fault(BlockRing& ring) {
  rev_.fault = rev_.bad = true;
  release_held(held_n_, false, ring);
}

// The count no longer follows the crank (backward step, jump, lost index): NaN until an index brings it back in
// step, and the phase is decided again after that.
void EdgeStreamAssembler::sync_fault(BlockRing& ring) {
  count_fault(ring);
  rev_.sync_lost = true;
  psi_valid_ = false;
  lose_phase();
}

void EdgeStreamAssembler::lose_phase() {
  locked_ = false;
  mismatches_ = 0;
  window_ = Window{};
  last_tdc_ = Tdc{};
  release_on_lock_ = false;
  peg_sum_ = 0.0;
  peg_n_ = 0;
}

void EdgeStreamAssembler::track_phase(double psi, double pressure, double cam, bool continuous) {
  if (config_.phase == PhaseSource::kCam) {
    if (have_prev_ && prev_cam_ < config_.cam_threshold_v && cam >= config_.cam_threshold_v) {
      // The crank angle of this edge is psi or psi + 360: take the one nearer the cam edge's known angle.
      const double d0 = std::abs(std::remainder(psi - config_.cam_edge_deg, 720.0));
      const double d1 = std::abs(std::remainder(psi + 360.0 - config_.cam_edge_deg, 720.0));
      vote(d0 <= d1 ? 0 : 1);
    }
    return;
  }
  // Pressure: the rise over each TDC window; firing TDC (compression + combustion) rises far more than the
  // gas-exchange TDC, motored or fired, whatever the sensor's offset.
  if (window_.open && psi > 360.0 * static_cast<double>(window_.tdc) + kTdcWindowDeg) {
    window_.open = false;
    if (window_.complete) {
      const double rise = window_.hi - window_.lo;
      const std::int64_t j = window_.tdc;
      if (last_tdc_.valid && last_tdc_.index == j - 1) {
        if (rise > kFiringRiseRatio * last_tdc_.rise)
          vote(static_cast<int>(floor_mod2(j)));
        else if (last_tdc_.rise > kFiringRiseRatio * rise)
          vote(static_cast<int>(floor_mod2(j - 1)));
      }
      last_tdc_ = {j, rise, true};
    }
  }
  const auto j = static_cast<std::int64_t>(std::llround(psi / 360.0));
  if (std::abs(psi - 360.0 * static_cast<double>(j)) > kTdcWindowDeg) return;
  if (!window_.open || window_.tdc != j) {
    // Complete only when an edge before the window was seen: its rise then covers the whole window.
    window_ = {j, pressure, pressure, true, continuous && prev_psi_ < 360.0 * static_cast<double>(j) - kTdcWindowDeg};
  } else {
    window_.lo = std::min(window_.lo, pressure);
    window_.hi = std::max(window_.hi, pressure);
  }
}

void EdgeStreamAssembler::vote(int phase) {
  if (!locked_) {
    phase_ = phase;
    locked_ = true;
    mismatches_ = 0;
    release_on_lock_ = true;
    return;
  }
  if (phase == phase_) {
    mismatches_ = 0;
    return;
  }
  if (++mismatches_ >= kMismatchesToCorrect) {
    phase_ = phase;
    mismatches_ = 0;
    ++counters_.phase_corrections;
  }
}

// Pegging, and whether the edge goes out: nothing before the first lock (and, with a relative sensor, the first
// pegging) since the (re)start; after that every edge, with NaN crank where the angle is not known.
bool EdgeStreamAssembler::gate(double psi, double pressure) {
  if (!output_ && !locked_) {
    ++counters_.edges_before_lock;
    return false;
  }
  if (config_.peg_pa > 0.0) {
    if (locked_ && !rev_.bad) {
      peg(psi + 360.0 * phase_, pressure);
    } else {
      peg_sum_ = 0.0;
      peg_n_ = 0;
    }
  }
  if (!output_) {
    if (!peg_known_) {
      ++counters_.edges_before_lock;
      return false;
    }
    output_ = true;
  }
  return true;
}

void EdgeStreamAssembler::peg(double theta, double pressure) {
  const double a = model::CrankKinematics::cycle_angle(theta);
  if (std::abs(std::remainder(a - config_.peg_angle_deg, 720.0)) <= 0.5 * config_.peg_window_deg) {
    peg_sum_ += pressure;
    ++peg_n_;
  } else if (peg_n_ > 0) {  // just left the pegging window: the relative sensor's offset for this cycle
    peg_prev_offset_ = peg_offset_;
    peg_offset_ = config_.peg_pa - peg_sum_ / static_cast<double>(peg_n_);
    peg_cycle_ = cycle_of(theta);
    peg_known_ = true;
    peg_sum_ = 0.0;
    peg_n_ = 0;
  }
}

// An edge of a revolution not confirmed yet waits for its index.
void EdgeStreamAssembler::hold(double t, double x, double psi, BlockRing& ring) {
  if (held_n_ == held_.size()) {  // edges on and on without the count reaching an index (a stuck counter)
    ++counters_.lost_index;
    sync_fault(ring);
    emit(t, x, kNaN, ring);
    return;
  }
  held_[(held_head_ + held_n_) % held_.size()] = {t, x, psi};
  ++held_n_;
}

// The oldest n held edges go out, with their angles (the phase as now known) or NaN crank.
void EdgeStreamAssembler::release_held(std::size_t n, bool angles, BlockRing& ring) {
  n = std::min(n, held_n_);
  for (std::size_t i = 0; i < n; ++i) {
    const Held& e = held_[held_head_];
    emit(e.t, e.x, angles ? e.psi + 360.0 * phase_ : kNaN, ring);
    held_head_ = (held_head_ + 1) % held_.size();
  }
  held_n_ -= n;
  confirmed_n_ -= std::min(confirmed_n_, n);
}

// The offset of the pegging that belongs to the cycle of theta (the previous cycle's for an edge held that long; the
// latest for an unknown angle or an older cycle).
double EdgeStreamAssembler::peg_offset_of(double theta) const {
  if (std::isfinite(theta) && peg_cycle_ != INT64_MIN && cycle_of(theta) == peg_cycle_ - 1) return peg_prev_offset_;
  return peg_offset_;
}

// A relative sensor's edge is pegged with its own cycle's offset, measured at peg_angle_deg of that cycle: the
// edges before it wait for it (and the edges after them, to stay in order), so that one offset holds for the whole
// cycle. No pegging for two revolutions (a window missed): the waiting edges go with the offset in hand.
void EdgeStreamAssembler::emit(double t, double x, double theta, BlockRing& ring) {
  if (!(config_.peg_pa > 0.0)) return feed(t, x, theta, ring);
  while (peg_wait_n_ > 0) {
    const Held& w = peg_wait_[peg_wait_head_];
    if (std::isfinite(w.psi) && cycle_of(w.psi) > peg_cycle_ && peg_wait_n_ < peg_wait_.size()) break;
    feed(w.t, w.x + peg_offset_of(w.psi), w.psi, ring);
    peg_wait_head_ = (peg_wait_head_ + 1) % peg_wait_.size();
    --peg_wait_n_;
  }
  if (peg_wait_n_ == 0 && !(std::isfinite(theta) && cycle_of(theta) > peg_cycle_))
    return feed(t, x + peg_offset_of(theta), theta, ring);
  peg_wait_[(peg_wait_head_ + peg_wait_n_++) % peg_wait_.size()] = {t, x, theta};
}

// What waits for its pegging goes out with the offset in hand (at a stop, before a restart).
void EdgeStreamAssembler::release_pegged(BlockRing& ring) {
  for (; peg_wait_n_ > 0; --peg_wait_n_, peg_wait_head_ = (peg_wait_head_ + 1) % peg_wait_.size()) {
    const Held& w = peg_wait_[peg_wait_head_];
    feed(w.t, w.x + peg_offset_of(w.psi), w.psi, ring);
  }
}

// One edge into the resampler (pressure) and the crank-angle history.
void EdgeStreamAssembler::feed(double t, double x, double theta, BlockRing& ring) {
  const bool checked = config_.index_resets_counter;
  if (checked && have_fed_ && t - last_fed_t_ > kMaxEdgeGapS) restart_resampler(ring);
  if (have_fed_ && !(t > last_fed_t_)) {  // cannot happen with positive tick steps; keep the resampler safe
    ++counters_.encoder_errors;
    return;
  }
  t_[batch_] = t;
  x_[batch_] = x;
  ++batch_;
  if (angle_ring_) {
    double* e = angle_writer_.edge(t * kPipelineRateHz, angle_block_edges_, *angle_ring_);
    e[kAngleCrankChannel] = model::CrankKinematics::cycle_angle(theta);
    e[kAnglePressureChannel] = x;
  }
  history_[history_end_ % kHistory] = {t, theta};
  ++history_end_;
  have_fed_ = true;
  last_fed_t_ = t;
  if (batch_ == kEdgeBatch || (checked && t - t_[0] >= kMaxBatchSpanS)) run_batch(ring);
}

// No edge for kMaxEdgeGapS (the engine stopped, a stall): what the resampler has goes out and it starts afresh
// at the next edge, leaving a gap in the stream rather than pressure and angle interpolated across the pause.
void EdgeStreamAssembler::restart_resampler(BlockRing& ring) {
  run_batch(ring);
  resampler_ = make_resampler(config_);
  history_end_ = cursor_ = 0;
  have_fed_ = false;
}

double EdgeStreamAssembler::crank_at(double t) {
  const std::uint64_t oldest = history_end_ > kHistory ? history_end_ - kHistory : 0;
  cursor_ = std::max(cursor_, oldest);
  while (cursor_ + 1 < history_end_ && history_[(cursor_ + 1) % kHistory].t <= t) ++cursor_;
  // Linear between the bracketing edges (the angle is smooth on this scale); at the ends, the nearest pair.
  // NaN (an angle not known) at either end makes the frame's angle NaN.
  std::uint64_t a = cursor_;
  if (a + 1 >= history_end_ && a > oldest) --a;
  if (a + 1 >= history_end_) return history_[a % kHistory].theta;
  const Edge& e0 = history_[a % kHistory];
  const Edge& e1 = history_[(a + 1) % kHistory];
  return e0.theta + (e1.theta - e0.theta) * (t - e0.t) / (e1.t - e0.t);
}

void EdgeStreamAssembler::run_batch(BlockRing& ring) {
  std::size_t n = batch_;
  batch_ = 0;
  for (bool first = true; first || n == out_.size(); first = false) {
    n = resampler_.process(t_.data(), x_.data(), first ? n : 0, out_.data(), out_.size());
    std::int64_t k = resampler_.next_output_index() - static_cast<std::int64_t>(n);
    for (std::size_t f = 0; f < n; ++f, ++k) {
      double* slot = writer_.frame(k, ring);
      slot[kPressureChannel] = out_[f];
      slot[kCrankChannel] = model::CrankKinematics::cycle_angle(crank_at(static_cast<double>(k) / kPipelineRateHz));
    }
    counters_.frames += n;
  }
}

void EdgeStreamAssembler::deliver(BlockRing& ring, bool all) {
  if (all && held_n_ > 0) {  // at stop or before a restart: what is held goes out unconfirmed, as does its rest
    release_held(held_n_, false, ring);
    rev_.bad = true;
  }
  if (all) release_pegged(ring);
  run_batch(ring);
  if (all || writer_.pending_frames() >= SampleBlock::kMaxFrames / 2) {
    writer_.flush(ring);
    // The edges go out with the 40 kHz frames made from them (the processing waits for both streams).
    if (angle_ring_) angle_writer_.flush(*angle_ring_);
  }
}

}  // namespace noisemon::drivers::comedi
