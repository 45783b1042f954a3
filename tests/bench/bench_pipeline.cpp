// Per-cycle processing time of the whole processing stage (CycleProcessor) for 11 input channels: cylinder
// pressure + ten microphones, i.e. block model on the pressure and 1/3-octave bands on 12 channels
// (pressure, prediction, ten microphones), levels, A-weighting and the report; with and without the crank-angle
// stream of a 0.1 deg encoder (4.6 edges a frame at 3050 rpm), whose cycles the combustion figures then come from.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <numbers>
#include <random>

#include "daemon/cycle_processor.hpp"

using namespace noisemon;

namespace {

constexpr double kFs = 40000.0;

void BM_CycleProcessing(benchmark::State& state) {
  const int cycle_frames = static_cast<int>(state.range(0));  // 1574 = 3050 rpm, 1391 = 3450 rpm
  const bool angle_stream = state.range(2) != 0;
  drivers::StreamInfo info;
  info.mic_count = 10;
  info.acoustic_delay_s = 1.75 / 343.0;
  info.pressure_angle_step_deg = angle_stream ? 0.1 : 0.0;
  daemon::ProcessorConfig pc;
  pc.model = model::preset(state.range(1) ? "nl_damper" : "linear");
  std::int64_t reports = 0;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport&) { ++reports; });

  // One second of realistic-looking input, reused: a pressure pulse per cycle and noisy microphones.
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.5);
  const std::int64_t blocks = 160;  // 160 x 256 frames = 1.024 s
  std::vector<drivers::SampleBlock> pb(blocks), mb(blocks);
  std::vector<std::vector<drivers::SampleBlock>> ab(blocks);  // the edges within each 256 frames, <= 256 a block
  const auto pressure_at = [](double x) { return 1e5 + 6e6 * std::exp(-x * x / (2 * 0.02 * 0.02)); };
  for (std::int64_t b = 0; b < blocks; ++b) {
    pb[b].frames = mb[b].frames = 256;
    pb[b].channels = 2;
    mb[b].channels = 10;
    for (int f = 0; f < 256; ++f) {
      const std::int64_t k = b * 256 + f;
      const double x = static_cast<double>(k % cycle_frames) / cycle_frames - 0.5;  // cycle phase, 0 = TDC
      pb[b].data[f * 2] = pressure_at(x);
      pb[b].data[f * 2 + 1] = -360.0 + 720.0 * (x + 0.5);
      for (int m = 0; m < 10; ++m) mb[b].data[f * 10 + m] = noise(rng);
    }
  }
  const double frames_per_edge = 0.1 / 720.0 * cycle_frames;
  for (std::int64_t e = 0; angle_stream && static_cast<double>(e) * frames_per_edge < blocks * 256.0; ++e) {
    const double t = static_cast<double>(e) * frames_per_edge, x = std::fmod(t, cycle_frames) / cycle_frames - 0.5;
    auto& group = ab[static_cast<std::size_t>(t / 256.0)];
    if (group.empty() || group.back().frames == 256) {
      group.emplace_back();
      group.back().channels = drivers::kAngleStreamChannels;
      group.back().first_index = static_cast<std::int64_t>(std::floor(t));
    }
    drivers::SampleBlock& a = group.back();
    a.data[a.frames * 2 + drivers::kAngleCrankChannel] = -360.0 + 720.0 * (x + 0.5);
    a.data[a.frames * 2 + drivers::kAnglePressureChannel] = pressure_at(x);
    ++a.frames;
  }
  std::int64_t offset = 0, frames = 0;
  double busy_s = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    for (std::int64_t b = 0; b < blocks; ++b) {
      pb[b].first_index = mb[b].first_index = offset + b * 256;
      // Keep the crank channel continuous across repetitions.
      const daemon::CycleProcessor::CpuBatch cpu(p);  // as the processing thread times each batch of blocks
      for (drivers::SampleBlock& a : ab[b]) {
        a.first_index += offset;
        p.add_pressure_angle(a);
        a.first_index -= offset;
      }
      p.add_pressure(pb[b]);
      p.add_mics(mb[b]);
      p.process();
    }
    busy_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    offset += blocks * 256;
    frames += blocks * 256;
  }
  const double seconds_of_data = static_cast<double>(frames) / kFs;
  state.counters["cycles"] = static_cast<double>(reports);
  state.counters["us_per_cycle"] = reports ? 1e6 * busy_s / static_cast<double>(reports) : 0.0;
  state.counters["x_realtime"] = benchmark::Counter(seconds_of_data, benchmark::Counter::kIsRate);
}

}  // namespace

BENCHMARK(BM_CycleProcessing)
    ->Args({1574, 0, 0})
    ->Args({1574, 0, 1})
    ->Args({1574, 1, 0})
    ->Args({1391, 0, 0})
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
