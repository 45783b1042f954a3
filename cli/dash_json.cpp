#include "cli/dash_json.hpp"

#include <cmath>
#include <limits>

#include "daemon/report_messages.hpp"

namespace noisemon::cli {

nlohmann::json cycle_json(const noisemon::cycle_report_t& r) {
  return {
      {"cycle", r.cycle},
      {"utime", r.utime},
      {"duration_s", r.duration_s},
      {"speed_rpm", r.speed_rpm},
      {"load_nm", r.load_nm},
      {"soi_deg_btdc", r.soi_deg_btdc},
      {"rail_pressure_bar", r.rail_pressure_bar},
      {"motored", r.motored},
      {"lpa_measured_db", r.lpa_measured_db},
      {"lpa_predicted_db", r.lpa_predicted_db},
      {"lwa_measured_db", r.lwa_measured_db},
      {"lwa_predicted_db", r.lwa_predicted_db},
      {"radius_m", r.radius_m},
      {"band_hz", r.band_hz},
      {"spl_a_measured_db", r.spl_a_measured_db},
      {"spl_a_predicted_db", r.spl_a_predicted_db},
      {"cpl_db", r.cpl_db},
      {"att_measured_db", r.att_measured_db},
      {"att_predicted_db", r.att_predicted_db},
      {"band_flags", r.band_flags},
      {"mic_lpa_db", r.mic_lpa_db},
      {"mic_flags", r.mic_flags},
      {"flags", r.flags},
      {"processing_ms", r.processing_ms},
      {"peak_pressure_bar", r.peak_pressure_bar},
      {"imep_net_bar", r.imep_net_bar},
      {"ca50_deg", r.ca50_deg},
  };
}

nlohmann::json trend_point_json(const noisemon::cycle_report_t& r, std::int64_t dropped, bool restarted) {
  nlohmann::json gap = nlohmann::json::array();
  for (int b = 0; b < r.nbands; ++b) {
    const double g = daemon::band_says_nothing(r.band_flags[b])
                         ? std::numeric_limits<double>::quiet_NaN()
                         : static_cast<double>(r.spl_a_measured_db[b]) - r.spl_a_predicted_db[b];
    gap.push_back(std::isfinite(g) ? nlohmann::json(std::round(g * 10.0) / 10.0) : nlohmann::json(nullptr));
  }
  return {{"t", static_cast<double>(r.utime) * 1e-6},
          {"cycle", r.cycle},
          {"gap", std::move(gap)},
          {"lpa_m", r.lpa_measured_db},
          {"lpa_p", r.lpa_predicted_db},
          {"lwa_m", r.lwa_measured_db},
          {"lwa_p", r.lwa_predicted_db},
          {"speed", r.speed_rpm},
          {"load", r.load_nm},
          {"soi", r.soi_deg_btdc},
          {"flags", r.flags},
          {"dropped", dropped},
          {"restarted", restarted}};
}

nlohmann::json status_json(const noisemon::status_t& s) {
  nlohmann::json threads = nlohmann::json::array(), rings = nlohmann::json::array(), counters = nlohmann::json::array();
  for (int i = 0; i < s.nthreads; ++i)
    threads.push_back({{"name", s.thread_name[i]}, {"state", s.thread_state[i]}, {"error", s.thread_error[i]}});
  for (int i = 0; i < s.nrings; ++i)
    rings.push_back({{"name", s.ring_name[i]}, {"fill", s.ring_fill[i]}, {"overruns", s.ring_overruns[i]}});
  for (int i = 0; i < s.ncounters; ++i)
    counters.push_back({{"name", s.counter_name[i]}, {"value", s.counter_value[i]}});
  return {{"utime", s.utime},
          {"uptime_s", s.uptime_s},
          {"source", s.source},
          {"threads", threads},
          {"rings", rings},
          {"cycles_published", s.cycles_published},
          {"cycles_dropped", s.cycles_dropped},
          {"latency_ms_mean", s.latency_ms_mean},
          {"latency_ms_max", s.latency_ms_max},
          {"processing_ms_mean", s.processing_ms_mean},
          {"processing_ms_max", s.processing_ms_max},
          {"report_latency_ms_p50", s.report_latency_ms_p50},
          {"report_latency_ms_p99", s.report_latency_ms_p99},
          {"report_latency_ms_max", s.report_latency_ms_max},
          {"counters", counters},
          {"record_file", s.record_file}};
}

nlohmann::json operating_point_json(const noisemon::operating_point_t& op) {
  return {{"utime", op.utime},
          {"speed_rpm", op.speed_rpm},
          {"load_nm", op.load_nm},
          {"soi_deg_btdc", op.soi_deg_btdc},
          {"rail_pressure_bar", op.rail_pressure_bar},
          {"motored", op.motored}};
}

nlohmann::json gap_event_json(const noisemon::gap_event_t& e) {
  nlohmann::json params = nlohmann::json::object();
  for (int i = 0; i < e.nparams; ++i) params[e.param_names[i]] = e.param_values[i];
  nlohmann::json candidates = nlohmann::json::array();
  for (int i = 0; i < e.ncandidates; ++i)
    candidates.push_back({{"effect", e.candidates[i]}, {"weight", e.candidate_weights[i]}});
  auto floats = [](const std::vector<float>& v) {
    nlohmann::json a = nlohmann::json::array();
    for (const float x : v) a.push_back(std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr));
    return a;
  };
  return {{"utime", e.utime},
          {"effect", e.effect},
          {"params", params},
          {"confidence", e.confidence},
          {"kind", e.kind},
          {"onset_s", e.onset_s},
          {"detected_s", e.detected_s},
          {"onset_cycle", e.onset_cycle},
          {"detected_cycle", e.detected_cycle},
          {"gap_before_db", e.gap_before_db},
          {"gap_after_db", e.gap_after_db},
          {"features", e.features},
          {"explanation", e.explanation},
          {"band_hz", floats(e.band_hz)},
          {"gap_change_db", floats(e.gap_change_db)},
          {"mic_change_db", floats(e.mic_change_db)},
          {"candidates", candidates}};
}

nlohmann::json gap_status_json(const noisemon::gap_status_t& s) {
  return {{"utime", s.utime},
          {"cycles", s.cycles},
          {"events", s.events},
          {"operating_points", s.operating_points},
          {"learning", s.learning},
          {"reference_s", s.reference_s},
          {"since_reference_s", s.since_reference_s},
          {"watched_features", s.watched_features}};
}

nlohmann::json check_json(const noisemon::check_t& c) {
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < c.nrows; ++i)
    rows.push_back(
        {{"item", c.item[i]}, {"value", c.value[i]}, {"verdict", c.verdict[i]}, {"failed", c.failed[i] != 0}});
  return {{"utime", c.utime},       {"source", c.source},   {"seconds", c.seconds},
          {"problems", c.problems}, {"summary", c.summary}, {"rows", rows}};
}

}  // namespace noisemon::cli
