#include "drivers/comedi_streams.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "model/engine_cycle.hpp"

namespace noisemon::drivers {
namespace {

constexpr std::size_t kEdgeBatch = 1024;       // edges per resampler call
constexpr std::size_t kOutFrames = 8192;       // resampler output room per call (frames)
constexpr std::size_t kHistory = 1 << 15;      // recent edges kept for the crank-angle interpolation
constexpr double kTdcWindowDeg = 30.0;         // pressure rise measured over TDC +- this
constexpr double kFiringRiseRatio = 3.0;       // firing TDC's rise must exceed the other TDC's by this factor
constexpr int kMismatchesToCorrect = 2;        // consecutive contrary phase votes before re-phasing
constexpr std::size_t kCardBatch = 1024;       // card scans per resampler call

std::int64_t floor_mod2(std::int64_t j) { return ((j % 2) + 2) % 2; }

}  // namespace

// ---------------------------------------------------------------------------------------------- edges

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
  if (c.timestamp_bits < 8 || c.timestamp_bits > 32) fail("timestamp_bits must be in [8, 32] (comedi samples are 32-bit at most)");
  if (c.peg_pa > 0.0 && !(c.peg_window_deg > 0.0 && c.peg_window_deg < 180.0)) fail("peg_window_deg must be in (0, 180)");
  if (c.max_scan_skew == 0) fail("max_scan_skew must be positive");
  for (std::uint32_t n : c.stream_channels) {
    Fifo f;
    f.channels = n;
    f.values.resize((c.max_scan_skew + 1) * n);
    fifos_.push_back(std::move(f));
  }
  restart(epoch_utime);
}

EdgeStreamAssembler::~EdgeStreamAssembler() = default;

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
  peg_known_ = !(config_.peg_pa > 0.0);
  peg_offset_ = peg_sum_ = 0.0;
  peg_n_ = 0;
  resampler_ = dsp::NonuniformResampler(kPipelineRateHz, 1);
  batch_ = 0;
  history_end_ = cursor_ = 0;
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
  const std::uint64_t raw = ticks_raw & tick_mask_;
  const std::uint64_t cpr = config_.counts_per_rev;
  const std::uint64_t pos = position % cpr;
  if (!have_prev_) {
    ticks_ = raw;
    count_ = static_cast<std::int64_t>(pos);
  } else {
    const std::uint64_t delta = config_.timestamp_mode == TimestampMode::kAbsolute ? (raw - prev_ticks_raw_) & tick_mask_ : raw;
    if (delta == 0) {  // two edges at one instant: a glitch; the edge cannot be placed in time
      ++counters_.encoder_errors;
      return;
    }
    ticks_ += delta;
    auto step = static_cast<std::int64_t>((pos + cpr - prev_position_) % cpr);
    if (step > static_cast<std::int64_t>(cpr / 2)) {  // backwards: reverse rotation or a counting glitch
      step -= static_cast<std::int64_t>(cpr);
      ++counters_.encoder_errors;
    }
    count_ += step;
  }
  prev_ticks_raw_ = raw;
  prev_position_ = pos;
  const double t = origin_s_ + static_cast<double>(ticks_) / config_.timebase_hz;
  const double psi = static_cast<double>(count_) * 360.0 / static_cast<double>(cpr) + config_.index_angle_deg;
  track_phase(psi, pressure, cam);
  have_prev_ = true;
  prev_psi_ = psi;
  prev_cam_ = cam;
  if (!locked_) {
    ++counters_.edges_before_lock;
    return;
  }
  const double theta = psi + 360.0 * phase_;
  if (config_.peg_pa > 0.0) {
    const double a = model::CrankKinematics::cycle_angle(theta);
    if (std::abs(std::remainder(a - config_.peg_angle_deg, 720.0)) <= 0.5 * config_.peg_window_deg) {
      peg_sum_ += pressure;
      ++peg_n_;
    } else if (peg_n_ > 0) {  // just left the pegging window: the relative sensor's offset for this cycle
      peg_offset_ = config_.peg_pa - peg_sum_ / static_cast<double>(peg_n_);
      peg_known_ = true;
      peg_sum_ = 0.0;
      peg_n_ = 0;
    }
  }
  if (!peg_known_) {
    ++counters_.edges_before_lock;
    return;
  }
  if (batch_ > 0 && !(t > t_[batch_ - 1])) {  // cannot happen with positive tick steps; keep the resampler safe
    ++counters_.encoder_errors;
    return;
  }
  t_[batch_] = t;
  x_[batch_] = pressure + peg_offset_;
  ++batch_;
  history_[history_end_ % kHistory] = {t, theta};
  ++history_end_;
  if (batch_ == kEdgeBatch) run_batch(ring);
}

void EdgeStreamAssembler::track_phase(double psi, double pressure, double cam) {
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
        if (rise > kFiringRiseRatio * last_tdc_.rise) vote(static_cast<int>(floor_mod2(j)));
        else if (last_tdc_.rise > kFiringRiseRatio * rise) vote(static_cast<int>(floor_mod2(j - 1)));
      }
      last_tdc_ = {j, rise, true};
    }
  }
  const auto j = static_cast<std::int64_t>(std::llround(psi / 360.0));
  if (std::abs(psi - 360.0 * static_cast<double>(j)) > kTdcWindowDeg) return;
  if (!window_.open || window_.tdc != j) {
    // Complete only when an edge before the window was seen: its rise then covers the whole window.
    window_ = {j, pressure, pressure, true, have_prev_ && prev_psi_ < 360.0 * static_cast<double>(j) - kTdcWindowDeg};
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

double EdgeStreamAssembler::crank_at(double t) {
  const std::uint64_t oldest = history_end_ > kHistory ? history_end_ - kHistory : 0;
  cursor_ = std::max(cursor_, oldest);
  while (cursor_ + 1 < history_end_ && history_[(cursor_ + 1) % kHistory].t <= t) ++cursor_;
  // Linear between the bracketing edges (the angle is smooth on this scale); at the ends, the nearest pair.
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
  run_batch(ring);
  if (all || writer_.pending_frames() >= SampleBlock::kMaxFrames / 2) writer_.flush(ring);
}

// ---------------------------------------------------------------------------------------------- timed

namespace {
double whole_rate(double hz) {
  const double r = std::round(hz);
  if (!(r >= 1.0) || std::abs(hz - r) > 1e-6 * r)
    throw std::invalid_argument("card scan rate " + std::to_string(hz) +
                                " Hz is not a whole number of Hz (choose a rate whose period the card's timer hits exactly, e.g. 50000)");
  return r;
}
}  // namespace

TimedStreamAssembler::TimedStreamAssembler(std::uint32_t channels, double card_rate_hz, std::int64_t epoch_utime)
    : channels_(channels),
      card_rate_hz_(whole_rate(card_rate_hz)),
      epoch_utime_(epoch_utime),
      resampler_(card_rate_hz_, kPipelineRateHz, channels),
      in_(kCardBatch * channels),
      out_((resampler_.max_output_frames(kCardBatch) + 1) * channels),
      writer_(channels) {
  if (channels == 0 || channels > SampleBlock::kMaxChannels)
    throw std::invalid_argument("timed stream needs 1.." + std::to_string(SampleBlock::kMaxChannels) + " channels");
}

TimedStreamAssembler::~TimedStreamAssembler() = default;

void TimedStreamAssembler::restart(std::int64_t origin_utime) {
  // 40 kHz frames are 25 us apart.
  first_index_ = std::llround(static_cast<double>(origin_utime - epoch_utime_) / 25.0);
  resampler_ = dsp::RationalResampler(card_rate_hz_, kPipelineRateHz, channels_);
  batch_ = 0;
}

void TimedStreamAssembler::add_scan(const double* values, BlockRing& ring) {
  std::copy_n(values, channels_, &in_[batch_ * channels_]);
  if (++batch_ == kCardBatch) run_batch(ring);
}

void TimedStreamAssembler::run_batch(BlockRing& ring) {
  if (batch_ == 0) return;
  const std::size_t room = out_.size() / channels_;
  const std::size_t n = resampler_.process(in_.data(), batch_, out_.data(), room);
  batch_ = 0;
  std::int64_t local = resampler_.next_output_index() - static_cast<std::int64_t>(n);
  for (std::size_t f = 0; f < n; ++f, ++local) {
    if (local < kSettleFrames) continue;
    double* slot = writer_.frame(first_index_ + local, ring);
    std::copy_n(&out_[f * channels_], channels_, slot);
    ++frames_;
  }
}

void TimedStreamAssembler::deliver(BlockRing& ring, bool all) {
  run_batch(ring);
  if (all || writer_.pending_frames() >= SampleBlock::kMaxFrames / 2) writer_.flush(ring);
}

}  // namespace noisemon::drivers
