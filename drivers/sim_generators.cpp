#include "drivers/sim_generators.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace noisemon::drivers::sim {

namespace {

constexpr std::size_t kCardBatch = 256;           // card frames per resampler call
constexpr std::size_t kOutFrames = 4096;          // resampler output room (frames)

std::int64_t to_index(double t_s, double rate_hz) { return std::llround(t_s * rate_hz); }

}  // namespace

model::EngineCycleParams engine_params(const SimConfig& config) {
  model::EngineCycleParams p;
  p.ringing = config.gas_ringing;
  return p;
}

model::OperatingCondition operating_condition(const SimConfig& config) {
  // Fuelling saturates at full load: loads above full_load_nm get the full-load fuel.
  return {.speed_rpm = config.speed_rpm,
          .load_nm = std::min(config.load_nm, config.full_load_nm),
          .soi_deg_btdc = config.soi_deg_btdc,
          .motored = config.motored};
}

model::CrankKinematics crank_kinematics(const SimConfig& config) {
  return model::CrankKinematics(config.speed_rpm, config.speed_fluctuation, -360.0);
}

// ---------------------------------------------------------------------------------------------- cycles

EngineCycleCache::EngineCycleCache(const SimConfig& config)
    : op_(operating_condition(config)), seed_(config.seed), sigma_(config.cycle_variation), cycle_(engine_params(config)) {}

double EngineCycleCache::pressure_pa(double theta_deg) {
  const std::int64_t k = model::CrankKinematics::cycle_index(theta_deg);
  if (!valid_ || k != index_) {
    cycle_.compute(op_, model::draw_cycle_variation(seed_, k, sigma_));
    index_ = k;
    valid_ = true;
  }
  return cycle_.pressure_pa(theta_deg - 720.0 * static_cast<double>(k));
}

// ---------------------------------------------------------------------------------------------- pressure

PressureGenerator::PressureGenerator(const SimConfig& config, double t_first_s)
    : kin_(crank_kinematics(config)),
      cache_(config),
      chain_(config.pressure_chain, config.effects, config.seed),
      resampler_(kPipelineRateHz, 1),
      writer_(kPressureStreamChannels),
      resolution_deg_(config.encoder_resolution_deg),
      next_edge_(static_cast<std::int64_t>(std::ceil(kin_.theta_deg(t_first_s - kPreRollS) / config.encoder_resolution_deg))),
      first_index_(to_index(t_first_s, kPipelineRateHz)) {
  // Keep each resampler call's output well inside its room, even for slow engines and coarse encoders.
  const double frames_per_edge =
      kPipelineRateHz * resolution_deg_ / (6.0 * config.speed_rpm * (1.0 - config.speed_fluctuation));
  batch_ = static_cast<std::size_t>(std::clamp(1024.0 / frames_per_edge, 1.0, 256.0));
  t_.resize(batch_);
  x_.resize(batch_);
  out_.resize(kOutFrames);
}

void PressureGenerator::advance(double t_end_s, BlockRing& ring) {
  for (;;) {
    std::size_t n = 0;
    for (; n < batch_; ++n) {
      const double theta = static_cast<double>(next_edge_) * resolution_deg_;
      const double t = kin_.time_s(theta);
      if (t >= t_end_s) break;
      t_[n] = t;
      x_[n] = cache_.pressure_pa(theta);
      ++next_edge_;
    }
    if (n == 0) break;
    chain_.measure(next_edge_ - static_cast<std::int64_t>(n), x_.data(), n);
    std::int64_t k = resampler_.next_output_index();
    const std::size_t frames = resampler_.process(t_.data(), x_.data(), n, out_.data(), out_.size());
    for (std::size_t f = 0; f < frames; ++f, ++k) {
      if (k < first_index_) continue;
      double* slot = writer_.frame(k, ring);
      slot[kPressureChannel] = out_[f];
      slot[kCrankChannel] = model::CrankKinematics::cycle_angle(kin_.theta_deg(static_cast<double>(k) / kPipelineRateHz));
    }
    if (n < batch_) break;
  }
  writer_.flush(ring);
}

// ---------------------------------------------------------------------------------------------- microphones

model::VirtualEngineConfig virtual_engine_config(const SimConfig& config, double input_rate_hz) {
  model::VirtualEngineConfig v;
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
  model::EngineCycle cycle(engine_params(config));
  cycle.compute(operating_condition(config));
  double mean = 0.0;
  const int n = 1440;
  for (int i = 0; i < n; ++i) mean += cycle.pressure_pa(-360.0 + 720.0 * i / n);
  v.mean_pressure_pa = mean / n;
  v.speed_rpm = config.speed_rpm;
  v.soi_deg_btdc = config.soi_deg_btdc;
  v.motored = config.motored;
  v.effects = config.effects;
  v.seed = config.seed;
  v.setup_seed = config.seed;
  return v;
}

EngineFeed::EngineFeed(const SimConfig& config, double t0_s, double rate_hz)
    : kin_(crank_kinematics(config)), cache_(config), t0_(t0_s), rate_(rate_hz) {}

void EngineFeed::fill(std::int64_t first, double* pressure_pa, double* crank_deg, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const double t = t0_ + static_cast<double>(first + static_cast<std::int64_t>(i)) / rate_;
    crank_deg[i] = kin_.theta_deg(t);
    pressure_pa[i] = cache_.pressure_pa(crank_deg[i]);
  }
}

MicGenerator::MicGenerator(const SimConfig& config, double t_first_s)
    : card_rate_(config.mic_rate_hz),
      t0_(t_first_s - kPreRollS),
      index0_(to_index(t_first_s - kPreRollS, kPipelineRateHz)),
      first_index_(to_index(t_first_s, kPipelineRateHz)),
      mics_(config.mic_count),
      feed_(config, t_first_s - kPreRollS, 2.0 * config.mic_rate_hz),
      engine_(virtual_engine_config(config, 2.0 * config.mic_rate_hz)),
      to_pipeline_(config.mic_rate_hz, kPipelineRateHz, config.mic_count),
      writer_(config.mic_count) {
  if (std::abs(t0_ / kGridAlignS - std::round(t0_ / kGridAlignS)) > 1e-6)
    throw std::invalid_argument("MicGenerator: start time must be a multiple of 1/1600 s");
  mic_card_.resize(kCardBatch * mics_);
  out_.resize(kOutFrames * mics_);
}

void MicGenerator::advance(double t_end_s, BlockRing& ring) {
  const std::int64_t m_end = static_cast<std::int64_t>(std::ceil((t_end_s - t0_) * card_rate_));
  while (card_next_ < m_end) {
    const auto n = static_cast<std::size_t>(std::min<std::int64_t>(kCardBatch, m_end - card_next_));
    engine_.render(feed_, mic_card_.data(), n);
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

}  // namespace noisemon::drivers::sim
