#include "cli/dash_metrics.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "daemon/report_messages.hpp"

namespace noisemon::cli {
namespace {

// Writes one metric family: its HELP and TYPE lines once, then samples.
class Family {
 public:
  Family(std::ostringstream& out, const std::string& cell, const char* name, const char* type, const char* help)
      : out_(out), cell_(cell), name_(name) {
    out_ << "# HELP " << name << ' ' << help << '\n' << "# TYPE " << name << ' ' << type << '\n';
  }
  // `extra`: a further label as name="value" (value escaped here), or empty.
  void sample(double value, const char* label = nullptr, const std::string& label_value = "") {
    out_ << name_ << "{cell=\"" << prometheus_label_value(cell_) << '"';
    if (label) out_ << ',' << label << "=\"" << prometheus_label_value(label_value) << '"';
    out_ << "} " << format(value) << '\n';
  }

 private:
  static std::string format(double v) {
    if (std::isnan(v)) return "NaN";
    if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
  }
  std::ostringstream& out_;
  const std::string& cell_;
  const char* name_;
};

void status_metrics(std::ostringstream& out, const std::string& cell, const noisemon::status_t& s, double age_s) {
  Family(out, cell, "noisemon_cycles_published_total", "counter",
         "Cycle reports the daemon published since it started.")
      .sample(static_cast<double>(s.cycles_published));
  Family(out, cell, "noisemon_cycles_dropped_total", "counter", "Cycles the daemon did not publish (gaps, overruns).")
      .sample(static_cast<double>(s.cycles_dropped));
  Family(out, cell, "noisemon_uptime_seconds", "gauge", "Seconds since the daemon started.").sample(s.uptime_s);
  Family(out, cell, "noisemon_status_age_seconds", "gauge", "Seconds since the dash received the last status message.")
      .sample(age_s);
  Family fill(out, cell, "noisemon_ring_fill_ratio", "gauge", "Fill of each ring buffer, 0 to 1.");
  for (int i = 0; i < s.nrings; ++i) fill.sample(s.ring_fill[i], "ring", s.ring_name[i]);
  Family overruns(out, cell, "noisemon_ring_overruns_total", "counter", "Blocks dropped because the ring was full.");
  for (int i = 0; i < s.nrings; ++i) overruns.sample(static_cast<double>(s.ring_overruns[i]), "ring", s.ring_name[i]);
  Family state(out, cell, "noisemon_thread_state", "gauge", "Thread state: 0 idle, 1 running, 2 stopped, 3 failed.");
  for (int i = 0; i < s.nthreads; ++i) state.sample(s.thread_state[i], "thread", s.thread_name[i]);
  Family(out, cell, "noisemon_latency_mean_seconds", "gauge",
         "End of a cycle's acoustic window to its report, mean over the last second.")
      .sample(s.latency_ms_mean * 1e-3);
  Family(out, cell, "noisemon_latency_max_seconds", "gauge",
         "End of a cycle's acoustic window to its report, maximum over the last second.")
      .sample(s.latency_ms_max * 1e-3);
  Family report_latency(out, cell, "noisemon_report_latency_seconds", "gauge",
                        "A cycle's last sample reaching the processing thread to its report leaving, over the last "
                        "second: quantile 0.5, 0.99 and 1 (the maximum).");
  report_latency.sample(s.report_latency_ms_p50 * 1e-3, "quantile", "0.5");
  report_latency.sample(s.report_latency_ms_p99 * 1e-3, "quantile", "0.99");
  report_latency.sample(s.report_latency_ms_max * 1e-3, "quantile", "1");
  Family(out, cell, "noisemon_processing_mean_seconds", "gauge",
         "Processing thread CPU time per cycle, mean over the last second.")
      .sample(s.processing_ms_mean * 1e-3);
  Family(out, cell, "noisemon_processing_max_seconds", "gauge",
         "Processing thread CPU time per cycle, maximum over the last second.")
      .sample(s.processing_ms_max * 1e-3);
  Family counters(out, cell, "noisemon_driver_counter_total", "counter",
                  "The source's driver counters, cumulative since start.");
  for (int i = 0; i < s.ncounters; ++i)
    if (!s.counter_is_gauge[i]) counters.sample(static_cast<double>(s.counter_value[i]), "counter", s.counter_name[i]);
  Family gauges(out, cell, "noisemon_driver_gauge", "gauge",
                "The source's states that may go down: a clock's drift (ppb), an alignment's uncertainty (us), a "
                "microphone's calibration age (days), ...");
  for (int i = 0; i < s.ncounters; ++i)
    if (s.counter_is_gauge[i]) gauges.sample(static_cast<double>(s.counter_value[i]), "gauge", s.counter_name[i]);
}

void cycle_metrics(std::ostringstream& out, const std::string& cell, const noisemon::cycle_report_t& r) {
  Family(out, cell, "noisemon_last_cycle", "gauge", "Index of the last cycle report received.")
      .sample(static_cast<double>(r.cycle));
  Family(out, cell, "noisemon_lpa_measured_db", "gauge",
         "Last cycle's measured Lp(A), dB(A) re 20 uPa (NaN: not measured).")
      .sample(r.lpa_measured_db);
  Family(out, cell, "noisemon_lpa_predicted_db", "gauge",
         "Last cycle's predicted Lp(A), dB(A) re 20 uPa (NaN: not predicted).")
      .sample(r.lpa_predicted_db);
  Family(out, cell, "noisemon_last_cycle_flags", "gauge", "Last cycle's CYCLE_* flag bits (0: fully valid).")
      .sample(r.flags);
}

// The gap measured - predicted of the last cycle, energy over the bands of a group (below 500 Hz, 500 Hz ... 2 kHz,
// above 2 kHz) that both carry and whose flags leave them a gap (report_messages.hpp); NaN when none does.
double band_group_gap_db(const noisemon::cycle_report_t& r, double from_hz, double to_hz) {
  double measured = 0, predicted = 0;
  for (int b = 0; b < r.nbands; ++b)
    if (r.band_hz[b] >= from_hz && r.band_hz[b] < to_hz && !daemon::band_says_nothing(r.band_flags[b]) &&
        std::isfinite(r.spl_a_measured_db[b]) && std::isfinite(r.spl_a_predicted_db[b])) {
      measured += std::pow(10.0, r.spl_a_measured_db[b] / 10.0);
      predicted += std::pow(10.0, r.spl_a_predicted_db[b] / 10.0);
    }
  return predicted > 0 ? 10.0 * std::log10(measured / predicted) : std::nan("");
}

void gap_metrics(std::ostringstream& out, const MetricsInput& in) {
  if (!in.gap_events_by_effect.empty()) {
    Family events(out, in.cell, "noisemon_gap_events_total", "counter",
                  "noisemon gapwatch's events since the dash started, by the effect named.");
    for (const auto& [effect, count] : in.gap_events_by_effect)
      events.sample(static_cast<double>(count), "effect", effect);
  }
  if (in.cycle && in.cycle->nbands > 0) {
    Family groups(out, in.cell, "noisemon_gap_band_group_db", "gauge",
                  "Last cycle's gap measured - predicted over a band group, dB.");
    groups.sample(band_group_gap_db(*in.cycle, 0.0, 500.0), "group", "below_500hz");
    groups.sample(band_group_gap_db(*in.cycle, 500.0, 2000.0), "group", "500hz_2khz");
    groups.sample(band_group_gap_db(*in.cycle, 2000.0, 1e9), "group", "above_2khz");
  }
  if (in.gap_status) {
    Family(out, in.cell, "noisemon_gap_seconds_since_reference", "gauge",
           "Engine seconds since gapwatch's reference of the current operating point was complete (0: learning).")
        .sample(in.gap_status->since_reference_s);
    Family(out, in.cell, "noisemon_gap_learning", "gauge",
           "1 while gapwatch learns the current operating point's reference.")
        .sample(in.gap_status->learning ? 1.0 : 0.0);
  }
}

// The pre-test check's verdicts: 1 per failed row, by its item, and when it ran.
void check_metrics(std::ostringstream& out, const std::string& cell, const noisemon::check_t& c) {
  Family(out, cell, "noisemon_check_problems", "gauge", "Rows noisemon check failed, its last published run.")
      .sample(c.problems);
  Family(out, cell, "noisemon_check_time_seconds", "gauge", "When that check ended, seconds since the epoch.")
      .sample(1e-6 * static_cast<double>(c.utime));
  Family failed(out, cell, "noisemon_check_failed", "gauge", "1 where a row of that check failed, by its item.");
  for (int i = 0; i < c.nrows; ++i) failed.sample(c.failed[i] ? 1.0 : 0.0, "item", c.item[i]);
}

}  // namespace

std::string prometheus_label_value(const std::string& value) {
  std::string out;
  for (const char c : value) {
    if (c == '\\')
      out += "\\\\";
    else if (c == '"')
      out += "\\\"";
    else if (c == '\n')
      out += "\\n";
    else
      out += c;
  }
  return out;
}

std::string prometheus_text(const MetricsInput& in) {
  std::ostringstream out;
  Family(out, in.cell, "noisemon_dash_cycles_received_total", "counter",
         "Cycle reports the dash received since it started.")
      .sample(static_cast<double>(in.cycles_received));
  if (in.status) status_metrics(out, in.cell, *in.status, in.status_age_s);
  if (in.cycle) cycle_metrics(out, in.cell, *in.cycle);
  gap_metrics(out, in);
  if (in.check) check_metrics(out, in.cell, *in.check);
  return out.str();
}

}  // namespace noisemon::cli
