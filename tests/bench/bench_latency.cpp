// Report latency at real time: the daemon's pipeline on the virtual engine (paced to the wall clock, the
// default configuration) publishing through the real LCM publisher (to a log file, so nothing leaves the
// machine), for 20 s. Prints p50 / p99 / max of the time from a cycle's last sample reaching the processing
// thread to its report handed to LCM, over every cycle, and the worst of the status messages' per-second p99.
// Not a pass/fail test: a shared 2-core machine's scheduler is part of the figure.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/latency_window.hpp"
#include "daemon/lcm_publisher.hpp"
#include "daemon/pipeline.hpp"
#include "daemon/sources.hpp"

namespace {

namespace nd = noisemon::daemon;
using Clock = std::chrono::steady_clock;

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

void BM_ReportLatencyAtRealTime(benchmark::State& state) {
  const std::filesystem::path log = std::filesystem::temp_directory_path() / "noisemon_bench_latency.lcmlog";
  for (auto _ : state) {
    nd::Config config;  // the default: the simulated engine, paced
    nd::LatencyWindow all(1 << 16);
    std::mutex m;
    nd::PipelineOptions options;
    options.quiet = true;
    options.on_report = [&](const nd::CycleReport& r) {
      const double ms = 1e-6 * static_cast<double>(steady_ns() - r.input_ns);
      std::lock_guard<std::mutex> lock(m);
      all.add(ms);
    };
    auto publisher = std::make_shared<nd::LcmPublisher>("file://" + log.string() + "?mode=w");
    nd::Pipeline pipeline(config, nd::make_source(config), publisher, options);
    pipeline.start();
    std::this_thread::sleep_for(std::chrono::seconds(20));
    pipeline.stop();
    std::lock_guard<std::mutex> lock(m);
    state.counters["cycles"] = static_cast<double>(pipeline.cycles_published());
    state.counters["p50_ms"] = all.quantile(0.5);
    state.counters["p99_ms"] = all.quantile(0.99);
    state.counters["max_ms"] = all.max();
  }
  std::filesystem::remove(log);
}

BENCHMARK(BM_ReportLatencyAtRealTime)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
