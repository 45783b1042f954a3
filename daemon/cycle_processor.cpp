#include "daemon/cycle_processor.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>

#include "dsp/math_constants.hpp"
#include "dsp/weighting.hpp"

namespace noisemon::daemon {
namespace {

constexpr double kFs = drivers::kPipelineRateHz;
constexpr std::size_t kChunkFrames = 512;
constexpr std::size_t kModelPrimeFrames = 4096;   // 0.1 s: many time constants of the block model's modes
constexpr double kGridStepDeg = 0.25;             // the combustion metrics' crank-angle grid from the 40 kHz frames
constexpr std::int64_t kAngleWaitFrames = 20000;  // 0.5 s: how long the processing waits for a crank-angle stream
constexpr std::size_t kReplacedChannel = drivers::kPressureStreamChannels;  // pressure FIFO: 1 where replaced
constexpr std::size_t kPressureFifoChannels = drivers::kPressureStreamChannels + 1;
constexpr double kOverloadFraction = 0.99;    // of the full scale: a sample there was clipped
constexpr double kHiddenBoundaryRatio = 1.5;  // a flagged-encoder cycle this much longer than a good one hid a boundary

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double overload_level(double full_scale) { return full_scale > 0 ? kOverloadFraction * full_scale : kInf; }

}  // namespace

// Adds the processing thread's CPU time spent in one call to cpu_spent_s_ (idle polling is not counted), unless a
// CpuBatch around the call times it.
struct CycleProcessor::CpuScope {
  explicit CpuScope(CycleProcessor& p) : p_(p), start_(p.cpu_batch_open_ ? 0.0 : thread_cpu_seconds()) {}
  ~CpuScope() {
    if (!p_.cpu_batch_open_) p_.cpu_spent_s_ += thread_cpu_seconds() - start_;
  }
  CycleProcessor& p_;
  double start_;
};

CycleProcessor::CpuBatch::CpuBatch(CycleProcessor& p) : p_(p), start_(thread_cpu_seconds()) {
  p_.cpu_batch_open_ = true;
}
CycleProcessor::CpuBatch::~CpuBatch() {
  p_.cpu_batch_open_ = false;
  p_.cpu_spent_s_ += thread_cpu_seconds() - start_;
}

CycleProcessor::CycleProcessor(const ProcessorConfig& config, const drivers::StreamInfo& info, Sink sink)
    : config_(config),
      info_(info),
      sink_(std::move(sink)),
      mics_(info.mic_count),
      bank_channels_(2 + info.mic_count + (config.time_average_mics && info.mic_count > 0 ? 1 : 0)),
      delay_frames_(
          std::llround((config.acoustic_delay_s >= 0 ? config.acoustic_delay_s : info.acoustic_delay_s) * kFs)),
      model_(config.model, kFs),
      model_latency_(static_cast<std::int64_t>(model_.latency_samples())),
      pressure_(kPressureFifoChannels, static_cast<std::size_t>(config.fifo_seconds * kFs)),
      predicted_(1, static_cast<std::size_t>(config.fifo_seconds * kFs)),
      mics_fifo_(info.mic_count, static_cast<std::size_t>(config.fifo_seconds * kFs)),
      clean_(drivers::SampleBlock::kMaxFrames * kPressureFifoChannels),
      model_in_(drivers::SampleBlock::kMaxFrames),
      model_out_(drivers::SampleBlock::kMaxFrames),
      model_prime_(drivers::SampleBlock::kMaxFrames),
      bank_(kFs, bank_channels_),
      sound_power_(config.sound_power, info, bank_.bands()),
      chunk_(bank_channels_ * kChunkFrames),
      mean_square_(bank_channels_ * 64),
      windows_(1 + info.mic_count, kFs),
      stats_(1 + info.mic_count),
      replaced_until_(1 + info.mic_count, INT64_MIN),
      pressure_overload_pa_(overload_level(info.pressure_full_scale_pa)),
      mic_overload_pa_(overload_level(info.mic_full_scale_pa)),
      frame_grid_(kGridStepDeg),
      angle_(info.pressure_angle_step_deg > 0
                 ? std::make_unique<AngleCycles>(info.pressure_angle_step_deg, config.fifo_seconds * kFs)
                 : nullptr) {
  // 0 microphones: a pressure-only recording (an imported cycle table); measured levels are then NaN.
  if (info.mic_count > kMaxMics)
    throw std::invalid_argument("CycleProcessor: microphone count must be 0.." + std::to_string(kMaxMics));
  if (bank_.band_count() > kMaxBands) throw std::logic_error("CycleProcessor: too many bands");
  mean_square_.assign(bank_channels_ * bank_.band_count(), 0.0);
  for (const dsp::ThirdOctaveBand& b : bank_.bands())
    a_gain_.push_back(std::pow(10.0, dsp::a_weighting_db(b.exact_mid_hz) / 10.0));
  reset_stats();
}

CycleProcessor::~CycleProcessor() = default;

void CycleProcessor::note_gap(std::int64_t from, std::int64_t to) {
  gaps_.push_back({from, to});
  counters_.gap_frames += to - from;
}

// Copies the block into clean_ as the pressure FIFO holds it. Returns the first frame to keep: before the first
// finite pressure ever seen, non-finite pressure is not data (there is nothing to hold), so the stream begins later.
std::uint32_t CycleProcessor::sanitise_pressure(const drivers::SampleBlock& block) {
  std::uint32_t from = 0;
  if (!have_finite_pressure_)
    while (from < block.frames && !std::isfinite(block.data[from * block.channels + drivers::kPressureChannel])) ++from;
  for (std::uint32_t f = from; f < block.frames; ++f) {
    const double* in = block.data + f * block.channels;
    double* out = &clean_[(f - from) * kPressureFifoChannels];
    const bool finite = std::isfinite(in[drivers::kPressureChannel]);
    if (finite) last_finite_pressure_ = in[drivers::kPressureChannel];
    out[drivers::kPressureChannel] = last_finite_pressure_;
    out[drivers::kCrankChannel] = in[drivers::kCrankChannel];
    out[kReplacedChannel] = finite ? 0.0 : 1.0;
  }
  if (from < block.frames) have_finite_pressure_ = true;
  return from;
}

void CycleProcessor::add_pressure(const drivers::SampleBlock& block) {
  CpuScope cpu(*this);
  if (block.channels != drivers::kPressureStreamChannels)
    throw std::invalid_argument("CycleProcessor: pressure block with " + std::to_string(block.channels) + " channels");
  const std::uint32_t from = sanitise_pressure(block);
  if (from == block.frames) return;
  const std::int64_t first = block.first_index + from;
  const auto n = static_cast<std::int64_t>(block.frames - from);
  const std::int64_t end_before = pressure_.started() ? pressure_.end_index() : first;
  const FrameFifo::Appended added = pressure_.append(first, clean_.data(), static_cast<std::size_t>(n));
  counters_.frames_discarded += static_cast<std::int64_t>(added.dropped);
  if (added.restarted) {
    // A stall longer than the FIFO holds: the model restarts, settled at the new pressure.
    note_gap(end_before, first + model_latency_);
    model_primed_ = false;
  } else if (added.held > 0) {
    // The model sees held pressure across the gap; its output is disturbed for a while after it too.
    note_gap(end_before, first + model_latency_);
    feed_held_to_model(end_before, first);  // so that its time base stays on the grid
  }
  const std::int64_t new_first = std::max(first, end_before);
  const std::int64_t skip = new_first - first;
  if (skip >= n) return;
  for (std::int64_t f = skip; f < n; ++f)
    model_in_[static_cast<std::size_t>(f - skip)] =
        clean_[static_cast<std::size_t>(f) * kPressureFifoChannels + drivers::kPressureChannel];
  run_model(new_first, static_cast<std::size_t>(n - skip));
}

void CycleProcessor::feed_held_to_model(std::int64_t from, std::int64_t to) {
  for (std::int64_t i = from; i < to; i += drivers::SampleBlock::kMaxFrames) {
    const auto frames = static_cast<std::size_t>(std::min<std::int64_t>(drivers::SampleBlock::kMaxFrames, to - i));
    for (std::size_t f = 0; f < frames; ++f)
      model_in_[f] = pressure_.frame(i + static_cast<std::int64_t>(f))[drivers::kPressureChannel];
    run_model(i, frames);
  }
}

void CycleProcessor::run_model(std::int64_t first, std::size_t n) {
  if (!model_primed_) {
    // The engine did not start with our first sample: settle the model at the first pressure (its static
    // equilibrium) instead of hitting it with a step from zero, whose ringing would spill into the first cycle.
    std::fill(model_prime_.begin(), model_prime_.end(), model_in_[0]);
    for (std::size_t done = 0; done < kModelPrimeFrames; done += model_prime_.size())
      model_.process(model_prime_.data(), model_out_.data(), model_prime_.size());
    model_primed_ = true;
  }
  model_.process(model_in_.data(), model_out_.data(), n);
  // Output j of the model describes the instant of input j - latency.
  counters_.frames_discarded +=
      static_cast<std::int64_t>(predicted_.append(first - model_latency_, model_out_.data(), n).dropped);
}

void CycleProcessor::add_pressure_angle(const drivers::SampleBlock& block) {
  CpuScope cpu(*this);
  if (!angle_)
    throw std::invalid_argument("CycleProcessor: crank-angle block for a stream without a crank-angle stream");
  if (block.channels != drivers::kAngleStreamChannels)
    throw std::invalid_argument("CycleProcessor: crank-angle block with " + std::to_string(block.channels) +
                                " channels");
  angle_->add(block);
}

// How far the crank-angle stream lets the processing go. Until its first block has come the processing waits, at
// most kAngleWaitFrames of pressure (a log of a source that had the stream but did not record it): whether a
// cycle's figures come from the edges then depends on what the streams hold, not on which arrived first.
std::int64_t CycleProcessor::angle_end(std::int64_t end) {
  if (angle_->started()) return angle_->covered_until();
  if (angle_abandoned_) return end;
  const auto wait = std::min(kAngleWaitFrames, static_cast<std::int64_t>(pressure_.capacity() / 2));
  if (end - next_ <= wait) return next_;
  angle_abandoned_ = true;
  return end;
}

void CycleProcessor::add_mics(const drivers::SampleBlock& block) {
  CpuScope cpu(*this);
  if (mics_ == 0) throw std::invalid_argument("CycleProcessor: microphone block for a stream without microphones");
  if (block.channels != mics_)
    throw std::invalid_argument("CycleProcessor: microphone block with " + std::to_string(block.channels) +
                                " channels, expected " + std::to_string(mics_));
  const std::int64_t end_before = mics_fifo_.started() ? mics_fifo_.end_index() : block.first_index;
  const FrameFifo::Appended added = mics_fifo_.append(block.first_index, block.data, block.frames);
  counters_.frames_discarded += static_cast<std::int64_t>(added.dropped);
  if (added.held > 0 || added.restarted) note_gap(end_before - delay_frames_, block.first_index - delay_frames_);
}

void CycleProcessor::set_operating_point(const drivers::OperatingPoint& op) {
  op_ = op;
  have_op_ = true;
}

void CycleProcessor::process() {
  CpuScope cpu(*this);
  const bool with_mics = mics_ > 0;
  if (!pressure_.started() || (with_mics && !mics_fifo_.started()) || !predicted_.started()) return;
  if (next_ == INT64_MIN) {
    next_ = std::max(pressure_.begin_index(), predicted_.begin_index());
    if (with_mics) next_ = std::max(next_, mics_fifo_.begin_index() - delay_frames_);
    settle_from_ = next_;
  }
  // Frames a stalled stream's partners pushed out of their FIFOs are gone: continue where all streams have data.
  std::int64_t earliest = std::max(pressure_.begin_index(), predicted_.begin_index());
  if (with_mics) earliest = std::max(earliest, mics_fifo_.begin_index() - delay_frames_);
  if (next_ < earliest) {
    note_gap(next_, earliest);
    next_ = earliest;
    have_last_crank_ = false;  // a cycle boundary may lie in the gap
    frame_grid_.break_line();
  }
  std::int64_t end = std::min(pressure_.end_index(), predicted_.end_index());
  if (with_mics) end = std::min(end, mics_fifo_.end_index() - delay_frames_);
  if (angle_ && !streams_ended_) end = std::min(end, angle_end(end));
  for (; next_ < end; ++next_) {
    const double* p = pressure_.frame(next_);
    const double crank = p[drivers::kCrankChannel];
    if (!std::isfinite(crank)) {
      unknown_crank();
    } else {
      // A cycle starts where the crank angle wraps from just below +360 to -360.
      if (have_last_crank_ && crank < last_crank_ - 360.0) close_cycle(crank, p[drivers::kPressureChannel]);
      window_ = CrankWindows::window_of(crank);
      frame_grid_.add(crank, p[drivers::kPressureChannel]);
      last_crank_ = crank;
      have_last_crank_ = true;
      crank_unknown_ = false;
    }
    add_frame(p);
  }
  // Keep what later combined frames still need.
  pressure_.drop_before(next_);
  predicted_.drop_before(next_);
  if (with_mics) mics_fifo_.drop_before(next_ + delay_frames_);
}

// The angle is not known: no boundary can be seen here and the grid gets nothing (nor an interpolation across).
void CycleProcessor::unknown_crank() {
  ++counters_.crank_unknown_frames;
  crank_unknown_ = true;
  cycle_encoder_ = true;
  frame_grid_.break_line();
}

void CycleProcessor::close_cycle(double crank_deg, double pressure_pa) {
  // The ending cycle's grid reaches +360 deg with this frame; the new one's starts from the last frame.
  frame_grid_.close(crank_deg, pressure_pa);
  flush_chunk();
  finish_cycle(next_);
  frame_grid_.reopen(-360.0);
  // The first known angle after an unknown stretch: the wrap happened somewhere inside it, the start is uncertain.
  cycle_encoder_ = crank_unknown_;
}

// Frame next_ into the bank's chunk (microphone samples made finite), and into the channels' statistics.
void CycleProcessor::add_frame(const double* p) {
  double* out = &chunk_[chunk_frames_ * bank_channels_];
  const double pa = p[drivers::kPressureChannel];
  out[0] = pa;
  out[1] = predicted_.frame(next_)[0];
  ChannelStats& ps = stats_[0];
  ps.min = std::min(ps.min, pa);
  ps.max = std::max(ps.max, pa);
  if (p[kReplacedChannel] != 0) {
    ++ps.replaced;
    ++counters_.samples_replaced;
    replaced_until_[0] = next_ + 1;
  } else if (pa >= pressure_overload_pa_) {
    ps.overload = true;
  }
  if (mics_ > 0) {
    const double* m = mics_fifo_.frame(next_ + delay_frames_);
    for (std::size_t c = 0; c < mics_; ++c) {
      ChannelStats& s = stats_[1 + c];
      double x = m[c];
      if (!std::isfinite(x)) {
        x = 0.0;
        ++s.replaced;
        ++counters_.samples_replaced;
        replaced_until_[1 + c] = next_ + 1;
      } else if (std::abs(x) >= mic_overload_pa_) {
        s.overload = true;
      }
      s.min = std::min(s.min, x);
      s.max = std::max(s.max, x);
      out[2 + c] = x;
    }
    if (config_.time_average_mics) {
      const std::vector<double>& weights = sound_power_.area_weights();
      double mean = 0;
      for (std::size_t c = 0; c < mics_; ++c) mean += weights[c] * out[2 + c];
      out[2 + mics_] = mean;
    }
  }
  windows_.add(window_, out + 1);
  if (++chunk_frames_ == kChunkFrames) flush_chunk();
}

void CycleProcessor::flush_chunk() {
  if (chunk_frames_ == 0) return;
  bank_.process(chunk_.data(), chunk_frames_);
  counters_.frames_processed += static_cast<std::int64_t>(chunk_frames_);
  chunk_frames_ = 0;
}

void CycleProcessor::reset_stats() { std::fill(stats_.begin(), stats_.end(), ChannelStats{kInf, -kInf, 0, false}); }

// The channels' verdicts on the cycle [start, end_index) just ended; the statistics restart for the next one.
CycleProcessor::CycleHealth CycleProcessor::take_health(std::int64_t start, std::int64_t end_index) {
  CycleHealth h;
  // Samples replaced shortly before the cycle: the filters still ring from the step at the stretch's end. Bands
  // slower than the cycle are flagged BAND_SLOW (smeared over neighbouring cycles) and do not count here.
  const double cycle_s = start == INT64_MIN ? 0.0 : static_cast<double>(end_index - start) / kFs;
  double ring_s = 0;
  for (const dsp::ThirdOctaveBand& b : bank_.bands())
    if (b.response_time_s <= cycle_s) ring_s = std::max(ring_s, b.response_time_s);
  const auto replaced = [&](std::size_t ch) {
    if (stats_[ch].replaced > 0) return true;
    if (start == INT64_MIN || replaced_until_[ch] == INT64_MIN) return false;
    return static_cast<double>(start - replaced_until_[ch]) < ring_s * kFs;
  };
  // A stuck converter repeats one code; after resampling to 40 kHz only rounding remains (1e-16 relative), far
  // below any converter's step (a 24-bit step is 6e-8 of full scale). Never true before any frame: inf > -inf.
  const auto flat = [](const ChannelStats& s) {
    return s.max >= s.min && s.max - s.min <= 1e-9 * std::max(std::abs(s.max), std::abs(s.min));
  };
  const ChannelStats& ps = stats_[0];
  h.pressure_fault = flat(ps) || ps.overload || replaced(0);
  h.overload = ps.overload;
  for (std::size_t m = 0; m < mics_; ++m) {
    const ChannelStats& s = stats_[1 + m];
    std::int8_t f = 0;
    if (flat(s)) f |= kMicFlat;
    if (s.overload) f |= kMicOverload;
    if (replaced(1 + m)) f |= kMicNan;
    h.mic_flags[m] = f;
    h.overload = h.overload || s.overload;
  }
  reset_stats();
  return h;
}

// The combustion metrics of the cycle just ended, then a fresh grid (only complete grids give numbers).
// The grid of the cycle [start, end_index): the crank-angle stream's cycle that closes at end_index, or the frames'
// when the stream has none. Its closing edge lies within an edge spacing after end_index, its block begins at most a
// block's span before that edge: the tolerance is a block of this cycle's edges and two more (an eighth of the cycle
// and a little: neighbouring cycles stay apart).
CrankGrid* CycleProcessor::combustion_grid(std::int64_t start, std::int64_t end_index, bool& angle_gap) {
  if (!angle_ || !angle_->started()) return &frame_grid_;
  const double cycle = start == INT64_MIN ? 0.0 : static_cast<double>(end_index - start);
  const double block = cycle * drivers::max_edges_per_angle_block(angle_->step_deg()) * angle_->step_deg() / 720.0;
  CrankGrid* grid = angle_->take(end_index, 2.0 + block + cycle * angle_->step_deg() / 360.0);
  angle_gap = grid == nullptr || !grid->complete();
  return grid;
}

model::CombustionMetrics CycleProcessor::take_combustion(std::int64_t start, std::int64_t end_index, bool wanted,
                                                         bool& angle_gap) {
  model::CombustionMetrics combustion;  // NaN throughout unless the grid is complete
  angle_gap = false;
  CrankGrid* grid = combustion_grid(start, end_index, angle_gap);
  if (wanted && start != INT64_MIN && grid && grid->complete()) {
    model::MetricsOptions options = config_.metrics;  // dp/dtheta max from this cycle's start of injection
    options.soi_deg_btdc = have_op_ && !op_.motored ? op_.soi_deg_btdc : kNaN;
    combustion = grid->metrics(config_.engine, 720.0 / 360.0 * 60.0 * kFs / static_cast<double>(end_index - start),
                               options, metrics_scratch_);
  }
  return combustion;
}

// Whether samples were lost in [start, end_index); forgets the gaps that end there and restarts the settling.
bool CycleProcessor::take_gaps(std::int64_t start, std::int64_t end_index) {
  bool gap = false;
  std::int64_t last_gap_end = INT64_MIN;
  for (const Gap& g : gaps_) {
    if (g.from >= end_index) continue;
    if (g.to > start) gap = true;
    last_gap_end = std::max(last_gap_end, g.to);
  }
  std::erase_if(gaps_, [&](const Gap& g) { return g.to <= end_index; });
  settle_from_ = std::max(settle_from_, last_gap_end);  // filters restart settling after lost samples
  return gap;
}

// A stretch that hides the boundaries inside it: count the cycles it spans at the last good cycle's length.
void CycleProcessor::count_dropped(double duration_s) {
  const double spanned = last_duration_s_ > 0 ? std::round(duration_s / last_duration_s_) : 1.0;
  const auto n = static_cast<std::int64_t>(std::max(1.0, spanned));
  counters_.cycles_completed += n;
  counters_.cycles_dropped += n;
}

void CycleProcessor::finish_cycle(std::int64_t end_index) {
  bank_.take_mean_square(mean_square_.data());
  windows_.close();
  const std::int64_t start = cycle_start_;
  cycle_start_ = end_index;
  const double cpu_s = cpu_spent_s_;  // calls completed since the previous cycle; the current call counts for the next
  cpu_spent_s_ = 0;
  const CycleHealth health = take_health(start, end_index);
  const bool encoder = cycle_encoder_;
  bool angle_gap = false;
  const model::CombustionMetrics combustion =
      take_combustion(start, end_index, !encoder && !health.pressure_fault, angle_gap);
  if (start == INT64_MIN) return;  // frames before the first boundary only warm the filters up

  const bool gap = take_gaps(start, end_index);
  const double duration = static_cast<double>(end_index - start) / kFs;
  if (gap || (encoder && last_duration_s_ > 0 && duration > kHiddenBoundaryRatio * last_duration_s_)) {
    count_dropped(duration);
    return;
  }
  const std::int64_t cycle = counters_.cycles_completed++;
  const bool odd = last_duration_s_ > 0 && std::abs(duration - last_duration_s_) > 0.1 * last_duration_s_;
  if (!encoder) last_duration_s_ = duration;

  CycleReport r;
  r.utime = drivers::utime_of_frame(info_.epoch_utime, static_cast<double>(start));
  r.window_end_utime = drivers::utime_of_frame(info_.epoch_utime, static_cast<double>(end_index + delay_frames_));
  r.cycle = cycle;
  r.duration_s = duration;
  r.op = op_;
  r.tdc_deg = config_.metrics.tdc_deg;
  r.op.speed_rpm = 720.0 / 360.0 * 60.0 / duration;  // two revolutions per cycle
  r.radius_m = info_.radius_m;
  r.nbands = static_cast<std::uint16_t>(bank_.band_count());
  r.nmics = static_cast<std::uint16_t>(mics_);
  if (!have_op_) r.flags |= kCycleNoOperatingPoint;
  if (odd) r.flags |= kCycleLengthOdd;
  if (mics_ == 0) r.flags |= kCycleNoMics;
  if (encoder) r.flags |= kCycleEncoder;
  if (health.overload) r.flags |= kCycleOverload;
  if (health.pressure_fault) r.flags |= kCyclePressureFault;
  if (angle_gap) r.flags |= kCycleAngleGap;
  std::copy(health.mic_flags, health.mic_flags + mics_, r.mic_flags);

  mic_levels(r);
  select_mics(r);
  band_levels(r, static_cast<double>(start - settle_from_) / kFs, health.pressure_fault);
  window_levels(r, health.pressure_fault);
  r.processing_ms = static_cast<float>(1e3 * cpu_s);
  r.combustion = combustion;
  sink_(r);
}

}  // namespace noisemon::daemon
