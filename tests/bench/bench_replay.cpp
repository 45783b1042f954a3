// Offline replay speed: a raw LCM log of 11 channels at 40 kHz (pressure + crank, ten microphones) through
// `noisemon replay`'s path (log reading, decoding, cycle processing, CSV), as a multiple of real time.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <lcm/lcm-cpp.hpp>
#include <numbers>
#include <random>

#include "daemon/replay.hpp"
#include "drivers/formats/stream_messages.hpp"

using namespace noisemon;

namespace {

constexpr double kFs = 40000.0;

template <class Message>
void write(lcm::LogFile& log, const std::string& channel, const Message& m) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm::LogEvent e{0, 0, channel, static_cast<std::int32_t>(buf.size()), buf.data()};
  log.writeEvent(&e);
}

// seconds of synthetic data at 3050 rpm: a pressure pulse per cycle, noisy microphones.
std::string make_log(double seconds) {
  const std::string path = "/tmp/noisemon_bench_replay_" + std::to_string(getpid()) + ".lcmlog";  // this run's own
  lcm::LogFile log(path, "w");
  drivers::StreamInfo info;
  info.mic_count = 10;
  info.mic_positions_m.assign(10, {0, 0, 1.75});
  info.acoustic_delay_s = 1.75 / 343.0;
  write(log, "NOISEMON_SESSION", drivers::formats::to_message(info, "bench", 0));
  const int cycle = 1574;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.5);
  drivers::SampleBlock p, m;
  for (std::int64_t first = 0; first < static_cast<std::int64_t>(seconds * kFs); first += 256) {
    p.first_index = m.first_index = first;
    p.frames = m.frames = 256;
    p.channels = 2;
    m.channels = 10;
    for (int f = 0; f < 256; ++f) {
      const std::int64_t k = first + f;
      const double x = static_cast<double>(k % cycle) / cycle - 0.5;
      p.data[2 * f] = 1e5 + 6e6 * std::exp(-x * x / (2 * 0.02 * 0.02));
      p.data[2 * f + 1] = 720.0 * x;
      for (int c = 0; c < 10; ++c) m.data[f * 10 + c] = noise(rng);
    }
    write(log, "NOISEMON_RAW", drivers::formats::to_message(p, 0, 0));
    write(log, "NOISEMON_RAW", drivers::formats::to_message(m, 1, 0));
  }
  return path;
}

void BM_OfflineReplay(benchmark::State& state) {
  const double seconds = 10.0;
  const std::string path = make_log(seconds);
  daemon::ReplayOptions o;
  o.log_path = path;
  o.csv_path = path + ".csv";
  o.progress = false;
  std::int64_t cycles = 0;
  double wall_s = 0, cpu_s = 0;
  for (auto _ : state) {
    const auto w0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    cycles += daemon::run_replay(o).reports;
    cpu_s += static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
    wall_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
  }
  const double replayed_s = seconds * static_cast<double>(state.iterations());
  state.counters["cycles"] = static_cast<double>(cycles);
  // Seconds of 11-channel 40 kHz data replayed per second: by the clock, and per second of CPU (one core; what
  // the figure would be on an idle machine).
  state.counters["x_realtime"] = replayed_s / wall_s;
  state.counters["x_realtime_cpu"] = replayed_s / cpu_s;
  std::remove(path.c_str());
  std::remove(o.csv_path.c_str());
}

}  // namespace

BENCHMARK(BM_OfflineReplay)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK_MAIN();
