#include "drivers/sim_generators.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace noisemon::drivers::sim {

namespace {

constexpr double kAcCouplingHz = 2.0;             // microphone / card high-pass corner
constexpr std::size_t kFineBatch = 1024;          // fine-grid samples per block-model call
constexpr std::size_t kCardBatch = 256;           // card frames per resampler call
constexpr std::size_t kOutFrames = 4096;          // resampler output room (frames)

std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

std::int64_t to_index(double t_s, double rate_hz) { return std::llround(t_s * rate_hz); }

}  // namespace

model::EngineCycleParams engine_params(const SimConfig&) { return model::EngineCycleParams{}; }

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

// ---------------------------------------------------------------------------------------------- blocks

double* BlockWriter::frame(std::int64_t index, BlockRing& ring) {
  if (block_.frames == SampleBlock::kMaxFrames ||
      (block_.frames > 0 && index != block_.first_index + static_cast<std::int64_t>(block_.frames)))
    flush(ring);
  if (block_.frames == 0) block_.first_index = index;
  return &block_.data[static_cast<std::size_t>(block_.frames++) * block_.channels];
}

void BlockWriter::flush(BlockRing& ring) {
  if (block_.frames == 0) return;
  if (ring.push(block_)) ++written_;
  block_.frames = 0;
}

// ---------------------------------------------------------------------------------------------- pressure

PressureGenerator::PressureGenerator(const SimConfig& config, double t_first_s)
    : kin_(crank_kinematics(config)),
      cache_(config),
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

// ---------------------------------------------------------------------------------------------- noise

PinkNoise::PinkNoise(double rms, std::uint64_t seed) {
  for (auto& s : s_) s = splitmix64(seed);
  // Kellet's refined pink filter: six one-pole sections plus a direct and a one-sample-delayed white term.
  // Its white-noise variance in closed form: sum over the impulse response h[n] = sum_k g_k p_k^n (+ d0 at
  // n = 0, + d1 at n = 1) squared.
  constexpr std::array<double, 6> p{0.99886, 0.99332, 0.96900, 0.86650, 0.55000, -0.7616};
  constexpr std::array<double, 6> g{0.0555179, 0.0750759, 0.1538520, 0.3104856, 0.5329522, -0.0168980};
  constexpr double d0 = 0.5362, d1 = 0.115926;
  double var = d0 * d0 + d1 * d1;
  double a0 = 0.0, a1 = 0.0;
  for (std::size_t j = 0; j < 6; ++j) {
    a0 += g[j];
    a1 += g[j] * p[j];
    for (std::size_t k = 0; k < 6; ++k) var += g[j] * g[k] / (1.0 - p[j] * p[k]);
  }
  var += 2.0 * d0 * a0 + 2.0 * d1 * a1;
  scale_ = rms / std::sqrt(var);
}

double PinkNoise::gaussian() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  auto next_u64 = [this] {  // xoshiro256**
    const std::uint64_t result = std::rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = std::rotl(s_[3], 45);
    return result;
  };
  const double u1 = (static_cast<double>(next_u64() >> 11) + 1.0) * 0x1.0p-53;
  const double u2 = static_cast<double>(next_u64() >> 11) * 0x1.0p-53;
  const double r = std::sqrt(-2.0 * std::log(u1));
  spare_ = r * std::sin(2.0 * std::numbers::pi * u2);
  has_spare_ = true;
  return r * std::cos(2.0 * std::numbers::pi * u2);
}

double PinkNoise::next() {
  const double w = gaussian();
  b_[0] = 0.99886 * b_[0] + w * 0.0555179;
  b_[1] = 0.99332 * b_[1] + w * 0.0750759;
  b_[2] = 0.96900 * b_[2] + w * 0.1538520;
  b_[3] = 0.86650 * b_[3] + w * 0.3104856;
  b_[4] = 0.55000 * b_[4] + w * 0.5329522;
  b_[5] = -0.7616 * b_[5] - w * 0.0168980;
  const double pink = b_[0] + b_[1] + b_[2] + b_[3] + b_[4] + b_[5] + b_[6] + w * 0.5362;
  b_[6] = w * 0.115926;
  return scale_ * pink;
}

// ---------------------------------------------------------------------------------------------- microphones

namespace {

// Cycle-mean pressure of the nominal cycle mapped through the block's static response (k1 z + k3 z^3 = p,
// y = c0 z): the DC the AC coupling removes, used to start its filter settled.
double static_output_pa(const SimConfig& config) {
  model::EngineCycle cycle(engine_params(config));
  cycle.compute(operating_condition(config));
  double mean = 0.0;
  const int n = 1440;
  for (int i = 0; i < n; ++i) mean += cycle.pressure_pa(-360.0 + 720.0 * i / n);
  mean /= n;
  const auto& b = config.true_block;
  double z = mean / b.k1;
  for (int it = 0; it < 50; ++it) z -= (b.k1 * z + b.k3 * z * z * z - mean) / (b.k1 + 3.0 * b.k3 * z * z);
  return b.c0 * z;
}

std::size_t next_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

}  // namespace

MicGenerator::MicGenerator(const SimConfig& config, double t_first_s)
    : fine_rate_(2.0 * config.mic_rate_hz),
      card_rate_(config.mic_rate_hz),
      t0_(t_first_s - kPreRollS),
      index0_(to_index(t_first_s - kPreRollS, kPipelineRateHz)),
      first_index_(to_index(t_first_s, kPipelineRateHz)),
      mics_(config.mic_count),
      kin_(crank_kinematics(config)),
      cache_(config),
      block_(config.true_block, 2.0 * config.mic_rate_hz),
      latency_left_(block_.latency_samples()),
      hp_a_(1.0 / (1.0 + 2.0 * std::numbers::pi * kAcCouplingHz / (2.0 * config.mic_rate_hz))),
      hp_x_(static_output_pa(config)),
      hp_y_(0.0),
      to_card_(2.0 * config.mic_rate_hz, config.mic_rate_hz, 1),
      to_pipeline_(config.mic_rate_hz, kPipelineRateHz, config.mic_count),
      writer_(config.mic_count) {
  if (std::abs(t0_ / kGridAlignS - std::round(t0_ / kGridAlignS)) > 1e-6)
    throw std::invalid_argument("MicGenerator: start time must be a multiple of 1/1600 s");
  // Gains: seeded normal spread in dB, normalised to an energy mean of exactly 1 (0 dB).
  std::uint64_t state = config.seed ^ 0x6D69635F6761696EULL;
  gains_.resize(mics_);
  double energy = 0.0;
  for (auto& g : gains_) {
    const double u1 = (static_cast<double>(splitmix64(state) >> 11) + 1.0) * 0x1.0p-53;
    const double u2 = static_cast<double>(splitmix64(state) >> 11) * 0x1.0p-53;
    const double n = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
    g = std::pow(10.0, config.mic_gain_spread_db * n / 20.0);
    energy += g * g;
  }
  for (auto& g : gains_) g /= std::sqrt(energy / mics_);
  // Delays: each microphone's distance from the engine (the hemisphere centre) / c, in whole card samples.
  const auto positions = config.mic_positions_m.empty() ? thesis_mic_positions() : config.mic_positions_m;
  delay_card_.resize(mics_);
  for (std::uint32_t i = 0; i < mics_; ++i) {
    const auto& q = positions.at(i);
    const double r = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
    delay_card_[i] = std::llround(r / config.speed_of_sound_m_s * card_rate_);
  }
  min_delay_card_ = *std::min_element(delay_card_.begin(), delay_card_.end());
  const auto max_delay = static_cast<std::size_t>(*std::max_element(delay_card_.begin(), delay_card_.end()));
  card_line_.assign(next_pow2(max_delay + 8 * kCardBatch + 2 * kFineBatch), 0.0);
  card_mask_ = card_line_.size() - 1;
  // Background: pink, each channel its own generator, rms from the unweighted level re 20 uPa.
  const double rms = std::isfinite(config.background_noise_db) ? 20e-6 * std::pow(10.0, config.background_noise_db / 20.0) : 0.0;
  for (std::uint32_t i = 0; i < mics_; ++i) noise_.emplace_back(rms, config.seed * 0x9E3779B97F4A7C15ULL + i + 1);
  u_.resize(kFineBatch);
  y_.resize(kFineBatch);
  card_tmp_.resize(to_card_.max_output_frames(kFineBatch) + kOutFrames);
  mic_card_.resize(kCardBatch * mics_);
  out_.resize(kOutFrames * mics_);
}

std::vector<double> MicGenerator::delays_s() const {
  std::vector<double> d(delay_card_.size());
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = static_cast<double>(delay_card_[i]) / card_rate_;
  return d;
}

// The common (undelayed, unit-gain) card-rate signal, until at least m_end samples exist.
void MicGenerator::make_card(std::int64_t m_end) {
  while (card_avail_ < m_end) {
    const std::size_t n = kFineBatch;
    for (std::size_t i = 0; i < n; ++i) {
      const double t = t0_ + static_cast<double>(fine_next_ + static_cast<std::int64_t>(i)) / fine_rate_;
      u_[i] = cache_.pressure_pa(kin_.theta_deg(t));
    }
    fine_next_ += static_cast<std::int64_t>(n);
    block_.process(u_.data(), y_.data(), n);
    // Output j is the response at input j - latency: dropping the first `latency` outputs puts it on the grid.
    const std::size_t skip = std::min(latency_left_, n);
    latency_left_ -= skip;
    for (std::size_t i = skip; i < n; ++i) {
      hp_y_ = hp_a_ * (hp_y_ + y_[i] - hp_x_);
      hp_x_ = y_[i];
      y_[i] = hp_y_;
    }
    const std::size_t made = to_card_.process(y_.data() + skip, n - skip, card_tmp_.data(), card_tmp_.size());
    for (std::size_t i = 0; i < made; ++i) card_line_[static_cast<std::size_t>(card_avail_++) & card_mask_] = card_tmp_[i];
  }
}

void MicGenerator::advance(double t_end_s, BlockRing& ring) {
  const std::int64_t m_end = static_cast<std::int64_t>(std::ceil((t_end_s - t0_) * card_rate_));
  while (card_next_ < m_end) {
    const auto n = static_cast<std::size_t>(std::min<std::int64_t>(kCardBatch, m_end - card_next_));
    make_card(card_next_ + static_cast<std::int64_t>(n) - min_delay_card_);
    for (std::size_t f = 0; f < n; ++f) {
      const std::int64_t m = card_next_ + static_cast<std::int64_t>(f);
      double* frame = &mic_card_[f * mics_];
      for (std::uint32_t i = 0; i < mics_; ++i) {
        const std::int64_t src = m - delay_card_[i];
        frame[i] = src < 0 ? 0.0 : gains_[i] * card_line_[static_cast<std::size_t>(src) & card_mask_];
      }
    }
    card_next_ += static_cast<std::int64_t>(n);
    std::int64_t k = index0_ + to_pipeline_.next_output_index();
    const std::size_t frames = to_pipeline_.process(mic_card_.data(), n, out_.data(), kOutFrames);
    for (std::size_t f = 0; f < frames; ++f, ++k) {
      const double* in = &out_[f * mics_];
      if (k < first_index_) {
        for (auto& noise : noise_) noise.next();
        continue;
      }
      double* slot = writer_.frame(k, ring);
      for (std::uint32_t i = 0; i < mics_; ++i) slot[i] = in[i] + noise_[i].next();
    }
  }
  writer_.flush(ring);
}

}  // namespace noisemon::drivers::sim
