// Time to push one second of 40 kHz data through the one-third-octave bank, processed and taken in
// engine-cycle chunks as the pipeline does.
// Counters: cpu_per_data_s = CPU time per second of data (real time allows 1 s; the pipeline runs 12
// channels: pressure, predicted, ten microphones); x_realtime = seconds of data per CPU second.
// The "silence" case times the ten seconds after a noise burst stops, while the filter states decay:
// without flushing they would pass through subnormal numbers, which x86 computes far slower.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>
#include <vector>

#include "dsp/third_octave_bank.hpp"

namespace {

constexpr double kFs = 40000;
constexpr std::size_t kCycleFrames = 1600;  // one engine cycle at 3000 rpm: process, then take

void set_counters(benchmark::State& state, double seconds_of_data_per_iteration) {
  const double seconds = seconds_of_data_per_iteration * static_cast<double>(state.iterations());
  // kIsRate divides by the CPU time; kInvert turns "data seconds per CPU second" into CPU time per data.
  state.counters["cpu_per_data_s"] =
      benchmark::Counter(seconds, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["x_realtime"] = benchmark::Counter(seconds, benchmark::Counter::kIsRate);
}

void process_in_cycles(noisemon::dsp::ThirdOctaveBank& bank, const std::vector<double>& x, std::vector<double>& ms) {
  const std::size_t ch = bank.channels(), frames = x.size() / ch;
  for (std::size_t pos = 0; pos < frames; pos += kCycleFrames) {
    bank.process(x.data() + pos * ch, std::min(kCycleFrames, frames - pos));
    bank.take_mean_square(ms.data());
  }
}

std::vector<double> noise(std::size_t n) {
  std::vector<double> x(n);
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  for (double& v : x) v = g(rng);
  return x;
}

void BM_ThirdOctaveBank_Noise(benchmark::State& state) {
  const auto channels = static_cast<std::size_t>(state.range(0));
  const std::vector<double> x = noise(static_cast<std::size_t>(kFs) * channels);
  noisemon::dsp::ThirdOctaveBank bank(kFs, channels);
  std::vector<double> ms(channels * bank.band_count());
  for (auto _ : state) {
    process_in_cycles(bank, x, ms);
    benchmark::DoNotOptimize(ms.data());
  }
  set_counters(state, 1.0);
}

void BM_ThirdOctaveBank_SilenceAfterNoise(benchmark::State& state) {
  const auto channels = static_cast<std::size_t>(state.range(0));
  const std::vector<double> burst = noise(static_cast<std::size_t>(kFs) * channels);
  const std::vector<double> silence(10 * static_cast<std::size_t>(kFs) * channels, 0.0);
  noisemon::dsp::ThirdOctaveBank bank(kFs, channels);
  std::vector<double> ms(channels * bank.band_count());
  for (auto _ : state) {
    state.PauseTiming();
    bank.reset();
    process_in_cycles(bank, burst, ms);
    state.ResumeTiming();
    process_in_cycles(bank, silence, ms);
    benchmark::DoNotOptimize(ms.data());
  }
  set_counters(state, 10.0);
}

}  // namespace

BENCHMARK(BM_ThirdOctaveBank_Noise)->Arg(1)->Arg(12)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ThirdOctaveBank_SilenceAfterNoise)->Arg(12)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
