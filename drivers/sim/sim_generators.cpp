#include "drivers/sim/sim_generators.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "drivers/mic_positions.hpp"
#include "model/engine/random.hpp"

namespace noisemon::drivers::sim {

namespace {

constexpr std::size_t kCardBatch = 256;   // card frames per resampler call
constexpr std::size_t kOutFrames = 4096;  // resampler output room (frames)

std::int64_t to_index(double t_s, double rate_hz) { return std::llround(t_s * rate_hz); }

}  // namespace

void read_out_pressure(const SimConfig::PressureReadout& readout, double* pressure_pa, std::size_t n) {
  if (!(readout.nominal_mv_per_bar > 0.0)) return;
  const double card = readout.card_mv_per_bar > 0.0 ? readout.card_mv_per_bar : readout.nominal_mv_per_bar;
  const double scale = readout.nominal_mv_per_bar / card, offset = 1e5 * readout.card_offset_bar;
  for (std::size_t i = 0; i < n; ++i) pressure_pa[i] = scale * pressure_pa[i] - offset;
}

model::engine::EngineCycleParams engine_params(const SimConfig& config) {
  model::engine::EngineCycleParams p;
  p.ringing = config.gas_ringing;
  return p;
}

model::engine::OperatingCondition operating_condition(const SimConfig& config) {
  // Fuelling saturates at full load: loads above full_load_nm get the full-load fuel.
  return {.speed_rpm = config.speed_rpm,
          .load_nm = std::min(config.load_nm, config.full_load_nm),
          .soi_deg_btdc = config.soi_deg_btdc,
          .motored = config.motored};
}

OperatingProfile operating_profile(const SimConfig& config, double t_first_s) {
  const model::engine::OperatingCondition initial{.speed_rpm = config.speed_rpm,
                                                  .load_nm = config.load_nm,
                                                  .soi_deg_btdc = config.soi_deg_btdc,
                                                  .motored = config.motored};
  return OperatingProfile(initial, config.operating_schedule, config.speed_fluctuation, t_first_s);
}

model::CrankKinematics crank_kinematics(const SimConfig& config) { return operating_profile(config, 0.0).kinematics(); }

// ---------------------------------------------------------------------------------------------- cycles

EngineCycleCache::EngineCycleCache(const SimConfig& config)
    : EngineCycleCache(config, std::make_shared<const OperatingProfile>(operating_profile(config, 0.0))) {}

EngineCycleCache::EngineCycleCache(const SimConfig& config, std::shared_ptr<const OperatingProfile> profile)
    : profile_(std::move(profile)),
      full_load_nm_(config.full_load_nm),
      seed_(config.seed),
      sigma_(config.cycle_variation),
      cycle_(engine_params(config)) {}

double EngineCycleCache::pressure_pa(double theta_deg) {
  const std::int64_t k = model::CrankKinematics::cycle_index(theta_deg);
  if (!valid_ || k != index_) {
    model::engine::OperatingCondition op = profile_->condition(k);
    op.load_nm = std::min(op.load_nm, full_load_nm_);  // the fuelling saturates at full load
    cycle_.compute(op, model::engine::draw_cycle_variation(seed_, k, sigma_));
    index_ = k;
    valid_ = true;
  }
  return cycle_.pressure_pa(theta_deg - 720.0 * static_cast<double>(k));
}

// ---------------------------------------------------------------------------------------------- pressure

namespace {

// The decoder of the sim's encoder-clocked scans: one subdevice scanning pressure, position and timestamp.
// The highest speed is the operating point's with room for the speed ripple and a cycle's variation.
comedi::EdgeStreamConfig encoder_decoder_config(std::int64_t counts_per_rev, double index_angle_deg, double speed_rpm) {
  comedi::EdgeStreamConfig c;
  c.max_rpm = 1.25 * speed_rpm;
  c.stream_channels = {3};
  c.pressure = {0, 0};
  c.position = {0, 1};
  c.timestamp = {0, 2};
  c.counts_per_rev = static_cast<std::uint32_t>(counts_per_rev);
  c.index_angle_deg = index_angle_deg;
  c.timebase_hz = PressureGenerator::kTimebaseHz;
  c.timestamp_bits = 32;
  c.timestamp_mode = comedi::TimestampMode::kAbsolute;
  c.phase = comedi::PhaseSource::kPressure;
  c.max_scan_skew = 1;  // one subdevice: nothing to pair
  return c;
}

std::int64_t floor_mod(std::int64_t a, std::int64_t m) { return ((a % m) + m) % m; }

// Edges a fault of per_rev a revolution picks: evenly spread, away from the index.
bool picked(std::int64_t edge_in_rev, std::int64_t counts_per_rev, double per_rev) {
  const auto spacing = std::max<std::int64_t>(1, std::llround(static_cast<double>(counts_per_rev) / per_rev));
  return floor_mod(edge_in_rev, spacing) == spacing / 2;
}

}  // namespace

PressureGenerator::PressureGenerator(const SimConfig& config, double t_first_s)
    : PressureGenerator(config, t_first_s,
                        std::make_shared<const OperatingProfile>(operating_profile(config, t_first_s))) {}

PressureGenerator::PressureGenerator(const SimConfig& config, double t_first_s,
                                     std::shared_ptr<const OperatingProfile> profile)
    : profile_(std::move(profile)),
      kin_(profile_->kinematics()),
      cache_(config, profile_),
      chain_(config.pressure_chain, config.effects, config.seed),
      readout_(config.pressure_readout),
      faults_(config.faults),
      seed_(config.seed),
      resolution_deg_(config.encoder_resolution_deg),
      min_rpm_(profile_->min_speed_rpm()),
      counts_per_rev_(std::llround(360.0 / config.encoder_resolution_deg)),
      index_edge_(std::llround(kIndexAngleDeg / config.encoder_resolution_deg)),
      next_edge_(
          static_cast<std::int64_t>(std::ceil(kin_.theta_deg(t_first_s - kPreRollS) / config.encoder_resolution_deg))),
      first_index_(to_index(t_first_s, kPipelineRateHz)),
      t_first_(t_first_s),
      origin_s_(1e-6 * static_cast<double>(std::llround((t_first_s - kPreRollS) * 1e6))),
      decoder_(std::make_unique<comedi::EdgeStreamAssembler>(
          encoder_decoder_config(counts_per_rev_, static_cast<double>(index_edge_) * config.encoder_resolution_deg,
                                 profile_->max_speed_rpm()),
          0)),
      staging_(16),
      angle_staging_(64) {
  decoder_->restart(std::llround(origin_s_ * 1e6));
  for (const auto& e : config.scheduled_effects)
    if (e.setting.name == "transducer_noise") schedule_.push_back(e);
  // The counter as it stands at the first edge: counted from the last index (the card was started earlier).
  counter_ = static_cast<std::uint32_t>(floor_mod(next_edge_ - 1 - index_edge_, counts_per_rev_));
  batch_ = 256;
  t_.resize(batch_);
  x_.resize(batch_);
  edge_.resize(batch_);
}

PressureGenerator::~PressureGenerator() = default;

const comedi::EdgeStreamCounters& PressureGenerator::encoder_counters() const { return decoder_->counters(); }

void PressureGenerator::advance(double t_end_s, BlockRing& ring) {
  for (;;) {
    std::size_t n = 0;
    fill_batch(t_end_s, n);
    if (n == 0) break;
    add_scheduled_transducer_noise(n);
    chain_.measure(edge_[0], x_.data(), n);
    read_out_pressure(readout_, x_.data(), n);
    apply_channel_faults(n);
    for (std::size_t i = 0; i < n; ++i) count_edge(edge_[i], t_[i], x_[i], ring);
    if (n < batch_) break;
  }
  decoder_->deliver(staging_, false);
  forward(ring);
  forward_angles();
}

// A scheduled transducer_noise: its weight times its own white noise (counter-based on the edge, a stream of its own
// so it is independent of the chain's floor), added to the true pressure before the chain, as the effect acts.
void PressureGenerator::add_scheduled_transducer_noise(std::size_t n) {
  for (std::size_t k = 0; k < schedule_.size(); ++k) {
    model::engine::Effects alone;
    alone.add(schedule_[k].setting);
    const double sigma = model::engine::transducer_noise_rms_pa(alone);
    for (std::size_t i = 0; i < n; ++i) {
      const double w = effect_weight(schedule_[k], t_[i] - t_first_);
      if (w > 0.0)
        x_[i] += w * sigma *
                 model::engine::rnd::normal_at(model::engine::rnd::key(seed_, 0x5c4ed, k), 0,
                                               static_cast<std::uint64_t>(edge_[i]));
    }
  }
}

void PressureGenerator::set_angle_ring(BlockRing* ring) {
  angle_out_ = ring;
  decoder_->set_angle_ring(ring ? &angle_staging_ : nullptr);
}

// The decoder's crank-angle blocks to their ring, those wholly in the pre-roll left out: a block spans at most
// kMaxAngleBlockDeg, so one that begins that much before first_index_ may still reach it (the first cycle needs its
// edges whole).
void PressureGenerator::forward_angles() {
  const double lead_s = 1.5 * kMaxAngleBlockDeg / (6.0 * min_rpm_);  // 1.5: the speed's fluctuation, and more
  const std::int64_t from = first_index_ - static_cast<std::int64_t>(std::ceil(lead_s * kPipelineRateHz)) - 1;
  for (const SampleBlock* b = angle_staging_.front(); b; angle_staging_.consume(1), b = angle_staging_.front())
    if (angle_out_ && b->first_index >= from) (void)angle_out_->push(*b);  // full: counted there
}

// The true pressure at the next edges before t_end_s (an overload fault scales it before the converter).
void PressureGenerator::fill_batch(double t_end_s, std::size_t& n) {
  for (n = 0; n < batch_; ++n) {
    const double theta = static_cast<double>(next_edge_) * resolution_deg_;
    const double t = kin_.time_s(theta);
    if (t >= t_end_s) break;
    t_[n] = t;
    x_[n] = cache_.pressure_pa(theta);
    if (const SimFault* f = active_fault(faults_, SimFaultKind::kOverload, kPressureTarget, t - t_first_))
      x_[n] *= f->gain;
    edge_[n] = next_edge_++;
  }
}

// Faults of the converter's samples: stuck (repeats its last sample) or NaN.
void PressureGenerator::apply_channel_faults(std::size_t n) {
  if (faults_.empty()) return;
  for (std::size_t i = 0; i < n; ++i) {
    const double since = t_[i] - t_first_;
    if (active_fault(faults_, SimFaultKind::kFlat, kPressureTarget, since)) x_[i] = held_pressure_;
    held_pressure_ = x_[i];
    if (active_fault(faults_, SimFaultKind::kNan, kPressureTarget, since))
      x_[i] = std::numeric_limits<double>::quiet_NaN();
  }
}

// What the card's counter does at one true encoder edge, and the scans it clocks.
void PressureGenerator::count_edge(std::int64_t edge, double t, double pressure, BlockRing& ring) {
  const double since = t - t_first_;
  const std::int64_t in_rev = floor_mod(edge - index_edge_, counts_per_rev_);
  // (active_fault over an empty list is a null check: the fault-free run pays nothing.)
  const auto fault = [&](SimFaultKind kind) { return active_fault(faults_, kind, kPressureTarget, since); };
  if (const SimFault* missing = fault(SimFaultKind::kMissingEdges);
      missing && picked(in_rev, counts_per_rev_, missing->per_rev))
    return;  // never reaches the counter
  if (in_rev == 0 && !fault(SimFaultKind::kLostIndex))
    counter_ = 0;  // the index resets the counter
  else
    counter_ += fault(SimFaultKind::kReverse) ? ~0u : 1u;  // counting down wraps like the card's register
  scan(t, pressure, ring);
  const SimFault* extra = fault(SimFaultKind::kExtraEdges);
  if (extra && picked(in_rev, counts_per_rev_, extra->per_rev)) {
    const double t_next = kin_.time_s(static_cast<double>(edge + 1) * resolution_deg_);
    ++counter_;
    scan(0.5 * (t + t_next), pressure, ring);  // a glitch between two edges
  }
}

void PressureGenerator::scan(double t, double pressure, BlockRing& ring) {
  const auto ticks = static_cast<std::uint64_t>(std::llround((t - origin_s_) * kTimebaseHz)) & 0xffffffffULL;
  const double values[3] = {pressure, static_cast<double>(counter_), static_cast<double>(ticks)};
  decoder_->add_scan(0, values, staging_);
  forward(ring);
  forward_angles();  // as often as the frames: a held revolution released at once is more than the staging holds
}

// The decoder's blocks to the ring, from first_index_ on (the pre-roll settles the decoder; it is not published).
void PressureGenerator::forward(BlockRing& ring) {
  for (const SampleBlock* b = staging_.front(); b; staging_.consume(1), b = staging_.front()) {
    const std::int64_t end = b->first_index + static_cast<std::int64_t>(b->frames);
    if (end <= first_index_) continue;
    const SampleBlock* out = b;
    if (b->first_index < first_index_) {
      const auto skip = static_cast<std::uint32_t>(first_index_ - b->first_index);
      trimmed_.first_index = first_index_;
      trimmed_.channels = b->channels;
      trimmed_.frames = b->frames - skip;
      std::copy_n(b->data + skip * b->channels, trimmed_.frames * b->channels, trimmed_.data);
      out = &trimmed_;
    }
    if (ring.push(*out)) ++forwarded_;
  }
}

// ---------------------------------------------------------------------------------------------- microphones

model::engine::VirtualEngineConfig virtual_engine_config(const SimConfig& config, double input_rate_hz) {
  model::engine::VirtualEngineConfig v;
  v.input_rate_hz = input_rate_hz;
  v.output_rate_hz = config.mic_rate_hz;
  v.true_block = config.true_block;
  v.mic_positions_m = config.mic_positions_m;
  if (v.mic_positions_m.empty()) {
    v.mic_positions_m = thesis_mic_positions();
    v.mic_positions_m.resize(config.mic_count);
  }
  v.speed_of_sound_m_s = config.speed_of_sound_m_s;
  v.mic_gain_spread_db = config.mic_gain_spread_db;
  v.floor_db = config.background_noise_db;
  v.mic_chain = config.mic_chain;
  v.pressure_chain = config.pressure_chain;
  // Cycle-mean pressure of the nominal cycle: the AC coupling starts settled on its static response.
  model::engine::EngineCycle cycle(engine_params(config));
  cycle.compute(operating_condition(config));
  double mean = 0.0;
  const int n = 1440;
  for (int i = 0; i < n; ++i) mean += cycle.pressure_pa(-360.0 + 720.0 * i / n);
  v.mean_pressure_pa = config.stopped ? 1e5 * config.static_pressure_bar : mean / n;
  v.speed_rpm = config.speed_rpm;
  v.soi_deg_btdc = config.soi_deg_btdc;
  v.motored = config.motored;
  v.effects = config.effects;
  v.seed = config.seed;
  v.setup_seed = config.seed;
  return v;
}

EngineFeed::EngineFeed(const SimConfig& config, std::shared_ptr<const OperatingProfile> profile, double t0_s,
                       double rate_hz)
    : kin_(profile->kinematics()),
      cache_(config, std::move(profile)),
      t0_(t0_s),
      rate_(rate_hz),
      stopped_(config.stopped),
      static_pa_(1e5 * config.static_pressure_bar) {}

void EngineFeed::fill(std::int64_t first, double* pressure_pa, double* crank_deg, std::size_t n) {
  if (stopped_) {
    std::fill_n(pressure_pa, n, static_pa_);
    std::fill_n(crank_deg, n, 0.0);
    return;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const double t = t0_ + static_cast<double>(first + static_cast<std::int64_t>(i)) / rate_;
    crank_deg[i] = kin_.theta_deg(t);
    pressure_pa[i] = cache_.pressure_pa(crank_deg[i]);
  }
}

MicGenerator::MicGenerator(const SimConfig& config, double t_first_s)
    : MicGenerator(config, t_first_s, std::make_shared<const OperatingProfile>(operating_profile(config, t_first_s))) {}

MicGenerator::MicGenerator(const SimConfig& config, double t_first_s,
                           const std::shared_ptr<const OperatingProfile>& profile)
    : card_rate_(config.mic_rate_hz),
      t0_(t_first_s - kPreRollS),
      index0_(to_index(t_first_s - kPreRollS, kPipelineRateHz)),
      first_index_(to_index(t_first_s, kPipelineRateHz)),
      mics_(config.mic_count),
      schedule_(config.scheduled_effects),
      to_pipeline_(config.mic_rate_hz, kPipelineRateHz, config.mic_count),
      t_first_(t_first_s),
      adc_range_pa_(config.mic_chain.adc_bits > 0 ? config.mic_chain.adc_range_pa
                                                  : std::numeric_limits<double>::infinity()),
      seed_(config.seed),
      faults_(config.faults),
      held_(config.mic_count, 0.0),
      writer_(config.mic_count) {
  if (std::abs(t0_ / kGridAlignS - std::round(t0_ / kGridAlignS)) > 1e-6)
    throw std::invalid_argument("MicGenerator: start time must be a multiple of 1/1600 s");
  for (std::size_t k = 0; k <= schedule_.size(); ++k) {
    SimConfig step = config;
    step.effects = cumulative_effects(config.effects, schedule_, k);
    feeds_.emplace_back(step, profile, t0_, 2.0 * config.mic_rate_hz);
    engines_.emplace_back(virtual_engine_config(step, 2.0 * config.mic_rate_hz));
  }
  mic_card_.resize(kCardBatch * mics_);
  layer_card_.resize(schedule_.empty() ? 0 : 2 * kCardBatch * mics_);
  out_.resize(kOutFrames * mics_);
}

// n card frames into mic_card_: engine 0, plus each scheduled effect's difference weighted by its schedule.
void MicGenerator::render(std::size_t n) {
  engines_.front().render(feeds_.front(), mic_card_.data(), n);
  if (schedule_.empty()) return;
  double* previous = layer_card_.data();
  double* current = layer_card_.data() + kCardBatch * mics_;
  std::copy(mic_card_.begin(), mic_card_.begin() + static_cast<std::ptrdiff_t>(n * mics_), previous);
  for (std::size_t k = 1; k < engines_.size(); ++k) {
    engines_[k].render(feeds_[k], current, n);
    for (std::size_t j = 0; j < n; ++j) {
      const double since = t0_ + static_cast<double>(card_next_ + static_cast<std::int64_t>(j)) / card_rate_ - t_first_;
      const double w = effect_weight(schedule_[k - 1], since);
      if (w == 0.0) continue;
      for (std::size_t m = 0; m < mics_; ++m)
        mic_card_[j * mics_ + m] += w * (current[j * mics_ + m] - previous[j * mics_ + m]);
    }
    std::swap(previous, current);
  }
}

void MicGenerator::advance(double t_end_s, BlockRing& ring) {
  const std::int64_t m_end = static_cast<std::int64_t>(std::ceil((t_end_s - t0_) * card_rate_));
  while (card_next_ < m_end) {
    const auto n = static_cast<std::size_t>(std::min<std::int64_t>(kCardBatch, m_end - card_next_));
    render(n);
    apply_channel_faults(n);
    card_next_ += static_cast<std::int64_t>(n);
    std::int64_t k = index0_ + to_pipeline_.next_output_index();
    const std::size_t frames = to_pipeline_.process(mic_card_.data(), n, out_.data(), kOutFrames);
    for (std::size_t f = 0; f < frames; ++f, ++k) {
      if (k < first_index_) continue;
      const double* in = &out_[f * mics_];
      double* slot = writer_.frame(k, ring);
      for (std::uint32_t i = 0; i < mics_; ++i) slot[i] = in[i];
    }
  }
  writer_.flush(ring);
}

// Faults of the card's samples, per microphone: stuck, clipped at the rails after too much gain, NaN, or open
// (only the converter's noise: 1e-4 Pa rms, about 14 dB re 20 uPa, far below any microphone's self-noise).
void MicGenerator::apply_channel_faults(std::size_t n) {
  if (faults_.empty()) return;
  constexpr double kOpenInputNoisePa = 1e-4;
  constexpr std::uint64_t kOpenInputStream = 0x6f70656e;  // "open"
  for (std::size_t j = 0; j < n; ++j) {
    const std::int64_t card_frame = card_next_ + static_cast<std::int64_t>(j);
    const double since = t0_ + static_cast<double>(card_frame) / card_rate_ - t_first_;
    for (std::uint32_t m = 0; m < mics_; ++m) {
      double& x = mic_card_[j * mics_ + m];
      const int target = static_cast<int>(m);
      if (const SimFault* f = active_fault(faults_, SimFaultKind::kOverload, target, since))
        x = std::clamp(x * f->gain, -adc_range_pa_, adc_range_pa_);
      if (active_fault(faults_, SimFaultKind::kUnplugged, target, since))
        x = kOpenInputNoisePa *
            model::engine::rnd::normal_at(seed_, kOpenInputStream + m, static_cast<std::uint64_t>(card_frame));
      if (active_fault(faults_, SimFaultKind::kFlat, target, since)) x = held_[m];
      held_[m] = x;
      if (active_fault(faults_, SimFaultKind::kNan, target, since)) x = std::numeric_limits<double>::quiet_NaN();
    }
  }
}

}  // namespace noisemon::drivers::sim
