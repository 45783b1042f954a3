#include "cli/watch.hpp"
#include "cli/lcm_loop.hpp"

#include <poll.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <limits>

#include "daemon/cycle_statistics.hpp"
#include "daemon/report_messages.hpp"
#include "noisemon/cycle_stats_t.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::cli {
namespace {

volatile std::sig_atomic_t g_stop = 0;

// Adapts a callable to LCM's member-function subscription.
template <class Message>
struct Handler {
  std::function<void(const Message*)> fn;
  void on(const lcm::ReceiveBuffer*, const std::string&, const Message* m) { fn(m); }
};
void on_signal(int) { g_stop = 1; }

void print_bands(const noisemon::cycle_report_t& r) {
  std::printf("      band Hz   CPL dB   meas dB(A)  pred dB(A)  att meas  att pred    K1 dB  flags\n");
  for (int b = 0; b < r.nbands; ++b)
    std::printf("    %9.1f %8.1f %12.1f %11.1f %9.1f %9.1f %8.2f  %d\n", r.band_hz[b], r.cpl_db[b],
                r.spl_a_measured_db[b], r.spl_a_predicted_db[b], r.att_measured_db[b], r.att_predicted_db[b],
                r.k1_db[b], r.band_flags[b]);
}

const char* thread_state_name(std::int8_t s) {
  switch (s) {
    case noisemon::status_t::THREAD_IDLE:
      return "idle";
    case noisemon::status_t::THREAD_RUNNING:
      return "running";
    case noisemon::status_t::THREAD_STOPPED:
      return "stopped";
    case noisemon::status_t::THREAD_FAILED:
      return "FAILED";
  }
  return "?";
}

void print_status(const noisemon::status_t& s) {
  std::printf(
      "status  source=%s uptime=%.1fs published=%lld dropped=%lld latency=%.1f/%.1fms processing=%.3f/%.3fms "
      "report latency p50/p99/max=%.3f/%.3f/%.3fms\n",
      s.source.c_str(), s.uptime_s, static_cast<long long>(s.cycles_published),
      static_cast<long long>(s.cycles_dropped), s.latency_ms_mean, s.latency_ms_max, s.processing_ms_mean,
      s.processing_ms_max, s.report_latency_ms_p50, s.report_latency_ms_p99, s.report_latency_ms_max);
  std::printf("  threads:");
  for (int i = 0; i < s.nthreads; ++i) {
    std::printf(" %s=%s", s.thread_name[i].c_str(), thread_state_name(s.thread_state[i]));
    if (!s.thread_error[i].empty()) std::printf("(%s)", s.thread_error[i].c_str());
  }
  std::printf("\n  rings:");
  for (int i = 0; i < s.nrings; ++i)
    std::printf(" %s=%.0f%%/%lld overruns", s.ring_name[i].c_str(), 100.0 * s.ring_fill[i],
                static_cast<long long>(s.ring_overruns[i]));
  std::printf("\n");
  if (s.ncounters > 0) {
    std::printf("  counters:");
    for (int i = 0; i < s.ncounters; ++i)
      std::printf(" %s=%lld", s.counter_name[i].c_str(), static_cast<long long>(s.counter_value[i]));
    std::printf("\n");
  }
  if (!s.record_file.empty()) std::printf("  recording into %s\n", s.record_file.c_str());
}

}  // namespace

int run_watch(const WatchOptions& o) {
  lcm::LCM lcm(o.lcm_url);
  if (!lcm.good()) {
    std::fprintf(stderr, "noisemon watch: %s\n", lcm_open_error(o.lcm_url).c_str());
    return 1;
  }
  std::ofstream csv;
  if (!o.csv_path.empty()) {
    csv.open(o.csv_path);
    if (!csv) {
      std::fprintf(stderr, "noisemon watch: cannot write %s\n", o.csv_path.c_str());
      return 1;
    }
    csv << daemon::cycle_csv_header();
  }
  std::int64_t received = 0;
  auto last = std::chrono::steady_clock::now();
  // Every message shown counts toward --count and restarts the --timeout clock.
  const auto show = [&](const auto& print) {
    if (o.count > 0 && received >= o.count) return;
    print();
    std::fflush(stdout);
    ++received;
    last = std::chrono::steady_clock::now();
  };
  Handler<noisemon::cycle_report_t> handler;
  handler.fn = [&](const noisemon::cycle_report_t* r) {
    show([&] {
      if (received % 40 == 0) std::printf("%s\n", daemon::cycle_line_header().c_str());
      std::printf("%s\n", daemon::cycle_line(*r).c_str());
      if (o.bands) print_bands(*r);
      if (csv.is_open()) csv << daemon::cycle_csv_row(*r) << std::flush;
    });
  };
  Handler<noisemon::status_t> status_handler;
  status_handler.fn = [&](const noisemon::status_t* s) { show([&] { print_status(*s); }); };
  Handler<noisemon::cycle_stats_t> stats_handler;
  stats_handler.fn = [&](const noisemon::cycle_stats_t* s) {
    show([&] {
      std::printf("stats  last %d of %d cycles\n%s", s->cycles, s->window_cycles,
                  daemon::statistics_text(daemon::from_message(*s)).c_str());
    });
  };
  if (o.stats)
    lcm.subscribe(o.stats_channel, &Handler<noisemon::cycle_stats_t>::on, &stats_handler);
  else if (o.status)
    lcm.subscribe(o.status_channel, &Handler<noisemon::status_t>::on, &status_handler);
  else  // a second's reports and more wait while a loaded machine leaves this process unscheduled (LCM's default: 30)
    lcm.subscribe(o.channel, &Handler<noisemon::cycle_report_t>::on, &handler)->setQueueCapacity(1024);

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  while (!g_stop && (o.count == 0 || received < o.count)) {
    pollfd pfd{lcm.getFileno(), POLLIN, 0};
    const int ready = ::poll(&pfd, 1, 100);
    if (ready > 0) lcm.handle();
    if (o.timeout_s > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - last).count() > o.timeout_s) {
      const std::string& channel = o.stats ? o.stats_channel : o.status ? o.status_channel : o.channel;
      std::fprintf(stderr, "noisemon watch: nothing on %s for %.1f s\n", channel.c_str(), o.timeout_s);
      return 2;
    }
  }
  return 0;
}

}  // namespace noisemon::cli
