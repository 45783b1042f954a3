// Cost of resampling per second of data; the x_realtime counter is seconds of data processed per second
// of CPU time (so 1 / x_realtime of a core is busy for the stream).
//  - RationalResampler 51.2 kHz -> 40 kHz, 10 microphone channels, 256-frame input blocks, in single precision
//    (float WAVs, ADC words: import and the DAQ card) and double (the default; the virtual engine's 102.4 kHz).
//  - NonuniformResampler -> 40 kHz, 1 ms input blocks: the pressure channel (1) from 207 kHz encoder edges
//    (0.1 deg at 3450 rpm, 1 % speed ripple) with the highest edge rate given as 3450 rpm's and with the
//    any-encoder default; 2 channels from 183 kHz edges (0.1 deg at 3050 rpm); and 6 kHz edges (1 deg at
//    1000 rpm) for the slow-encoder case.
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "dsp/resample.hpp"

namespace {

using noisemon::dsp::NonuniformResampler;
using noisemon::dsp::RationalResampler;

void BM_Rational(benchmark::State& state, double in_rate, double out_rate, std::size_t channels,
                 noisemon::dsp::SamplePrecision precision) {
  const auto frames = static_cast<std::size_t>(in_rate);  // one second
  std::vector<double> x(frames * channels);
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (double& v : x) v = noise(rng);
  constexpr std::size_t kBlock = 256;
  RationalResampler r(in_rate, out_rate, channels, precision);
  std::vector<double> out(r.max_output_frames(kBlock) * channels);
  for (auto _ : state) {
    for (std::size_t i = 0; i < frames; i += kBlock) {
      const std::size_t n = std::min(kBlock, frames - i);
      benchmark::DoNotOptimize(r.process(&x[i * channels], n, out.data(), r.max_output_frames(n)));
    }
  }
  // One second of data per iteration: the rate is seconds of data per second of CPU.
  state.counters["x_realtime"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// Edge times of a crank with a 1 % speed ripple once per cycle (first-order inverse: plenty for timing).
// max_edge_rate_hz 0: the resampler's any-encoder default.
void BM_Nonuniform(benchmark::State& state, double rpm, double resolution_deg, std::size_t channels,
                   double max_edge_rate_hz) {
  const double w0 = rpm * 6.0, rate = w0 / resolution_deg, ripple_w = 2.0 * std::numbers::pi * rpm / 120.0;
  const auto n = static_cast<std::size_t>(rate);  // one second
  std::vector<double> t(n), x(n * channels);
  for (std::size_t i = 0; i < n; ++i) {
    const double t_even = static_cast<double>(i) / rate;
    t[i] = t_even - 0.01 * (1.0 - std::cos(ripple_w * t_even)) / ripple_w;
    for (std::size_t c = 0; c < channels; ++c)
      x[i * channels + c] = 1e5 + 1e3 * std::sin(2.0 * std::numbers::pi * (1000.0 + 3000.0 * c) * t[i]);
  }
  const auto block = static_cast<std::size_t>(rate / 1000.0);
  std::vector<double> out(4096 * channels);
  for (auto _ : state) {
    state.PauseTiming();
    NonuniformResampler r = max_edge_rate_hz > 0.0 ? NonuniformResampler(40000.0, channels, max_edge_rate_hz)
                                                   : NonuniformResampler(40000.0, channels);  // times restart at 0
    state.ResumeTiming();
    for (std::size_t i = 0; i < n; i += block) {
      const std::size_t m = std::min(block, n - i);
      benchmark::DoNotOptimize(r.process(&t[i], &x[i * channels], m, out.data(), 4096));
    }
  }
  // One second of data per iteration: the rate is seconds of data per second of CPU.
  state.counters["x_realtime"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

BENCHMARK_CAPTURE(BM_Rational, mics_51k2_to_40k_10ch_single, 51200.0, 40000.0, 10,
                  noisemon::dsp::SamplePrecision::kSingle)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Rational, mics_51k2_to_40k_10ch_double, 51200.0, 40000.0, 10,
                  noisemon::dsp::SamplePrecision::kDouble)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Rational, sim_102k4_to_51k2_10ch_double, 102400.0, 51200.0, 10,
                  noisemon::dsp::SamplePrecision::kDouble)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Nonuniform, edges_207k_1ch_max_3450rpm, 3450.0, 0.1, 1, 3450.0 * 3600.0 / 60.0)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Nonuniform, edges_207k_1ch_any_encoder, 3450.0, 0.1, 1, 0.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Nonuniform, edges_183k_2ch, 3050.0, 0.1, 2, 0.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Nonuniform, edges_6k_2ch, 1000.0, 1.0, 2, 0.0)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
