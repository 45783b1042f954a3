// CPU time of the block model per second of 40 kHz input, streamed in 10 ms blocks.
// Counters: cpu_per_data_s = CPU time per second of data; x_realtime = seconds of data per CPU second.
// Cases: each Table 4.1 preset on a pressure-like trace (mean about 3e6 Pa, a sharp combustion pulse
// every 39 ms, knock ringing); the simulator's 100 kHz rate; the worst case for the nonlinear models
// (full-band noise of 1e7 Pa, where step refinement hits its ration); and the ten seconds of zero
// input after a pulse train, where an unflushed state would decay through subnormal numbers.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "model/block_model.hpp"
#include "model/block_params.hpp"

namespace {

constexpr std::size_t kBlock = 400;  // 10 ms at 40 kHz

void set_counters(benchmark::State& state, double seconds_of_data_per_iteration) {
  const double seconds = seconds_of_data_per_iteration * static_cast<double>(state.iterations());
  state.counters["cpu_per_data_s"] =
      benchmark::Counter(seconds, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["x_realtime"] = benchmark::Counter(seconds, benchmark::Counter::kIsRate);
}

// Cylinder-pressure-like trace: compression hump, then a combustion pulse rising in 0.3 ms and decaying
// in 1.5 ms, with 6.5 kHz knock ringing; one cycle every 39 ms (about 3100 rpm).
std::vector<double> pressure_trace(double fs, double seconds) {
  constexpr double kCycle = 0.039, kPi = std::numbers::pi;
  std::vector<double> u(static_cast<std::size_t>(fs * seconds));
  for (std::size_t i = 0; i < u.size(); ++i) {
    const double t = std::fmod(static_cast<double>(i) / fs, kCycle) - 0.0195;  // TDC mid-cycle
    double p = 2e6 + 3e6 * std::exp(-t * t / (2 * 3e-3 * 3e-3));
    if (t > 0) {
      const double rise = t < 0.3e-3 ? 0.5 * (1 - std::cos(kPi * t / 0.3e-3)) : 1.0;
      p += 6e6 * rise * std::exp(-std::max(0.0, t - 0.3e-3) / 1.5e-3);
      p += 1e5 * std::sin(2 * kPi * 6500 * t) * std::exp(-t / 2e-3);
    }
    u[i] = p;
  }
  return u;
}

void run(benchmark::State& state, noisemon::model::BlockModel& model, const std::vector<double>& u, double seconds) {
  std::vector<double> y(kBlock);
  for (auto _ : state) {
    for (std::size_t pos = 0; pos < u.size(); pos += kBlock) {
      model.process(u.data() + pos, y.data(), std::min(kBlock, u.size() - pos));
      benchmark::DoNotOptimize(y.data());
    }
  }
  set_counters(state, seconds);
}

void BM_BlockModel_PressureTrace(benchmark::State& state, const std::string& preset, double fs) {
  const std::vector<double> u = pressure_trace(fs, 1.0);
  noisemon::model::BlockModel model(noisemon::model::preset(preset), fs);
  run(state, model, u, 1.0);
}

void BM_BlockModel_FullBandNoise(benchmark::State& state, const std::string& preset) {
  const double fs = 40000;
  std::vector<double> u(static_cast<std::size_t>(fs));
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> noise(-1e7, 1e7);
  for (double& v : u) v = 3e6 + noise(rng);
  noisemon::model::BlockModel model(noisemon::model::preset(preset), fs);
  run(state, model, u, 1.0);
}

void BM_BlockModel_SilenceAfterPulses(benchmark::State& state, const std::string& preset) {
  const double fs = 40000;
  const std::vector<double> pulses = pressure_trace(fs, 0.5);
  const std::vector<double> silence(static_cast<std::size_t>(10 * fs), 0.0);
  noisemon::model::BlockModel model(noisemon::model::preset(preset), fs);
  std::vector<double> y(pulses.size());
  for (auto _ : state) {
    state.PauseTiming();
    model.reset();
    model.process(pulses.data(), y.data(), pulses.size());
    state.ResumeTiming();
    for (std::size_t pos = 0; pos < silence.size(); pos += kBlock) {
      model.process(silence.data() + pos, y.data(), kBlock);
      benchmark::DoNotOptimize(y.data());
    }
  }
  set_counters(state, 10.0);
}

}  // namespace

BENCHMARK_CAPTURE(BM_BlockModel_PressureTrace, linear, std::string("linear"), 40000.0)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_BlockModel_PressureTrace, nl_damper, std::string("nl_damper"), 40000.0)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_BlockModel_PressureTrace, nl_spring_damper, std::string("nl_spring_damper"), 40000.0)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_BlockModel_PressureTrace, nl_spring_damper_opt, std::string("nl_spring_damper_opt"), 40000.0)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_BlockModel_PressureTrace, nl_spring_damper_opt_100kHz, std::string("nl_spring_damper_opt"),
                  100000.0)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_BlockModel_FullBandNoise, nl_spring_damper_opt, std::string("nl_spring_damper_opt"))
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_BlockModel_SilenceAfterPulses, linear, std::string("linear"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_BlockModel_SilenceAfterPulses, nl_damper, std::string("nl_damper"))->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
