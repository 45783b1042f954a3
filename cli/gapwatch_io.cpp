#include "cli/gapwatch_io.hpp"

#include <cmath>
#include <fstream>
#include <stdexcept>

#include "daemon/report_messages.hpp"

namespace noisemon::cli {

namespace {

using Report = noisemon::cycle_report_t;

constexpr int kFaultFlags = int{Report::CYCLE_SETTLING} | int{Report::CYCLE_GAP} | int{Report::CYCLE_LENGTH_ODD} |
                            int{Report::CYCLE_NO_MICS} | int{Report::CYCLE_ENCODER} | int{Report::CYCLE_OVERLOAD} |
                            int{Report::CYCLE_PRESSURE_FAULT} | int{Report::CYCLE_ANGLE_GAP};
constexpr int kBadMic = int{Report::MIC_FLAT} | int{Report::MIC_OVERLOAD} | int{Report::MIC_NAN} | int{Report::MIC_LOW};

nlohmann::json number(double x) { return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr); }

std::vector<double> numbers(const nlohmann::json& j) {
  std::vector<double> out;
  for (const auto& v : j) out.push_back(v.is_null() ? model::diagnosis::kNoValue : v.get<double>());
  return out;
}

nlohmann::json array(const std::vector<double>& values) {
  nlohmann::json a = nlohmann::json::array();
  for (const double v : values) a.push_back(number(v));
  return a;
}

}  // namespace

model::diagnosis::CycleGap cycle_gap(const Report& r) {
  model::diagnosis::CycleGap c;
  c.cycle = r.cycle;
  c.time_s = static_cast<double>(r.utime) * 1e-6;
  c.speed_rpm = r.speed_rpm;
  c.load_nm = r.load_nm;
  c.soi_deg_btdc = r.soi_deg_btdc;
  c.motored = r.motored;
  c.usable = (r.flags & kFaultFlags) == 0;
  for (int b = 0; b < r.nbands; ++b) {
    const bool silent = daemon::band_says_nothing(r.band_flags[b]);
    c.band_hz.push_back(r.band_hz[b]);
    c.measured_db.push_back(silent ? model::diagnosis::kNoValue : r.spl_a_measured_db[b]);
    c.predicted_db.push_back(silent ? model::diagnosis::kNoValue : r.spl_a_predicted_db[b]);
    c.cpl_db.push_back(silent ? model::diagnosis::kNoValue : r.cpl_db[b]);
  }
  for (int m = 0; m < r.nmics; ++m)
    c.mic_db.push_back((r.mic_flags[m] & kBadMic) ? model::diagnosis::kNoValue : r.mic_lpa_db[m]);
  c.overall_measured_db = r.lpa_measured_db;
  c.overall_predicted_db = r.lpa_predicted_db;
  c.window_measured_db.assign(r.window_lpa_measured_db.begin(), r.window_lpa_measured_db.end());
  c.window_predicted_db.assign(r.window_lpa_predicted_db.begin(), r.window_lpa_predicted_db.end());
  return c;
}

noisemon::gap_event_t gap_event_message(const model::diagnosis::GapEvent& e, std::int64_t utime) {
  noisemon::gap_event_t m;
  m.utime = utime;
  m.effect = e.effect;
  for (const auto& [key, value] : e.params) {
    m.param_names.push_back(key);
    m.param_values.push_back(value);
  }
  m.nparams = static_cast<std::int16_t>(m.param_names.size());
  m.confidence = e.confidence;
  m.explained = e.attribution.explained;
  m.kind = e.kind;
  m.drift_db_per_min = e.drift_db_per_min;
  m.onset_cycle = e.onset_cycle;
  m.detected_cycle = e.detected_cycle;
  m.onset_s = e.onset_s;
  m.detected_s = e.detected_s;
  m.gap_before_db = e.gap_before_db;
  m.gap_after_db = e.gap_after_db;
  m.speed_rpm = e.speed_rpm;
  m.load_nm = e.load_nm;
  m.soi_deg_btdc = e.soi_deg_btdc;
  m.motored = e.motored;
  m.features = e.features;
  m.nfeatures = static_cast<std::int16_t>(m.features.size());
  m.explanation = e.attribution.explanation;
  const model::diagnosis::GapChange& g = e.change;
  for (std::size_t b = 0; b < g.band_hz.size(); ++b) {
    m.band_hz.push_back(static_cast<float>(g.band_hz[b]));
    const double gap = (g.measured_after[b] - g.predicted_after[b]) - (g.measured_before[b] - g.predicted_before[b]);
    m.gap_change_db.push_back(g.band_used[b] ? static_cast<float>(gap) : NAN);
    m.cpl_change_db.push_back(static_cast<float>(g.cpl_after[b] - g.cpl_before[b]));
  }
  m.nbands = static_cast<std::int16_t>(m.band_hz.size());
  for (std::size_t i = 0; i < g.mic_before.size(); ++i)
    m.mic_change_db.push_back(static_cast<float>(g.mic_after[i] - g.mic_before[i]));
  m.nmics = static_cast<std::int16_t>(m.mic_change_db.size());
  for (const auto& c : e.attribution.candidates) {
    m.candidates.push_back(c.effect);
    m.candidate_weights.push_back(static_cast<float>(c.weight));
  }
  m.ncandidates = static_cast<std::int16_t>(m.candidates.size());
  return m;
}

noisemon::gap_status_t gap_status_message(const model::diagnosis::GapWatch& watch, std::int64_t utime,
                                          std::int32_t events) {
  noisemon::gap_status_t m;
  m.utime = utime;
  m.cycles = watch.cycles();
  m.events = events;
  m.operating_points = static_cast<std::int32_t>(watch.reference().points.size());
  m.learning = watch.learning();
  m.reference_s = watch.reference_seconds();
  m.since_reference_s = watch.since_reference_seconds();
  m.watched_features = static_cast<std::int32_t>(watch.watched_features());
  return m;
}

nlohmann::json gap_event_json(const model::diagnosis::GapEvent& e) {
  nlohmann::json params = nlohmann::json::object();
  for (const auto& [key, value] : e.params) params[key] = number(value);
  nlohmann::json candidates = nlohmann::json::array();
  for (const auto& c : e.attribution.candidates) {
    nlohmann::json p = nlohmann::json::object();
    for (const auto& [key, value] : c.params) p[key] = number(value);
    candidates.push_back(
        {{"effect", c.effect}, {"weight", c.weight}, {"chi2", c.chi2}, {"parameters", c.parameters}, {"params", p}});
  }
  return {{"effect", e.effect},
          {"params", params},
          {"kind", e.kind},
          {"drift_db_per_min", number(e.drift_db_per_min)},
          {"onset_s", e.onset_s},
          {"detected_s", e.detected_s},
          {"onset_cycle", e.onset_cycle},
          {"detected_cycle", e.detected_cycle},
          {"gap_before_db", number(e.gap_before_db)},
          {"gap_after_db", number(e.gap_after_db)},
          {"confidence", e.confidence},
          {"explained", e.attribution.explained},
          {"features", e.features},
          {"speed_rpm", e.speed_rpm},
          {"load_nm", e.load_nm},
          {"soi_deg_btdc", e.soi_deg_btdc},
          {"motored", e.motored},
          {"explanation", e.attribution.explanation},
          {"candidates", candidates}};
}

nlohmann::json reference_json(const model::diagnosis::GapReference& r) {
  nlohmann::json points = nlohmann::json::array();
  for (const auto& p : r.points) {
    if (p.features.empty()) continue;  // still learning
    nlohmann::json features = nlohmann::json::array();
    for (const auto& f : p.features)
      features.push_back({{"mean", number(f.mean)}, {"sigma", number(f.sigma)}, {"blocks", f.blocks}});
    points.push_back({{"speed_rpm", p.speed_rpm},
                      {"load_nm", p.load_nm},
                      {"soi_deg_btdc", p.soi_deg_btdc},
                      {"motored", p.motored},
                      {"cycles", p.cycles},
                      {"features", features},
                      {"measured_db", array(p.measured_db)},
                      {"predicted_db", array(p.predicted_db)},
                      {"cpl_db", array(p.cpl_db)},
                      {"mic_db", array(p.mic_db)},
                      {"window_db", array(p.window_db)}});
  }
  return {{"format", "noisemon gapwatch reference 1"},
          {"band_hz", r.band_hz},
          {"mics", r.mics},
          {"windows", r.windows},
          {"points", points}};
}

model::diagnosis::GapReference load_reference(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open the reference file");
  model::diagnosis::GapReference r;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    if (j.value("format", "") != "noisemon gapwatch reference 1")
      throw std::runtime_error("\"format\" is not \"noisemon gapwatch reference 1\"");
    r.band_hz = j.at("band_hz").get<std::vector<double>>();
    r.mics = j.at("mics").get<std::size_t>();
    r.windows = j.at("windows").get<std::size_t>();
    for (const auto& p : j.at("points")) {
      model::diagnosis::OperatingPointReference o;
      o.speed_rpm = p.at("speed_rpm").get<double>();
      o.load_nm = p.at("load_nm").get<double>();
      o.soi_deg_btdc = p.at("soi_deg_btdc").get<double>();
      o.motored = p.at("motored").get<bool>();
      o.cycles = p.at("cycles").get<std::size_t>();
      for (const auto& f : p.at("features"))
        o.features.push_back({f.at("mean").is_null() ? model::diagnosis::kNoValue : f.at("mean").get<double>(),
                              f.at("sigma").is_null() ? model::diagnosis::kNoValue : f.at("sigma").get<double>(),
                              f.at("blocks").get<std::size_t>()});
      o.measured_db = numbers(p.at("measured_db"));
      o.predicted_db = numbers(p.at("predicted_db"));
      o.cpl_db = numbers(p.at("cpl_db"));
      o.mic_db = numbers(p.at("mic_db"));
      o.window_db = numbers(p.at("window_db"));
      if (o.features.size() != r.band_hz.size() + r.mics + 1 + r.windows || o.measured_db.size() != r.band_hz.size() ||
          o.mic_db.size() != r.mics || o.window_db.size() != r.windows)
        throw std::runtime_error("an operating point's arrays do not match band_hz, mics and windows");
      r.points.push_back(std::move(o));
    }
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(path + ": not a gapwatch reference: " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  return r;
}

}  // namespace noisemon::cli
