#include "cli/report/diagnosis_report.hpp"

#include <cmath>

#include "model/fit/pressure_floor.hpp"

namespace noisemon::cli::report {

using nlohmann::json;

namespace {

// NaN and infinities -> null (JSON has neither).
json number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json numbers(const std::vector<double>& v) {
  json a = json::array();
  for (double x : v) a.push_back(number(x));
  return a;
}

json rows(const std::vector<std::vector<double>>& v) {
  json a = json::array();
  for (const auto& r : v) a.push_back(numbers(r));
  return a;
}

json flags(const std::vector<std::vector<char>>& v) {
  json a = json::array();
  for (const auto& r : v) {
    json row = json::array();
    for (char c : r) row.push_back(c != 0);
    a.push_back(row);
  }
  return a;
}

// Every fitted quantity of a model: the block, then the extensions that are on (units in the names).
json model_params(const model::fit::ExtendedModel& m) {
  json p = json::object();
  p["k1_n_per_m"] = m.block.k1;
  p["b1_n_s_per_m"] = m.block.b1;
  p["k3_n_per_m3"] = m.block.k3;
  p["b3_n_s3_per_m3"] = m.block.b3;
  p["c0"] = m.block.c0;
  p["c1"] = m.block.c1;
  const model::fit::ExtensionParams& e = m.ext;
  if (m.on.second_mode) {
    p["mode_db"] = e.mode_db;
    p["mode_hz"] = e.mode_hz;
    p["mode_q"] = e.mode_q;
    p["mode_phase_deg"] = e.mode_phase_deg;
    p["mode_rise_db"] = model::fit::mode_rise_db(e);  // the level change at mode_hz the mode makes
  }
  if (m.on.speed) {
    p["speed_gain_db_per_krpm"] = e.speed_gain_db_per_krpm;
    p["speed_shift_per_krpm"] = e.speed_shift_per_krpm;
    p["speed_ref_rpm"] = e.speed_ref_rpm;
  }
  if (m.on.transducer) {
    p["transducer_density_pa2_per_hz_at_1khz"] = e.transducer_density;
    p["transducer_slope"] = e.transducer_slope;
    p["transducer_noise_pa_per_rthz_at_1khz"] = std::sqrt(std::max(0.0, e.transducer_density));
  }
  if (m.on.stationary) {
    json db = json::array();
    for (double ms : e.stationary_ms) db.push_back(ms > 0 ? number(10.0 * std::log10(ms / 4e-10)) : json(nullptr));
    p["background_band_db"] = db;
  }
  if (m.on.locked) {
    json db = json::array();
    for (double ms : e.locked_ms) db.push_back(ms > 0 ? number(10.0 * std::log10(ms / 4e-10)) : json(nullptr));
    p["locked_band_window_db"] = db;  // [band * kCrankWindows + window]
    p["locked_speed_exponent"] = e.locked_speed_exp;
  }
  if (m.on.mic_gain) p["mic_gain_db"] = numbers(e.mic_gain_db);
  return p;
}

json score_json(const model::diagnosis::ModelScore& s) {
  json c;
  c["effect"] = s.name;
  c["effects"] = s.effects;
  c["heldout_rms_db"] = number(s.heldout_gap_db);
  c["heldout_thesis_rms_db"] = number(s.heldout_thesis_rms_db);
  c["train_rms_db"] = number(s.train_rms_db);
  c["gap_closed_fraction"] = number(s.gap_closed_fraction);
  // significant: alone against the baseline, or as the verdict's second effect on top of the first.
  c["significant"] = s.significant || s.significant_on_top;
  c["significant_alone"] = s.significant;
  c["significant_on_top_of_verdict"] = s.significant_on_top;
  c["improvement_db"] = number(s.improvement_db);
  c["improvement_p05_db"] = number(s.improvement_p05_db);
  c["win_fraction"] = number(s.win_fraction);
  c["parameters"] = s.parameters;
  // Parsimony: n ln(gap^2) + parameters ln(n) over the n held-out cells; a candidate must come below the baseline's.
  c["information_criterion"] = {{"value", number(s.information_criterion)},
                                {"heldout_cells", s.heldout_cells},
                                {"pays_for_parameters", s.pays_for_parameters}};
  c["gap_parts"] = {{"band_ms_db2", number(s.part_band_ms)},
                    {"mic_rss_db", number(s.part_mic)},
                    {"window_ms_db2", number(s.part_window_ms)}};
  // Which part of the baseline's gap it closes (dB of each part; negative: it makes that part worse).
  c["closes_db"] = {{"thesis_bands", number(s.closes_band_db)},
                    {"mic_calibration", number(s.closes_mic_db)},
                    {"crank_windows", number(s.closes_window_db)}};
  c["thesis_metric_worse"] = s.thesis_worse;
  // Leave-one-group-out by operating speed (null without groups), and whether it is worse there than the baseline.
  c["heldout_group_rms_db"] = number(s.heldout_group_gap_db);
  c["group_worse"] = s.group_worse;
  if (s.motored_law_checked) {
    // An additive source claimed louder than all the motored runs hear (beyond 3 standard errors): refuted.
    c["motored_law"] = {
        {"refuted", s.refuted}, {"overshoot_db", number(s.motored_overshoot_db)}, {"where", s.motored_overshoot_where}};
  }
  if (s.pressure_law_checked) {
    // A pressure-driven fit that predicts the motored runs worse than the baseline (beyond 3 standard errors): refuted.
    c["pressure_law"] = {
        {"refuted", s.refuted}, {"motored_worse_db", number(s.motored_worse_db)}, {"where", s.motored_worse_where}};
  }
  c["params"] = model_params(s.model);
  return c;
}

// The model the verdict selected (a combination or a candidate), else the best candidate: what the report's
// "best candidate" curves show.
const model::diagnosis::ModelScore* best_model(const model::diagnosis::DiagnosisResult& r) {
  const std::string& v = r.verdict.effect;
  if (!r.verdict.also.empty()) {
    for (const auto& c : r.combinations)
      if (c.effects.size() == 2 && c.effects[0] == v && c.effects[1] == r.verdict.also.front()) return &c;
  }
  for (const auto& c : r.candidates)
    if (c.name == v) return &c;
  return r.candidates.empty() ? nullptr : &r.candidates.front();
}

// What both reports start with: the tool, the mode, the units, the command, the data and the metric.
json report_head(const char* mode, const std::string& units, const ReportContext& ctx, const std::string& metric) {
  json j;
  j["tool"] = "noisemon diagnose";
  j["mode"] = mode;
  j["units"] = units;
  j["command"] = ctx.command;
  j["data"] = ctx.data;
  j["metric"] = metric;
  return j;
}

std::vector<std::string> condition_names(const model::fit::BandDataset& data, const std::vector<std::size_t>& which) {
  std::vector<std::string> names;
  for (std::size_t k : which) names.push_back(data.conditions[k].info.name);
  return names;
}

json band_protocol(const model::fit::BandDataset& data, const model::diagnosis::DiagnosisResult& r,
                   const model::diagnosis::DiagnosisOptions& o) {
  return {{"train", condition_names(data, r.train)},
          {"heldout", condition_names(data, r.heldout)},
          {"reference", condition_names(data, r.reference)},
          {"leave_one_condition_out", r.leave_one_out},
          {"bootstrap_replicates", o.bootstrap},
          {"seed", o.seed},
          {"tolerance_db", o.tolerance_db},
          {"min_closed_fraction", o.min_closed_fraction},
          {"floor_margin_db", o.floor_margin_db},
          {"pressure_floor_margin_db", model::fit::kFloorMarginDb},
          {"fit_cycles", o.fit_cycles}};
}

json band_conditions(const model::fit::BandDataset& data, const model::diagnosis::Where& w) {
  json conds = json::array();
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    const model::fit::ConditionData& d = data.conditions[k];
    conds.push_back({{"name", d.info.name},
                     {"role", k < w.roles.size() ? w.roles[k] : ""},
                     {"speed_rpm", number(d.mean_speed_rpm())},
                     {"load_nm", number(d.info.load_nm)},
                     {"soi_deg_btdc", number(d.info.soi_deg_btdc)},
                     {"motored", d.info.motored},
                     {"background", d.info.background},
                     {"cycles", d.cycle_count()},
                     {"mics", d.mics}});
  }
  return conds;
}

json band_floors(const model::diagnosis::Where& w) {
  return {{"pressure_judged_by", w.pressure_floor_judged_by},
          {"pressure_stated_bar", numbers(w.pressure_floor_stated_bar)},
          {"pressure_estimated_bar", numbers(w.pressure_floor_estimated_bar)},
          {"pressure_estimated_grid_bar", numbers(w.pressure_floor_estimated_grid_bar)},
          {"pressure_floor_db", rows(w.pressure_floor_db)},
          {"floor_limited_bands", w.floor_limited_bands},
          {"floor_limited_windows", w.floor_limited_windows},
          {"mic_floor_db", numbers(w.mic_floor_db)},
          {"mic_floor_source", w.mic_floor_source},
          {"summary", w.floor_summary}};
}

// The per-band, per-condition, per-microphone and per-window figures of where the gap is.
json band_where(const model::fit::BandDataset& data, const model::diagnosis::DiagnosisResult& r) {
  const model::diagnosis::Where& w = r.where;
  json where;
  where["bands_hz"] = numbers(w.band_hz);
  where["band_notes"] = w.band_notes;
  where["conditions"] = band_conditions(data, w);
  where["scored"] = flags(w.scored);
  where["floor_limited"] = flags(w.floor_limited);
  where["heldout_conditions"] = condition_names(data, r.heldout);
  where["gap_db"] = rows(w.gap);  // baseline, per held-out condition and band: measured - predicted
  where["gap_per_band_rms_db"] = numbers(w.gap_per_band_rms);
  where["gap_per_condition_rms_db"] = numbers(w.gap_per_condition_rms);
  where["noise_dominated"] = flags(w.noise_dominated);
  where["noise_floor"] = {{"combustion_independent_db", numbers(w.floor_db)},
                          {"background_db", numbers(w.background_db)}};
  where["floors"] = band_floors(w);
  where["amplitude"] = {{"cpl_overall_db", numbers(w.cpl_overall_db)},
                        {"mean_gap_db", numbers(w.mean_gap_db)},
                        {"slope_db_per_db", number(w.amplitude_slope_db_per_db)},
                        {"cycle_slope_db_per_db", number(w.cycle_amplitude_slope_db_per_db)}};
  where["speed_slope_db_per_krpm"] = number(w.speed_slope_db_per_krpm);
  where["soi_slope_db_per_deg"] = number(w.soi_slope_db_per_deg);
  where["load_slope_db_per_nm"] = number(w.load_slope_db_per_nm);
  where["mics"] = w.mics;
  where["mic_offset_db"] = numbers(w.mic_offset_db);
  where["mic_gap_rms_db"] = numbers(w.mic_gap_rms_db);
  where["crank_windows"] = {{"start_deg", numbers(w.window_start_deg)},
                            {"gap_db", numbers(w.window_gap_db)},
                            {"gap_per_band_db", rows(w.window_band_gap_db)}};
  where["coherence"] = {{"coherent_fraction", numbers(w.coherent_fraction)},
                        {"periodic_share", numbers(w.periodic_share)},
                        {"fluctuation_coherence", numbers(w.fluct_coherence)}};
  where["cpl_db"] = rows(w.cpl_db);
  where["att_meas_db"] = rows(w.att_meas);
  where["att_baseline_db"] = rows(w.att_base);
  if (const model::diagnosis::ModelScore* best = best_model(r)) {
    where["att_best_db"] = rows(best->att_pred);
    where["best_model"] = best->name;
    where["mic_residual_best_db"] = rows(best->mic_resid);
  }
  where["mic_residual_baseline_db"] = rows(r.baseline.mic_resid);
  return where;
}

json scores_json(const std::vector<model::diagnosis::ModelScore>& scores) {
  json a = json::array();
  for (const auto& c : scores) a.push_back(score_json(c));
  return a;
}

// What the verdict leaves: the selected model's gap, where it lies and how it scales across held-out conditions.
json remaining_json(const model::diagnosis::RemainingGap& r) {
  return {{"model", r.model},
          {"heldout_gap_db", number(r.gap_db)},
          {"largest_part", r.part},
          {"largest_band_hz", number(r.largest_band_hz)},
          {"largest_band_db", number(r.largest_band_db)},
          {"band_range_hz", {number(r.from_hz), number(r.to_hz)}},
          {"mean_gap_db", numbers(r.mean_gap_db)},
          {"speed_slope_db_per_krpm", number(r.speed_slope_db_per_krpm)},
          {"load_slope_db_per_nm", number(r.load_slope_db_per_nm)},
          {"level_slope_db_per_db", number(r.level_slope_db_per_db)},
          {"summary", r.summary}};
}

json band_verdict(const model::diagnosis::Verdict& v) {
  return {{"effect", v.effect},
          {"also", v.also},
          {"heldout_rms_before_db", number(v.heldout_rms_before_db)},
          {"heldout_rms_after_db", number(v.heldout_rms_after_db)},
          {"heldout_thesis_rms_before_db", number(v.heldout_thesis_before_db)},
          {"heldout_thesis_rms_after_db", number(v.heldout_thesis_after_db)},
          {"gap_closed_fraction", number(v.gap_closed_fraction)},
          {"remaining_db", number(v.heldout_rms_after_db)},
          {"noise_db", number(v.noise_db)},
          {"band_before_db", numbers(v.band_before_db)},
          {"band_after_db", numbers(v.band_after_db)},
          {"explanation", v.explanation},
          {"below_tolerance", v.below_tolerance.empty() ? json(nullptr) : json(v.below_tolerance)},
          {"below_tolerance_after_db", v.below_tolerance.empty() ? json(nullptr) : number(v.below_tolerance_after_db)},
          {"remaining", remaining_json(v.remaining)}};
}

// ---- waveform mode ----

json named_params(const std::vector<std::pair<std::string, double>>& p) {
  json o = json::object();
  for (const auto& [k, v] : p) o[k] = number(v);
  return o;
}

json waveform_candidates(const model::diagnosis::WaveformReport& rep) {
  json cands = json::array();
  for (const auto& c : rep.candidates) {
    json x = {{"effect", c.effect},
              {"heldout_rms_db", number(c.heldout_rms)},
              {"gap_closed_fraction", number(c.gap_closed_fraction)},
              {"significant", c.significant},
              {"p_value", number(c.p_value)},
              {"second_round", c.second_round},
              {"params", named_params(c.params)}};
    if (!c.error.empty()) x["error"] = c.error;
    cands.push_back(x);
  }
  return cands;
}

json waveform_where(const model::diagnosis::WaveformDiagnosis& d, const model::diagnosis::WaveformReport& rep) {
  json where;
  std::vector<double> hz, before, after, out;
  for (const auto& b : rep.bands) {
    hz.push_back(b.f_center_hz);
    out.push_back(b.output_rms);
    before.push_back(b.error_rms_before);
    after.push_back(b.error_rms_after);
  }
  where["bands_hz"] = numbers(hz);
  where["output_rms"] = numbers(out);
  where["error_rms_before"] = numbers(before);
  where["error_rms_after"] = numbers(after);
  json amp = json::array();
  for (const auto& a : rep.amplitude)
    amp.push_back({{"level_lo", number(a.level_lo)},
                   {"level_hi", number(a.level_hi)},
                   {"samples", a.samples},
                   {"error_rms_before", number(a.error_rms_before)},
                   {"error_rms_after", number(a.error_rms_after)}});
  where["amplitude"] = amp;
  where["heldout_segment_rms_before"] = numbers(d.segment_rms_before);
  where["heldout_segment_rms_after"] = numbers(d.segment_rms_after);
  where["explainable_gap"] = {{"baseline_fraction", number(d.baseline_gap.fraction)},
                              {"baseline_p_value", number(d.baseline_gap.test.p_value)},
                              {"baseline_significant", d.baseline_gap.significant},
                              {"remaining_fraction", number(d.remaining_gap.fraction)},
                              {"remaining_p_value", number(d.remaining_gap.test.p_value)},
                              {"remaining_significant", d.remaining_gap.significant}};
  return where;
}

json test_sets_json(const std::vector<WaveformTestSet>& tests) {
  json ts = json::array();
  for (const auto& t : tests)
    ts.push_back({{"name", t.name},
                  {"range", {t.range.begin, t.range.end}},
                  {"baseline_rms", number(t.baseline_rms)},
                  {"best_rms", number(t.best_rms)}});
  return ts;
}

}  // namespace

json band_report_json(const model::fit::BandDataset& data, const model::diagnosis::DiagnosisResult& r,
                      const model::diagnosis::DiagnosisOptions& o, const ReportContext& ctx) {
  json j = report_head(
      "band", "dB", ctx,
      "heldout_rms_db: the ranking gap, sqrt(thesis band gap^2 + microphone-calibration residual^2 + crank-window "
      "gap^2) over held-out conditions; *_thesis_rms_db: the thesis metric alone (attenuation-curve RMS over the "
      "scored 1/3-octave bands, cycle-averaged, per held-out condition, averaged)");
  j["protocol"] = band_protocol(data, r, o);
  j["baseline"] = {{"model", r.model_name},
                   {"train_rms_db", number(r.baseline.train_rms_db)},
                   {"heldout_rms_db", number(r.baseline.heldout_gap_db)},
                   {"heldout_thesis_rms_db", number(r.baseline.heldout_thesis_rms_db)},
                   {"parameters", r.baseline.parameters},
                   {"params", model_params(r.baseline.model)}};
  j["where"] = band_where(data, r);
  j["candidates"] = scores_json(r.candidates);
  j["combinations"] = scores_json(r.combinations);
  j["verdict"] = band_verdict(r.verdict);
  json timing = json::array();
  for (const auto& [stage, s] : r.timing) timing.push_back({{"stage", stage}, {"seconds", s}});
  j["timing"] = timing;
  j["seconds"] = r.seconds;
  return j;
}

json waveform_report_json(const model::diagnosis::WaveformDiagnosis& d, const std::string& units,
                          const std::vector<WaveformTestSet>& tests, const ReportContext& ctx) {
  const model::diagnosis::WaveformReport rep = model::diagnosis::waveform_report(d);
  json j = report_head("waveform", units, ctx,
                       "free-run simulation RMS error of the output on the held-out sample ranges, in " + units +
                           " (the *_rms_db keys carry it in waveform mode)");
  j["baseline"] = {{"model", rep.baseline_model},
                   {"train_rms_db", number(rep.baseline_train_rms)},
                   {"heldout_rms_db", number(rep.baseline_heldout_rms)},
                   {"params", named_params(rep.baseline_params)}};
  j["candidates"] = waveform_candidates(rep);
  json na = json::array();
  for (const auto& n : rep.not_applicable) na.push_back({{"effect", n.effect}, {"reason", n.reason}});
  j["not_applicable"] = na;
  j["where"] = waveform_where(d, rep);
  const double before_rms = rep.heldout_rms_before, after_rms = rep.heldout_rms_after;
  j["verdict"] = {{"effect", rep.verdict},
                  {"also", rep.also_significant},
                  {"heldout_rms_before_db", number(before_rms)},
                  {"heldout_rms_after_db", number(after_rms)},
                  {"gap_closed_fraction", number(before_rms > 0 ? 1.0 - after_rms / before_rms : 0.0)},
                  {"remaining_db", number(after_rms)}};
  j["test_sets"] = test_sets_json(tests);
  j["seconds"] = d.seconds;
  return j;
}

}  // namespace noisemon::cli::report
