#include "daemon/cycle_processor.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>

#include "dsp/levels.hpp"
#include "dsp/weighting.hpp"

namespace noisemon::daemon {
namespace {

constexpr double kFs = drivers::kPipelineRateHz;
constexpr std::size_t kChunkFrames = 512;
constexpr std::size_t kModelPrimeFrames = 4096;  // 0.1 s: many time constants of the block model's modes
constexpr double kGridStepDeg = 0.25;              // the combustion metrics' crank-angle grid
constexpr std::size_t kGridPoints = 2881;          // -360 ... 360 deg

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

std::int64_t utime_of(std::int64_t epoch, double frames) {
  return epoch + static_cast<std::int64_t>(std::llround(frames * 1e6 / kFs));
}

}  // namespace

// Adds the processing thread's CPU time spent in one call to cpu_spent_s_ (idle polling is not counted).
struct CycleProcessor::CpuScope {
  explicit CpuScope(double& sink) : sink_(sink), start_(thread_cpu_seconds()) {}
  ~CpuScope() { sink_ += thread_cpu_seconds() - start_; }
  double& sink_;
  double start_;
};

CycleProcessor::CycleProcessor(const ProcessorConfig& config, const drivers::StreamInfo& info, Sink sink)
    : config_(config),
      info_(info),
      sink_(std::move(sink)),
      mics_(info.mic_count),
      delay_frames_(std::llround((config.acoustic_delay_s >= 0 ? config.acoustic_delay_s : info.acoustic_delay_s) * kFs)),
      model_(config.model, kFs),
      model_latency_(static_cast<std::int64_t>(model_.latency_samples())),
      pressure_(drivers::kPressureStreamChannels, static_cast<std::size_t>(config.fifo_seconds * kFs)),
      predicted_(1, static_cast<std::size_t>(config.fifo_seconds * kFs)),
      mics_fifo_(info.mic_count, static_cast<std::size_t>(config.fifo_seconds * kFs)),
      model_in_(drivers::SampleBlock::kMaxFrames),
      model_out_(drivers::SampleBlock::kMaxFrames),
      bank_(kFs, 2 + info.mic_count),
      chunk_((2 + info.mic_count) * kChunkFrames),
      mean_square_((2 + info.mic_count) * 64),
      grid_(kGridPoints, std::numeric_limits<double>::quiet_NaN()) {
  // 0 microphones: a pressure-only recording (an imported cycle table); measured levels are then NaN.
  if (info.mic_count > kMaxMics)
    throw std::invalid_argument("CycleProcessor: microphone count must be 0.." + std::to_string(kMaxMics));
  if (bank_.band_count() > kMaxBands) throw std::logic_error("CycleProcessor: too many bands");
  mean_square_.assign((2 + mics_) * bank_.band_count(), 0.0);
}

CycleProcessor::~CycleProcessor() = default;

void CycleProcessor::note_gap(std::int64_t from, std::int64_t to) {
  gaps_.push_back({from, to});
  counters_.gap_frames += to - from;
}

void CycleProcessor::add_pressure(const drivers::SampleBlock& block) {
  CpuScope cpu(cpu_spent_s_);
  if (block.channels != drivers::kPressureStreamChannels)
    throw std::invalid_argument("CycleProcessor: pressure block with " + std::to_string(block.channels) + " channels");
  const std::int64_t end_before = pressure_.started() ? pressure_.end_index() : block.first_index;
  const FrameFifo::Appended added = pressure_.append(block.first_index, block.data, block.frames);
  counters_.frames_discarded += static_cast<std::int64_t>(added.dropped);
  if (added.restarted) {
    // A stall longer than the FIFO holds: the model restarts, settled at the new pressure.
    note_gap(end_before, block.first_index + model_latency_);
    model_primed_ = false;
  } else if (added.held > 0) {
    // The model sees held pressure across the gap; its output is disturbed for a while after it too.
    note_gap(end_before, block.first_index + model_latency_);
    // Feed the held frames to the model so its time base stays on the grid.
    for (std::int64_t i = end_before; i < block.first_index; i += drivers::SampleBlock::kMaxFrames) {
      drivers::SampleBlock held;
      held.first_index = i;
      held.channels = drivers::kPressureStreamChannels;
      held.frames = static_cast<std::uint32_t>(std::min<std::int64_t>(drivers::SampleBlock::kMaxFrames, block.first_index - i));
      for (std::uint32_t f = 0; f < held.frames; ++f) held.data[f * held.channels] = pressure_.frame(i + f)[0];
      predict(i, held);
    }
  }
  const std::int64_t new_first = std::max(block.first_index, end_before);
  const std::int64_t skip = new_first - block.first_index;
  if (skip == 0) {
    predict(new_first, block);  // the usual case: all of the block is new, no copy
  } else if (skip < static_cast<std::int64_t>(block.frames)) {
    drivers::SampleBlock fresh;
    fresh.first_index = new_first;
    fresh.channels = block.channels;
    fresh.frames = block.frames - static_cast<std::uint32_t>(skip);
    std::copy(block.data + skip * block.channels, block.data + block.frames * block.channels, fresh.data);
    predict(new_first, fresh);
  }
}

void CycleProcessor::predict(std::int64_t first, const drivers::SampleBlock& block) {
  if (!model_primed_) {
    // The engine did not start with our first sample: settle the model at the first pressure (its static
    // equilibrium) instead of hitting it with a step from zero, whose ringing would spill into the first cycle.
    std::fill(model_in_.begin(), model_in_.end(), block.data[drivers::kPressureChannel]);
    for (std::size_t done = 0; done < kModelPrimeFrames; done += model_in_.size())
      model_.process(model_in_.data(), model_out_.data(), model_in_.size());
    model_primed_ = true;
  }
  for (std::uint32_t f = 0; f < block.frames; ++f) model_in_[f] = block.data[f * block.channels + drivers::kPressureChannel];
  model_.process(model_in_.data(), model_out_.data(), block.frames);
  // Output j of the model describes the instant of input j - latency.
  counters_.frames_discarded +=
      static_cast<std::int64_t>(predicted_.append(first - model_latency_, model_out_.data(), block.frames).dropped);
}

void CycleProcessor::add_mics(const drivers::SampleBlock& block) {
  CpuScope cpu(cpu_spent_s_);
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
  CpuScope cpu(cpu_spent_s_);
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
    grid_has_last_ = false;
  }
  std::int64_t end = std::min(pressure_.end_index(), predicted_.end_index());
  if (with_mics) end = std::min(end, mics_fifo_.end_index() - delay_frames_);
  const std::size_t channels = 2 + mics_;
  for (; next_ < end; ++next_) {
    const double* p = pressure_.frame(next_);
    const double crank = p[drivers::kCrankChannel];
    // A cycle starts where the crank angle wraps from just below +360 to -360.
    if (have_last_crank_ && crank < last_crank_ - 360.0) {
      // The ending cycle's grid reaches +360 deg with this frame; the new one's starts from the last frame.
      const double prev_deg = grid_last_deg_ - 720.0, prev_pa = grid_last_pa_;
      grid_pressure(crank + 720.0, p[drivers::kPressureChannel]);
      flush_chunk();
      finish_cycle(next_);
      grid_last_deg_ = prev_deg;
      grid_last_pa_ = prev_pa;
    }
    grid_pressure(crank, p[drivers::kPressureChannel]);
    last_crank_ = crank;
    have_last_crank_ = true;
    double* out = &chunk_[chunk_frames_ * channels];
    out[0] = p[drivers::kPressureChannel];
    out[1] = predicted_.frame(next_)[0];
    if (with_mics) {
      const double* m = mics_fifo_.frame(next_ + delay_frames_);
      std::copy(m, m + mics_, out + 2);
    }
    if (++chunk_frames_ == kChunkFrames) flush_chunk();
  }
  // Keep what later combined frames still need.
  pressure_.drop_before(next_);
  predicted_.drop_before(next_);
  if (with_mics) mics_fifo_.drop_before(next_ + delay_frames_);
}

void CycleProcessor::grid_pressure(double crank_deg, double pressure_pa) {
  if (grid_has_last_ && crank_deg > grid_last_deg_) {
    // Grid points in (last, this]: linear between the two frames.
    const double from = (grid_last_deg_ + 360.0) / kGridStepDeg, to = (crank_deg + 360.0) / kGridStepDeg;
    const auto first = static_cast<std::int64_t>(std::floor(from)) + 1, last = static_cast<std::int64_t>(std::floor(to));
    for (std::int64_t k = std::max<std::int64_t>(first, 0); k <= std::min<std::int64_t>(last, kGridPoints - 1); ++k) {
      const double x = (static_cast<double>(k) - from) / (to - from);
      grid_[static_cast<std::size_t>(k)] = grid_last_pa_ + x * (pressure_pa - grid_last_pa_);
    }
  }
  grid_last_deg_ = crank_deg;
  grid_last_pa_ = pressure_pa;
  grid_has_last_ = true;
}

void CycleProcessor::flush_chunk() {
  if (chunk_frames_ == 0) return;
  bank_.process(chunk_.data(), chunk_frames_);
  counters_.frames_processed += static_cast<std::int64_t>(chunk_frames_);
  chunk_frames_ = 0;
}

void CycleProcessor::finish_cycle(std::int64_t end_index) {
  const std::size_t nb = bank_.band_count();
  bank_.take_mean_square(mean_square_.data());
  const std::int64_t start = cycle_start_;
  cycle_start_ = end_index;
  const double cpu_s = cpu_spent_s_;  // calls completed since the previous cycle; the current call counts for the next
  cpu_spent_s_ = 0;
  // The combustion metrics of the cycle just ended, then a fresh grid (only complete grids give numbers).
  model::CombustionMetrics combustion;  // NaN throughout unless the grid is complete
  const bool grid_complete =
      start != INT64_MIN && std::none_of(grid_.begin(), grid_.end(), [](double v) { return std::isnan(v); });
  if (grid_complete)
    combustion = model::combustion_metrics(grid_, -360.0, kGridStepDeg, config_.engine,
                                           720.0 / 360.0 * 60.0 * kFs / static_cast<double>(end_index - start), config_.metrics);
  std::fill(grid_.begin(), grid_.end(), std::numeric_limits<double>::quiet_NaN());
  if (start == INT64_MIN) return;  // frames before the first boundary only warm the filters up

  bool gap = false;
  std::int64_t last_gap_end = INT64_MIN;
  for (const Gap& g : gaps_) {
    if (g.from >= end_index) continue;
    if (g.to > start) gap = true;
    last_gap_end = std::max(last_gap_end, g.to);
  }
  std::erase_if(gaps_, [&](const Gap& g) { return g.to <= end_index; });
  settle_from_ = std::max(settle_from_, last_gap_end);  // filters restart settling after lost samples

  const double duration = static_cast<double>(end_index - start) / kFs;
  if (gap) {
    // A stall hides the boundaries inside it: count the cycles it spans at the last good cycle's length.
    const double spanned = last_duration_s_ > 0 ? std::round(duration / last_duration_s_) : 1.0;
    const auto n = static_cast<std::int64_t>(std::max(1.0, spanned));
    counters_.cycles_completed += n;
    counters_.cycles_dropped += n;
    return;
  }
  const std::int64_t cycle = counters_.cycles_completed++;
  const bool odd = last_duration_s_ > 0 && std::abs(duration - last_duration_s_) > 0.1 * last_duration_s_;
  last_duration_s_ = duration;

  CycleReport r;
  r.utime = utime_of(info_.epoch_utime, static_cast<double>(start));
  r.window_end_utime = utime_of(info_.epoch_utime, static_cast<double>(end_index + delay_frames_));
  r.cycle = cycle;
  r.duration_s = duration;
  r.op = op_;
  r.op.speed_rpm = 720.0 / 360.0 * 60.0 / duration;  // two revolutions per cycle
  r.radius_m = info_.radius_m;
  r.nbands = static_cast<std::uint16_t>(nb);
  r.nmics = static_cast<std::uint16_t>(mics_);
  if (!have_op_) r.flags |= kCycleNoOperatingPoint;
  if (odd) r.flags |= kCycleLengthOdd;
  if (mics_ == 0) r.flags |= kCycleNoMics;

  const double settled_s = static_cast<double>(start - settle_from_) / kFs;
  const auto& bands = bank_.bands();
  std::vector<double>& ms = mean_square_;
  double meas_sum = 0, pred_sum = 0;
  double mic_sum[kMaxMics] = {};
  const double firing_hz = 1.0 / duration;  // one firing per 720 deg
  for (std::size_t b = 0; b < nb; ++b) {
    const double aw = dsp::a_weighting_db(bands[b].exact_mid_hz);
    const bool below_firing = bands[b].upper_edge_hz < firing_hz;
    const double cpl = dsp::level_db(ms[0 * nb + b]);
    const double pred_a = dsp::level_db(ms[1 * nb + b]) + aw;
    double mic_ms_mean = 0;
    for (std::size_t m = 0; m < mics_; ++m) {
      const double msm = ms[(2 + m) * nb + b];
      mic_ms_mean += msm;
      if (!below_firing) mic_sum[m] += msm * std::pow(10.0, aw / 10.0);
    }
    // Energy average over microphones; without microphones nothing was measured: NaN, never a number.
    const double meas_a = mics_ > 0 ? dsp::level_db(mic_ms_mean / static_cast<double>(mics_)) + aw
                                    : std::numeric_limits<double>::quiet_NaN();
    if (!below_firing) {
      meas_sum += dsp::mean_square_from_level(meas_a);
      pred_sum += dsp::mean_square_from_level(pred_a);
    }
    r.band_hz[b] = static_cast<float>(bands[b].nominal_hz);
    r.cpl_db[b] = static_cast<float>(cpl);
    r.spl_a_measured_db[b] = static_cast<float>(meas_a);
    r.spl_a_predicted_db[b] = static_cast<float>(pred_a);
    r.att_measured_db[b] = static_cast<float>(dsp::attenuation_db(cpl, meas_a));
    r.att_predicted_db[b] = static_cast<float>(dsp::attenuation_db(cpl, pred_a));
    std::int8_t f = 0;
    if (bands[b].nyquist_cut) f |= kBandNyquistCut;
    if (bands[b].response_time_s > duration) f |= kBandSlow;
    if (below_firing) f |= kBandBelowFiring;
    if (bands[b].response_time_s > settled_s) {
      f |= kBandSettling;
      r.flags |= kCycleSettling;
    }
    r.band_flags[b] = f;
  }
  r.lpa_measured_db = dsp::level_db(meas_sum);
  r.lpa_predicted_db = dsp::level_db(pred_sum);
  r.lwa_measured_db = dsp::sound_power_level_db(r.lpa_measured_db, info_.radius_m);
  r.lwa_predicted_db = dsp::sound_power_level_db(r.lpa_predicted_db, info_.radius_m);
  for (std::size_t m = 0; m < mics_; ++m) r.mic_lpa_db[m] = static_cast<float>(dsp::level_db(mic_sum[m]));

  r.processing_ms = static_cast<float>(1e3 * cpu_s);
  r.combustion = combustion;
  sink_(r);
}

}  // namespace noisemon::daemon
