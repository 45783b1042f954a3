#include "daemon/watch.hpp"

#include <poll.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <lcm/lcm-cpp.hpp>

#include "daemon/report_messages.hpp"

namespace noisemon::daemon {
namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

void write_csv_header(std::ostream& out) {
  out << "cycle,utime,speed_rpm,load_nm,soi_deg_btdc,motored,lpa_measured_db,lpa_predicted_db,lwa_measured_db,"
         "lwa_predicted_db,flags\n";
}

void write_csv_row(std::ostream& out, const noisemon::cycle_report_t& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%lld,%lld,%.3f,%.3f,%.3f,%d,%.4f,%.4f,%.4f,%.4f,%d\n", static_cast<long long>(r.cycle),
                static_cast<long long>(r.utime), r.speed_rpm, r.load_nm, r.soi_deg_btdc, r.motored ? 1 : 0,
                r.lpa_measured_db, r.lpa_predicted_db, r.lwa_measured_db, r.lwa_predicted_db, r.flags);
  out << buf;
  out.flush();
}

void print_bands(const noisemon::cycle_report_t& r) {
  std::printf("      band Hz   CPL dB   meas dB(A)  pred dB(A)  att meas  att pred  flags\n");
  for (int b = 0; b < r.nbands; ++b)
    std::printf("    %9.1f %8.1f %12.1f %11.1f %9.1f %9.1f  %d\n", r.band_hz[b], r.cpl_db[b], r.spl_a_measured_db[b],
                r.spl_a_predicted_db[b], r.att_measured_db[b], r.att_predicted_db[b], r.band_flags[b]);
}

}  // namespace

int run_watch(const WatchOptions& o) {
  lcm::LCM lcm(o.lcm_url);
  if (!lcm.good()) {
    std::fprintf(stderr, "noisemon watch: cannot open LCM at '%s': the network needs a multicast route (see README)\n",
                 o.lcm_url.empty() ? "default URL" : o.lcm_url.c_str());
    return 1;
  }
  std::ofstream csv;
  if (!o.csv_path.empty()) {
    csv.open(o.csv_path);
    if (!csv) {
      std::fprintf(stderr, "noisemon watch: cannot write %s\n", o.csv_path.c_str());
      return 1;
    }
    write_csv_header(csv);
  }
  std::int64_t received = 0;
  auto last = std::chrono::steady_clock::now();
  struct Handler {
    std::function<void(const noisemon::cycle_report_t*)> fn;
    void on(const lcm::ReceiveBuffer*, const std::string&, const noisemon::cycle_report_t* r) { fn(r); }
  } handler;
  handler.fn = [&](const noisemon::cycle_report_t* r) {
    if (o.count > 0 && received >= o.count) return;
    if (received % 40 == 0) std::printf("%s\n", cycle_line_header().c_str());
    std::printf("%s\n", cycle_line(*r).c_str());
    if (o.bands) print_bands(*r);
    std::fflush(stdout);
    if (csv.is_open()) write_csv_row(csv, *r);
    ++received;
    last = std::chrono::steady_clock::now();
  };
  lcm.subscribe(o.channel, &Handler::on, &handler);

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  while (!g_stop && (o.count == 0 || received < o.count)) {
    pollfd pfd{lcm.getFileno(), POLLIN, 0};
    const int ready = ::poll(&pfd, 1, 100);
    if (ready > 0) lcm.handle();
    if (o.timeout_s > 0 && std::chrono::duration<double>(std::chrono::steady_clock::now() - last).count() > o.timeout_s) {
      std::fprintf(stderr, "noisemon watch: no report on %s for %.1f s\n", o.channel.c_str(), o.timeout_s);
      return 2;
    }
  }
  return 0;
}

}  // namespace noisemon::daemon
