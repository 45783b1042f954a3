// CPU cost of the sim source's generators per simulated second (no threads, no pacing): the real-time budget
// is well under one core at 3450 rpm with a 0.1 deg encoder, since the daemon's processing needs the other.
#include <benchmark/benchmark.h>

#include "drivers/sim/sim_generators.hpp"
#include "model/engine/engine_cycle.hpp"

namespace nd = noisemon::drivers;

namespace {

nd::sim::SimConfig config(const benchmark::State& state) {
  nd::sim::SimConfig c;
  c.speed_rpm = static_cast<double>(state.range(0));
  c.load_nm = c.speed_rpm > 3200 ? 20.0 : 0.0;
  c.encoder_resolution_deg = 0.1 * static_cast<double>(state.range(1));
  if (state.range(2)) c.true_block = noisemon::model::preset("nl_spring_damper_opt");
  return c;
}

// One iteration = 1 s of simulated stream, in 5 ms chunks as the driver thread runs it, so the time per
// iteration in ms is the thread's load in thousandths of a core.
template <class Generator>
void run_stream(benchmark::State& state) {
  const nd::sim::SimConfig c = config(state);
  nd::BlockRing ring(64);
  nd::SampleBlock block;
  Generator gen(c, 0.0);
  double t = 0.0;
  gen.advance(t, ring);  // pre-roll
  while (ring.read(&block, 1)) {
  }
  for (auto _ : state) {
    for (int i = 0; i < 200; ++i) {
      t += 0.005;
      gen.advance(t, ring);
      while (ring.read(&block, 1)) {
      }
    }
  }
}

void BM_PressureStream(benchmark::State& state) { run_stream<nd::sim::PressureGenerator>(state); }
void BM_MicStream(benchmark::State& state) { run_stream<nd::sim::MicGenerator>(state); }

void BM_EngineCycleCompute(benchmark::State& state) {
  noisemon::model::engine::EngineCycle cycle;
  const noisemon::model::engine::OperatingCondition op{
      .speed_rpm = 3450.0, .load_nm = 20.0, .soi_deg_btdc = 18.0, .motored = false};
  for (auto _ : state) {
    cycle.compute(op);
    benchmark::DoNotOptimize(cycle.summary().peak_pressure_pa);
  }
}

}  // namespace

// Args: speed rpm, encoder resolution in 0.1 deg, nonlinear true block (0/1).
BENCHMARK(BM_PressureStream)
    ->Args({3450, 1, 0})
    ->Args({3050, 1, 0})
    ->Args({3450, 5, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_MicStream)
    ->Args({3450, 1, 0})
    ->Args({3450, 1, 1})
    ->Args({3050, 1, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_EngineCycleCompute)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
