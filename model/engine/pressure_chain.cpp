#include "model/engine/pressure_chain.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "model/engine/random.hpp"

namespace noisemon::model::engine {

namespace {

// Random stream identifiers (distinct from the effects' and the virtual engine's).
enum : std::uint64_t {
  kStreamPressureFloor = 0x4001,
  kStreamFlickerOffset = 0x4002,
  kStreamFlickerRow = 0x4100,  // + row
};

std::int64_t row_offset(std::uint64_t seed, int row) {
  return static_cast<std::int64_t>(rnd::key(seed, kStreamFlickerOffset, static_cast<std::uint64_t>(row)) &
                                   ((std::uint64_t{1} << row) - 1));
}

double row_value(std::uint64_t seed, int row, std::int64_t block) {
  return rnd::normal_at(seed, kStreamFlickerRow + static_cast<std::uint64_t>(row), static_cast<std::uint64_t>(block));
}

}  // namespace

double PressureChainConfig::adc_step_bar() const {
  return adc_bits > 0 ? (adc_max_bar - adc_min_bar) / std::ldexp(1.0, adc_bits) : 0.0;
}

double PressureChainConfig::floor_bar() const {
  const double q = adc_step_bar();
  return std::sqrt(noise_bar * noise_bar + q * q / 12.0);
}

void PressureChainConfig::validate() const {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("pressure chain: " + what); };
  if (!(noise_bar >= 0.0 && noise_bar <= 100.0)) fail("noise_bar must be in [0, 100]");
  if (!(flicker_bar >= 0.0 && flicker_bar <= 100.0)) fail("flicker_bar must be in [0, 100]");
  if (adc_bits != 0 && (adc_bits < 4 || adc_bits > 32)) fail("adc_bits must be 0 (no ADC) or 4 .. 32");
  if (adc_bits != 0 && !(adc_max_bar > adc_min_bar)) fail("adc_max_bar must be above adc_min_bar");
  if (!(offset_bar >= -100.0 && offset_bar <= 100.0)) fail("offset_bar must be in [-100, 100]");
  if (!(gain_error > -0.5 && gain_error < 0.5)) fail("gain_error must be in (-0.5, 0.5)");
}

// Voss-McCartney: the sum of kFlickerRows rows, row k a unit Gaussian held for 2^k samples (from a seeded offset, so
// the rows do not all change together); each row's spectrum is a low-pass of width ~fs / 2^k and height ~2^k, so
// the sum falls as 1/f between fs / 2^kFlickerRows and fs / 2.
double flicker_unit_at(std::uint64_t seed, std::int64_t index) {
  double sum = 0.0;
  for (int k = 0; k < kFlickerRows; ++k) sum += row_value(seed, k, (index + row_offset(seed, k)) >> k);
  return sum / std::sqrt(static_cast<double>(kFlickerRows));
}

PressureChain::PressureChain(const PressureChainConfig& config, const Effects& effects, std::uint64_t seed)
    : config_(config), effects_(effects), seed_(seed) {
  config_.validate();
  if (config_.adc_bits > 0) adc_ = Adc(config_.adc_bits, 1e5 * config_.adc_min_bar, 1e5 * config_.adc_max_bar);
  for (int k = 0; k < kFlickerRows; ++k) {
    row_block_[k] = std::numeric_limits<std::int64_t>::min();
    row_value_[k] = 0.0;
    row_offset_[k] = row_offset(seed, k);
  }
}

double PressureChain::flicker_at(std::int64_t index) {
  double sum = 0.0;
  for (int k = 0; k < kFlickerRows; ++k) {
    const std::int64_t block = (index + row_offset_[k]) >> k;
    if (block != row_block_[k]) {  // a cache: the value depends on (seed, row, block) only
      row_block_[k] = block;
      row_value_[k] = row_value(seed_, k, block);
    }
    sum += row_value_[k];
  }
  return sum / std::sqrt(static_cast<double>(kFlickerRows));
}

void PressureChain::measure(std::int64_t first_index, double* pressure_pa, std::size_t n) {
  const double white = 1e5 * config_.noise_bar, flicker = 1e5 * config_.flicker_bar;
  const double gain = 1.0 + config_.gain_error, offset = 1e5 * config_.offset_bar;
  for (std::size_t i = 0; i < n; ++i) {
    const std::int64_t index = first_index + static_cast<std::int64_t>(i);
    pressure_pa[i] = gain * pressure_pa[i] + offset;
    if (white > 0.0)
      pressure_pa[i] += white * rnd::normal_at(seed_, kStreamPressureFloor, static_cast<std::uint64_t>(index));
    if (flicker > 0.0) pressure_pa[i] += flicker * flicker_at(index);
  }
  add_transducer_noise(effects_, seed_, first_index, pressure_pa, n);
  adc_.convert(pressure_pa, n);
}

}  // namespace noisemon::model::engine
