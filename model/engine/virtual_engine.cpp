#include "model/engine/virtual_engine.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

#include "dsp/levels.hpp"
#include "dsp/resample.hpp"
#include "model/block_model.hpp"
#include "model/engine/adc.hpp"
#include "model/engine/random.hpp"

namespace noisemon::model::engine {

namespace {

constexpr std::size_t kBatch = 1024;  // input samples per feed/block-model call

enum : std::uint64_t {
  kStreamFloor = 0x3001,
  kStreamBackground = 0x3002,
  kStreamSelfNoise = 0x3003,
};

std::size_t next_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

// Pink floor: Kellet's refined filter (six one-pole sections plus a direct and a one-sample-delayed white
// term) on Gaussian white noise, scaled so its unweighted power up to 20 kHz (or fs/2) is the given mean square
// (the filter is pink from about 10 Hz up, flat below).
class PinkNoise {
 public:
  // The same level with another seed.
  PinkNoise(const PinkNoise& shape, std::uint64_t seed) : normal_(seed), scale_(shape.scale_) {}
  PinkNoise(double mean_square_pa2, double fs_hz, std::uint64_t seed) : normal_(seed) {
    // Power of the filter over [0, min(20 kHz, fs/2)] for unit white input (one-sided PSD 2/fs |H|^2).
    const double f_hi = std::min(20000.0, 0.5 * fs_hz);
    const auto n = static_cast<std::size_t>(std::ceil(f_hi));
    const double df = f_hi / static_cast<double>(n);
    double power = 0.0;
    for (std::size_t i = 0; i <= n; ++i) {
      const double w = 2.0 * kPi * df * static_cast<double>(i) / fs_hz;
      const std::complex<double> zi = std::polar(1.0, -w);  // z^-1
      std::complex<double> h = kD0 + kD1 * zi;
      for (std::size_t k = 0; k < 6; ++k) h += kG[k] / (1.0 - kP[k] * zi);
      power += (i == 0 || i == n ? 0.5 : 1.0) * std::norm(h);
    }
    power *= 2.0 / fs_hz * df;
    scale_ = std::sqrt(mean_square_pa2 / power);
  }
  double next() {
    const double w = normal_.next();
    for (std::size_t k = 0; k < 6; ++k) b_[k] = kP[k] * b_[k] + kG[k] * w;
    const double pink = b_[0] + b_[1] + b_[2] + b_[3] + b_[4] + b_[5] + delayed_ + kD0 * w;
    delayed_ = kD1 * w;
    return scale_ * pink;
  }

 private:
  static constexpr std::array<double, 6> kP{0.99886, 0.99332, 0.96900, 0.86650, 0.55000, -0.7616};
  static constexpr std::array<double, 6> kG{0.0555179, 0.0750759, 0.1538520, 0.3104856, 0.5329522, -0.0168980};
  static constexpr double kD0 = 0.5362, kD1 = 0.115926;
  rnd::Normal normal_;
  std::array<double, 6> b_{};
  double delayed_ = 0.0;
  double scale_ = 0.0;
};

// Static response of the structural path to a constant pressure: k1 z + k3 z^3 = p, y = c0 z.
double static_output_pa(const BlockParams& b, double pressure_pa) {
  double z = pressure_pa / b.k1;
  for (int it = 0; it < 60; ++it) z -= (b.k1 * z + b.k3 * z * z * z - pressure_pa) / (b.k1 + 3.0 * b.k3 * z * z);
  return b.c0 * z;
}

}  // namespace

std::vector<double> mic_spread_gains(std::size_t count, double spread_db, std::uint64_t setup_seed) {
  std::uint64_t state = setup_seed ^ 0x6D69635F6761696EULL;
  std::vector<double> gains(count);
  double energy = 0.0;
  for (auto& g : gains) {
    const double u1 = rnd::unit(rnd::splitmix64(state));
    const double u2 = static_cast<double>(rnd::splitmix64(state) >> 11) * 0x1.0p-53;
    const double n = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
    g = std::pow(10.0, spread_db * n / 20.0);
    energy += g * g;
  }
  for (auto& g : gains) g /= std::sqrt(energy / static_cast<double>(count));
  return gains;
}

struct VirtualEngine::Impl {
  VirtualEngineConfig cfg;
  BlockParams block_params;
  BlockModel block;
  std::size_t latency;
  std::size_t latency_left;
  SecondModeFilter second_mode;
  double gain;
  double hp_a, hp_x, hp_y = 0.0;
  std::optional<MechanicalNoise> mechanical;
  std::size_t decimation;
  std::optional<dsp::RationalResampler> to_output;
  std::size_t mics;
  std::vector<double> spread, mic_factor;
  std::vector<std::int64_t> delay;  // output samples
  std::int64_t min_delay = 0;
  std::vector<double> line;  // engine sound at the output rate, circular
  std::size_t line_mask = 0;
  std::int64_t line_avail = 0;  // output samples of engine sound produced
  std::int64_t input_next = 0;  // next input index to pull
  std::int64_t frames = 0;      // output frames rendered
  std::vector<PinkNoise> floor;
  std::vector<BackgroundNoise> background;
  std::vector<rnd::Normal> self_noise;
  double self_noise_rms = 0.0;
  std::vector<DirectivityFilter> directivity;
  Adc mic_adc;
  PressureChain pressure_chain;
  std::vector<double> u, y, crank, out_tmp;

  explicit Impl(const VirtualEngineConfig& c)
      : cfg(c),
        block_params(with_structural_effects(c.true_block, c.effects)),
        block(block_params, c.input_rate_hz),
        latency(block.latency_samples()),
        latency_left(latency),
        second_mode(c.effects, c.input_rate_hz),
        gain(structural_gain(c.effects, c.speed_rpm, c.soi_deg_btdc, c.motored)),
        hp_a(1.0 / (1.0 + 2.0 * kPi * c.ac_coupling_hz / c.input_rate_hz)),
        hp_x(gain * static_output_pa(block_params, c.mean_pressure_pa)),
        mics(c.mic_positions_m.size()),
        pressure_chain(c.pressure_chain, c.effects, c.seed) {
    const double ratio = c.input_rate_hz / c.output_rate_hz;
    if (!(c.output_rate_hz > 0.0) || !(ratio >= 1.0) || std::abs(ratio - std::round(ratio)) > 1e-9)
      throw std::invalid_argument("virtual engine: the input rate must be a whole multiple of the output rate");
    if (mics == 0) throw std::invalid_argument("virtual engine: no microphone positions");
    if (c.effects.mic_gain_db != 0.0 &&
        (c.effects.mic_gain_mic < 1 || static_cast<std::size_t>(c.effects.mic_gain_mic) > mics))
      throw std::invalid_argument("effect mic_gain: microphone " + std::to_string(c.effects.mic_gain_mic) +
                                  " does not exist (the layout has " + std::to_string(mics) + ")");
    if (!(c.speed_of_sound_m_s > 0.0)) throw std::invalid_argument("virtual engine: speed of sound must be positive");
    decimation = static_cast<std::size_t>(std::llround(ratio));
    if (decimation > 1) to_output.emplace(c.input_rate_hz, c.output_rate_hz, 1);
    if (c.effects.mechanical_noise_dba)
      mechanical.emplace(*c.effects.mechanical_noise_dba, c.speed_rpm, c.soi_deg_btdc, c.input_rate_hz, c.seed);
    spread = mic_spread_gains(mics, c.mic_gain_spread_db, c.setup_seed);
    for (std::size_t i = 0; i < mics; ++i) mic_factor.push_back(mic_gain_factor(c.effects, i));
    for (const auto& q : c.mic_positions_m)
      delay.push_back(
          std::llround(std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) / c.speed_of_sound_m_s * c.output_rate_hz));
    min_delay = *std::min_element(delay.begin(), delay.end());
    const auto max_delay = static_cast<std::size_t>(*std::max_element(delay.begin(), delay.end()));
    line.assign(next_pow2(max_delay + 4 * kBatch + 64), 0.0);
    floor.reserve(mics);
    background.reserve(mics);
    line_mask = line.size() - 1;
    if (std::isfinite(c.floor_db)) {
      floor.emplace_back(dsp::mean_square_from_level(c.floor_db), c.output_rate_hz, rnd::key(c.seed, kStreamFloor, 0));
      for (std::size_t i = 1; i < mics; ++i) floor.emplace_back(floor.front(), rnd::key(c.seed, kStreamFloor, i));
    }
    if (c.effects.background_noise_dba) {
      background.emplace_back(*c.effects.background_noise_dba, c.output_rate_hz,
                              rnd::key(c.seed, kStreamBackground, 0));
      for (std::size_t i = 1; i < mics; ++i)
        background.emplace_back(background.front(), rnd::key(c.seed, kStreamBackground, i));
    }
    set_up_mic_chain(c);
    u.resize(kBatch);
    y.resize(kBatch);
    crank.resize(kBatch + latency);
    out_tmp.resize((to_output ? to_output->max_output_frames(kBatch) : kBatch) + 16);
  }

  // Self-noise, directivity and ADC of every microphone (model/engine/mic_chain.hpp).
  void set_up_mic_chain(const VirtualEngineConfig& c) {
    c.mic_chain.validate();
    if (c.mic_chain.has_self_noise()) {
      self_noise_rms = self_noise_rms_pa(c.mic_chain.self_noise_dba, c.output_rate_hz);
      for (std::size_t i = 0; i < mics; ++i) self_noise.emplace_back(rnd::key(c.seed, kStreamSelfNoise, i));
    }
    for (const auto& g : directivity_gains_db(mics, c.mic_chain.directivity_db, c.output_rate_hz, c.setup_seed))
      directivity.emplace_back(g, c.output_rate_hz);
    if (c.mic_chain.adc_bits > 0)
      mic_adc = Adc(c.mic_chain.adc_bits, -c.mic_chain.adc_range_pa, c.mic_chain.adc_range_pa);
  }

  // One input batch through the structural path into the line.
  void pull(PressureFeed& feed) {
    // crank[0, latency) holds the angles of the latency samples before this batch: block output o of this batch
    // belongs to input index input_next + o - latency, whose angle is crank[o].
    feed.fill(input_next, u.data(), crank.data() + latency, kBatch);
    input_next += static_cast<std::int64_t>(kBatch);
    block.process(u.data(), y.data(), kBatch);
    const std::size_t skip = std::min(latency_left, kBatch);
    latency_left -= skip;
    double* s = y.data() + skip;
    const std::size_t n = kBatch - skip;
    second_mode.process(s, n);
    for (std::size_t i = 0; i < n; ++i) {
      const double v = gain * s[i];
      hp_y = hp_a * (hp_y + v - hp_x);
      hp_x = v;
      s[i] = hp_y;
    }
    if (mechanical) mechanical->add(crank.data() + skip, s, n);
    std::copy(crank.end() - static_cast<std::ptrdiff_t>(latency), crank.end(), crank.begin());
    if (to_output) {
      const std::size_t made = to_output->process(s, n, out_tmp.data(), out_tmp.size());
      for (std::size_t i = 0; i < made; ++i) line[static_cast<std::size_t>(line_avail++) & line_mask] = out_tmp[i];
    } else {
      for (std::size_t i = 0; i < n; ++i) line[static_cast<std::size_t>(line_avail++) & line_mask] = s[i];
    }
  }

  void render(PressureFeed& feed, double* out, std::size_t count) {
    for (std::size_t f = 0; f < count; ++f, ++frames) {
      while (line_avail <= frames - min_delay) pull(feed);
      double* frame = out + f * mics;
      for (std::size_t i = 0; i < mics; ++i) {
        const std::int64_t src = frames - delay[i];
        double v = directivity[i].process(src < 0 ? 0.0 : spread[i] * line[static_cast<std::size_t>(src) & line_mask]);
        if (!floor.empty()) v += floor[i].next();
        if (!background.empty()) v += background[i].next();
        if (!self_noise.empty()) v += self_noise_rms * self_noise[i].next();
        frame[i] = mic_factor[i] * mic_adc.convert(v);
      }
    }
  }
};

VirtualEngine::VirtualEngine(const VirtualEngineConfig& config) : impl_(std::make_unique<Impl>(config)) {}
VirtualEngine::~VirtualEngine() = default;
VirtualEngine::VirtualEngine(VirtualEngine&&) noexcept = default;
VirtualEngine& VirtualEngine::operator=(VirtualEngine&&) noexcept = default;

std::size_t VirtualEngine::mic_count() const { return impl_->mics; }
void VirtualEngine::render(PressureFeed& feed, double* mics, std::size_t frames) { impl_->render(feed, mics, frames); }
std::int64_t VirtualEngine::frames_rendered() const { return impl_->frames; }

void VirtualEngine::measured_pressure(std::int64_t first, const double* p_true, double* p_measured, std::size_t n) {
  if (p_measured != p_true) std::copy(p_true, p_true + n, p_measured);
  impl_->pressure_chain.measure(first, p_measured, n);
}

std::uint64_t VirtualEngine::pressure_clipped() const { return impl_->pressure_chain.clipped_samples(); }
std::uint64_t VirtualEngine::mic_clipped() const { return impl_->mic_adc.clipped(); }

std::complex<double> VirtualEngine::directivity_response(std::size_t mic, double f_hz) const {
  return impl_->directivity.at(mic).response(f_hz);
}

const VirtualEngineConfig& VirtualEngine::config() const { return impl_->cfg; }
const BlockParams& VirtualEngine::structural_block() const { return impl_->block_params; }
const std::vector<double>& VirtualEngine::spread_gains() const { return impl_->spread; }

std::vector<double> VirtualEngine::delays_s() const {
  std::vector<double> d;
  for (auto k : impl_->delay) d.push_back(static_cast<double>(k) / impl_->cfg.output_rate_hz);
  return d;
}

}  // namespace noisemon::model::engine
