// What `noisemon fit` costs. Waveform mode: free-run simulations (the inner loop of every Ceres iteration and
// Jacobian column) per second of data, and a whole fit of a Duffing oscillator (k1, b1, k3, c0, c1) to 60 s of
// data at 1 kHz from a start 20-40 % off; band mode: a fit of four virtual-engine conditions (8 cycles each).
// Counters: x_realtime = seconds of data simulated per CPU second; iterations_ceres, fit_s.
#include <benchmark/benchmark.h>

#include <unistd.h>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <random>
#include <vector>

#include "cli/fit_command.hpp"
#include "cli/sim_command.hpp"
#include "daemon/params_file.hpp"
#include "model/fit/waveform_fit.hpp"

namespace {

using namespace noisemon;
constexpr double kFs = 1000.0;

model::fit::WaveformModel duffing() {
  model::fit::WaveformModel m;
  const double w = 2.0 * std::numbers::pi * 40.0;
  m.block.m = 1.0;
  m.block.k1 = w * w;
  m.block.b1 = 2.0 * 0.05 * w;
  m.block.k3 = 0.3 * m.block.k1 / (2.5e-4 * 2.5e-4);
  m.block.b3 = 0.0;
  m.block.c0 = w * w;
  m.block.c1 = 0.5;
  return m;
}

struct Data {
  std::vector<double> u, y;
};

const Data& data() {
  static const Data d = [] {
    Data d;
    const std::size_t n = static_cast<std::size_t>(60 * kFs);
    std::mt19937 gen(3);
    std::normal_distribution<double> g(0.0, 1.0);
    d.u.resize(n);
    double x = 0.0;
    for (double& u : d.u) u = x = 0.7 * x + 0.7 * g(gen);  // coloured noise around the resonance
    d.y.assign(n, 0.0);
    model::fit::WaveformSimOptions sim;
    d.y = model::fit::simulate_waveform(duffing(), kFs, sim, d.u, d.y, {0, n});
    for (double& y : d.y) y += 0.01 * g(gen);
    return d;
  }();
  return d;
}

void BM_FreeRunSimulation(benchmark::State& state) {
  const Data& d = data();
  model::fit::WaveformSimOptions sim;
  sim.settle_samples = 0;
  for (auto _ : state) {
    auto y = model::fit::simulate_waveform(duffing(), kFs, sim, d.u, d.y, {0, d.u.size()});
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["x_realtime"] =
      benchmark::Counter(60.0 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_FreeRunSimulation)->Unit(benchmark::kMillisecond);

void BM_WaveformFitDuffing60s(benchmark::State& state) {
  const Data& d = data();
  model::fit::WaveformFitOptions o;
  o.fs_hz = kFs;
  o.train = {{0, 45000}};
  o.heldout = {{45000, 60000}};
  o.free_params = {"k1", "b1", "k3", "c0", "c1"};
  model::fit::WaveformModel start = duffing();
  start.block.k1 *= 0.8;
  start.block.b1 *= 1.4;
  start.block.c0 *= 1.2;
  start.block.k3 = 0.0;
  o.start = start;
  int iterations = 0;
  double rms = 0.0;
  for (auto _ : state) {
    const model::fit::WaveformFitResult r = model::fit::fit_waveform(d.u, d.y, o);
    iterations = r.iterations;
    rms = r.heldout_rms;
  }
  state.counters["iterations_ceres"] = iterations;
  state.counters["heldout_rms"] = rms;
}
BENCHMARK(BM_WaveformFitDuffing60s)->Unit(benchmark::kSecond)->Iterations(1);

void BM_BandFitFourConditions(benchmark::State& state) {
  const auto dir = std::filesystem::temp_directory_path() / ("noisemon_bench_fit_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  cli::SimOptions so;
  so.conditions = {"idle_mi12", "idle_mi18", "full_mi12", "full_mi18"};
  so.cycles = 8;
  so.out_dir = (dir / "runs").string();
  so.progress = false;
  model::BlockParams truth = model::preset("linear");
  truth.k1 *= 1.5;
  daemon::write_params_file((dir / "truth.toml").string(), truth, "linear");
  so.true_model = (dir / "truth.toml").string();
  const cli::SimSummary runs = cli::run_sim(so);
  cli::FitCommandOptions o;
  o.data = runs.run_dirs;
  o.holdout = {"full"};
  o.progress = false;
  std::FILE* sink = std::tmpfile();
  for (auto _ : state) benchmark::DoNotOptimize(cli::run_fit(o, sink).heldout_rms);
  std::fclose(sink);
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_BandFitFourConditions)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
