#include "cli/report/report_html.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "cli/report/svg_plot.hpp"

namespace noisemon::cli::report {
namespace {

using nlohmann::json;
using namespace svg;

// The page's colours.
constexpr const char* kMeasured = "#1b1b1b";
constexpr const char* kBaseline = "#e07b00";  // baseline / before
constexpr const char* kBest = "#1f6fd1";      // best candidate / after
constexpr const char* kGreen = "#2ca02c";
constexpr const char* kPurple = "#8c6bb1";

std::string pct(double f) { return finite(f) ? fixed(100.0 * f, 1) + " %" : kDash; }

// ---- JSON access: never throws; a missing key, a null or a value of the wrong type reads as empty / NaN ----

const json& get(const json& j, const char* key) {
  static const json kNull;
  if (!j.is_object()) return kNull;
  const auto it = j.find(key);
  return it == j.end() ? kNull : *it;
}
double num(const json& j) { return j.is_number() ? j.get<double>() : kNaN; }
bool flag(const json& j) { return j.is_boolean() && j.get<bool>(); }
std::string yesno(const json& j) { return j.is_boolean() ? (j.get<bool>() ? "yes" : "no") : kDash; }
Series nums(const json& j) {
  Series v;
  if (j.is_array())
    for (const json& x : j) v.push_back(num(x));
  return v;
}
std::vector<Series> rows_of(const json& j) {
  std::vector<Series> v;
  if (j.is_array())
    for (const json& r : j) v.push_back(nums(r));
  return v;
}
std::string text(const json& j) {
  if (j.is_string()) return j.get<std::string>();
  if (j.is_boolean()) return j.get<bool>() ? "yes" : "no";
  if (j.is_number_integer() || j.is_number_unsigned()) return j.dump();
  return j.is_number_float() ? sig(j.get<double>(), 6) : "";
}
std::vector<std::string> texts(const json& j) {
  std::vector<std::string> v;
  if (j.is_array())
    for (const json& x : j) v.push_back(text(x));
  else if (j.is_string())
    v.push_back(j.get<std::string>());
  return v;
}
std::string joined(const json& j, const std::string& sep) {
  std::string s;
  for (const auto& x : texts(j)) s += (s.empty() ? "" : sep) + esc(x);
  return s.empty() ? kDash : s;
}
template <class T>
T at(const std::vector<T>& v, std::size_t i, T fallback) {
  return i < v.size() ? v[i] : fallback;
}

// ---- The page: one column of sections ----

struct Page {
  std::string units;  // "dB" in band mode
  std::vector<std::string> missing;
  std::string val(double v) const { return units == "dB" ? db(v) : sig(v); }  // 2 decimals in dB, else 4 digits
  std::string with_units(double v) const { return finite(v) ? val(v) + " " + esc(units) : kDash; }
  // Records what a section could not show; returns the note shown in its place.
  std::string lack(const std::string& what) {
    missing.push_back(what);
    return el("p", {"class", "missing"}, "Not in this report: " + esc(what));
  }
};

std::string section(const std::string& id, const std::string& title, const std::string& body) {
  return el("section", {"id", id}, el("h2", {}, esc(title)) + body);
}
std::string row(std::initializer_list<std::string> cells, const std::string& cls = "", const char* cell = "td") {
  std::string o;
  for (const auto& c : cells) o += std::string("<") + cell + ">" + c + "</" + cell + ">";
  return el("tr", {"class", cls}, o);
}
std::string table(const std::string& head, const std::string& body, const std::string& cls = "") {
  return el("table", {"class", cls}, el("thead", {}, head) + "<tbody>" + body + "</tbody>");
}
std::string note(const std::string& html) { return el("p", {"class", "note"}, html); }
std::string closed_cell(double f) {
  const double w = finite(f) ? 60.0 * std::clamp(f, 0.0, 1.0) : 0.0;
  return pct(f) + " <span class=\"bar\" style=\"width:" + fixed(w, 0) + "px\"></span>";
}
std::string param_count(const json& c) {
  return get(c, "parameters").is_number() ? text(get(c, "parameters")) : std::to_string(get(c, "params").size());
}

// 1. Verdict, gap before -> after, explanation, baseline, command, data, metric, protocol.
std::string header(Page& pg, const json& r, const std::string& mode) {
  const json& v = get(r, "verdict");
  const json& b = get(r, "baseline");
  const json& p = get(r, "protocol");
  const std::string effect = text(get(v, "effect"));
  if (effect.empty()) pg.missing.push_back("verdict.effect");
  const double before = num(get(v, "heldout_rms_before_db")), after = num(get(v, "heldout_rms_after_db"));
  if (!finite(before) || !finite(after)) pg.missing.push_back("verdict held-out gap before / after");
  std::string o = el("div", {"class", "small"},
                     esc(text(get(r, "tool")).empty() ? "noisemon diagnose" : text(get(r, "tool"))) + " &middot; " +
                         esc(mode.empty() ? "unknown" : mode) +
                         " mode &middot; units: " + (pg.units.empty() ? kDash : esc(pg.units)));
  o += el("div", {"class", "vlabel"}, "Verdict") +
       el("div",
          {"class", std::string("verdict ") + (effect.empty()            ? "v-missing"
                                               : effect == "none"        ? "v-none"
                                               : effect == "unexplained" ? "v-unexplained"
                                                                         : "v-named")},
          esc(effect.empty() ? "no verdict in report" : effect));
  o += el("div", {"class", "gapline"},
          "Held-out gap <b>" + pg.val(before) + "</b> &rarr; <b>" + pg.val(after) + "</b> " + esc(pg.units) +
              " &middot; <b>" + pct(num(get(v, "gap_closed_fraction"))) + "</b> closed");
  if (const std::string e = text(get(v, "explanation")); !e.empty()) o += el("p", {"class", "expl"}, esc(e));
  o += "<p>Also significant: <b>" + joined(get(v, "also"), ", ") + "</b></p>";
  if (const std::string rest = text(get(get(v, "remaining"), "summary")); !rest.empty())
    o += el("p", {"class", "expl"}, esc(rest));
  if (get(v, "heldout_thesis_rms_before_db").is_number() || get(v, "noise_db").is_number())
    o += el("p", {"class", "small"},
            "Thesis metric (attenuation-curve RMS): " + pg.val(num(get(v, "heldout_thesis_rms_before_db"))) +
                " &rarr; " + pg.with_units(num(get(v, "heldout_thesis_rms_after_db"))) +
                " &middot; noise (bootstrap spread of the baseline gap): " + pg.with_units(num(get(v, "noise_db"))));
  if (b.is_object())
    o += "<p>Baseline model <b>" + esc(text(get(b, "model"))) + "</b> (" + param_count(b) + " parameters): train " +
         pg.val(num(get(b, "train_rms_db"))) + ", held-out " + pg.with_units(num(get(b, "heldout_rms_db"))) +
         (get(b, "heldout_thesis_rms_db").is_number()
              ? " (thesis metric " + pg.with_units(num(get(b, "heldout_thesis_rms_db"))) + ")"
              : "") +
         "</p>";
  else
    o += pg.lack("baseline");
  o += el("div", {"class", "small"}, "Command: <code>" + esc(text(get(r, "command"))) + "</code>") +
       el("div", {"class", "small"}, "Data: <code>" + joined(get(r, "data"), "<br>") + "</code>") +
       el("div", {"class", "small"}, "Metric: " + esc(text(get(r, "metric"))));
  if (p.is_object())
    o += el("div", {"class", "small"},
            "Protocol: train " + joined(get(p, "train"), ", ") + "; held-out " + joined(get(p, "heldout"), ", ") +
                "; reference " + joined(get(p, "reference"), ", ") + "; leave-one-condition-out " +
                yesno(get(p, "leave_one_condition_out")) + "; " + esc(text(get(p, "bootstrap_replicates"))) +
                " bootstrap replicates (seed " + esc(text(get(p, "seed"))) + "); tolerance " +
                db(num(get(p, "tolerance_db"))) + " dB; min closed " + pct(num(get(p, "min_closed_fraction"))) +
                "; floor margin " + db(num(get(p, "floor_margin_db"))) + " dB; " + esc(text(get(p, "fit_cycles"))) +
                " fit cycles");
  return el("header", {}, o);
}

// 2. Candidates (and band-mode combinations, waveform second-round candidates), the verdict's row highlighted.
std::vector<std::string> effects_of(const json& c) {
  std::vector<std::string> e = texts(get(c, "effects"));
  if (e.empty()) e.push_back(text(get(c, "effect")));
  return e;
}

// The verdict's row: the combination of the verdict with its "also" effects when one was scored (band mode),
// else the first first-round candidate of the verdict's effect.
const json* verdict_row(const json& r, bool band) {
  const json& v = get(r, "verdict");
  const std::string effect = text(get(v, "effect"));
  std::vector<std::string> verdict_set{effect};
  for (const auto& a : texts(get(v, "also"))) verdict_set.push_back(a);
  const json* target = nullptr;
  if (band && verdict_set.size() > 1)
    for (const json& c : get(r, "combinations"))
      if (!target && c.is_object() && effects_of(c) == verdict_set) target = &c;
  for (const json& c : get(r, "candidates"))
    if (!target && c.is_object() && !effect.empty() && effects_of(c).front() == effect && !flag(get(c, "second_round")))
      target = &c;
  return target;
}

std::string candidates_head(const Page& pg, bool band) {
  const std::string u = esc(pg.units);
  return band ? row({"effect", "held-out gap (dB)", "thesis metric (dB)", "train (dB)", "closed", "significant",
                     "win fraction", "improvement, p05 (dB)", "closes: bands / mics / windows (dB)", "parameters"},
                    "", "th")
              : row({"effect", "held-out RMS (" + u + ")", "closed", "significant", "p-value", "round", "parameters"},
                    "", "th");
}

std::string baseline_row(const Page& pg, const json& r, bool band) {
  const json& b = get(r, "baseline");
  if (!b.is_object()) return "";
  const std::string name = "<i>baseline (" + esc(text(get(b, "model"))) + ")</i>";
  return band ? row({name, db(num(get(b, "heldout_rms_db"))), db(num(get(b, "heldout_thesis_rms_db"))),
                     db(num(get(b, "train_rms_db"))), "", "", "", "", "", param_count(b)},
                    "base")
              : row({name, pg.val(num(get(b, "heldout_rms_db"))), "", "", "", "", param_count(b)}, "base");
}

// A candidate's name cell: its effects, tags (combination, 2nd round, verdict, = after, thesis metric worse) and
// its error, if any. `after`: the verdict's held-out RMS after.
std::string candidate_name(const json& c, bool combination, const json* target, double after) {
  std::string name;
  for (const auto& e : effects_of(c)) name += (name.empty() ? "" : " + ") + esc(e);
  const double h = num(get(c, "heldout_rms_db"));
  if (combination) name += "<span class=\"tag\">combination</span>";
  if (flag(get(c, "second_round"))) name += "<span class=\"tag\">2nd round</span>";
  if (&c == target) name += "<span class=\"tag vt\">verdict</span>";
  if (finite(h) && finite(after) && std::fabs(h - after) <= 1e-9 * std::fabs(after))
    name += "<span class=\"tag\">= after</span>";
  if (flag(get(c, "thesis_metric_worse"))) name += "<span class=\"tag\">thesis metric worse</span>";
  if (const json& ic = get(c, "information_criterion"); ic.is_object() && !flag(get(ic, "pays_for_parameters")))
    name += "<span class=\"tag\">does not pay for its parameters</span>";
  if (flag(get(c, "group_worse"))) name += "<span class=\"tag\">worse leaving out a speed</span>";
  if (const std::string e = text(get(c, "error")); !e.empty()) name += el("div", {"class", "small err"}, esc(e));
  return name;
}

std::string candidate_row(const Page& pg, const json& c, bool combination, bool band, const json* target,
                          double after) {
  const std::string name = candidate_name(c, combination, target, after);
  const bool second = flag(get(c, "second_round"));
  const double h = num(get(c, "heldout_rms_db"));
  const json& closes = get(c, "closes_db");
  const std::string parts = closes.is_object() ? db(num(get(closes, "thesis_bands"))) + " / " +
                                                     db(num(get(closes, "mic_calibration"))) + " / " +
                                                     db(num(get(closes, "crank_windows")))
                                               : "";
  const std::string closed = closed_cell(num(get(c, "gap_closed_fraction")));
  return band ? row({name, db(h), db(num(get(c, "heldout_thesis_rms_db"))), db(num(get(c, "train_rms_db"))), closed,
                     yesno(get(c, "significant")), fixed(num(get(c, "win_fraction")), 2),
                     db(num(get(c, "improvement_db"))) + ", " + db(num(get(c, "improvement_p05_db"))), parts,
                     param_count(c)},
                    &c == target ? "vrow" : "")
              : row({name, pg.val(h), closed, yesno(get(c, "significant")), sig(num(get(c, "p_value")), 2),
                     second ? "2" : "1", param_count(c)},
                    &c == target ? "vrow" : "");
}

std::string not_applicable(const json& r) {
  const json& na = get(r, "not_applicable");
  if (!na.is_array() || na.empty()) return "";
  std::string rows;
  for (const json& n : na) rows += row({esc(text(get(n, "effect"))), esc(text(get(n, "reason")))});
  return el("h3", {}, "Not applicable to this data") + table(row({"effect", "reason"}, "", "th"), rows, "txt");
}

// 2. Candidates (and band-mode combinations, waveform second-round candidates), the verdict's row highlighted.
std::string candidates(Page& pg, const json& r, bool band) {
  const json* target = verdict_row(r, band);
  const double after = num(get(get(r, "verdict"), "heldout_rms_after_db"));
  std::string body = baseline_row(pg, r, band);
  bool any = false;
  for (const auto& [list, combination] : {std::pair{"candidates", false}, std::pair{"combinations", true}})
    for (const json& c : get(r, list))
      if (c.is_object()) any = true, body += candidate_row(pg, c, combination, band, target, after);
  std::string o = table(candidates_head(pg, band), body) + (any ? "" : pg.lack("candidates"));
  o += note(
      band ? "Closed: share of the baseline's held-out gap the candidate removes; closes: by how many dB it reduces "
             "each part of the gap (the thesis band gap, the microphone-calibration residual, the crank-window gap; "
             "negative: it makes that part worse). Significant: the bootstrap win fraction and the improvement pass "
             "the thresholds in the protocol, and the held-out thesis metric is not worse than the baseline's."
           : "Closed: share of the held-out RMS removed (2nd-round candidates are fitted on top of the first-round "
             "winner; their share is relative to it). &ldquo;= after&rdquo; marks the model whose held-out RMS "
             "the verdict reports as after.");
  o += not_applicable(r);
  return section("candidates", "Candidates", o);
}

Series column_mean(const std::vector<Series>& m, std::size_t cols) {
  Series out(cols, kNaN);
  for (std::size_t c = 0; c < cols; ++c) {
    double s = 0;
    int n = 0;
    for (const auto& r : m)
      if (finite(at(r, c, kNaN))) s += r[c], ++n;
    if (n > 0) out[c] = s / n;
  }
  return out;
}
std::vector<std::string> band_tips(const Series& hz, const Series& v, const std::string& what,
                                   const std::string& unit) {
  std::vector<std::string> t;
  for (std::size_t i = 0; i < hz.size(); ++i)
    t.push_back(sig(hz[i]) + " Hz, " + what + ": " + db(at(v, i, kNaN)) + unit);
  return t;
}

// The measurement chains' floors: which floor each run's pressure was judged by, and the cells at a floor.
std::string floors_section(Page& pg, const json& f, const json& conds) {
  if (!f.is_object()) return section("floors", "Floors", pg.lack("where.floors"));
  std::string lines;
  for (const json& l : get(f, "summary")) lines += el("li", {}, esc(text(l)));
  const json &by = get(f, "pressure_judged_by"), &stated = get(f, "pressure_stated_bar"),
             &est = get(f, "pressure_estimated_bar"), &bands = get(f, "floor_limited_bands"),
             &wins = get(f, "floor_limited_windows");
  std::string rows;
  for (std::size_t k = 0; conds.is_array() && k < conds.size(); ++k) {
    static const json none;
    auto at = [&](const json& a) -> const json& { return a.is_array() && k < a.size() ? a[k] : none; };
    rows += row({esc(text(get(conds[k], "name"))), esc(text(at(by))), sig(num(at(stated)), 3), sig(num(at(est)), 3),
                 esc(text(at(bands))), esc(text(at(wins)))});
  }
  const std::string head = row({"condition", "pressure floor judged by", "stated (bar rms)", "estimated (bar rms)",
                                "floor-limited bands", "crank-window cells at the pressure floor"},
                               "", "th");
  return section(
      "floors", "Floors (never fitted, never scored)",
      el("ul", {}, lines) + table(head, rows, "txt") +
          note("Microphone floor from the " + esc(text(get(f, "mic_floor_source"))) +
               ". A band is floor-limited where the microphones are within the margin of the background "
               "runs' level, or the cylinder pressure within the margin of the pressure chain's floor (every "
               "prediction subtracts what that floor drives; cells within the margin are upper bounds)."));
}

// What the band-mode sections share: the report, its "where", the bands, the baseline gap per held-out condition
// and band, the held-out conditions' names (numbered where the report names fewer than the gap has rows) and the
// best model's name.
struct BandView {
  const json& r;
  const json& w;
  Series hz;
  std::vector<Series> gap;
  std::vector<std::string> held;
  std::string best_name;
};

BandView band_view(const json& r, const json& w) {
  BandView v{r, w, nums(get(w, "bands_hz")), rows_of(get(w, "gap_db")), texts(get(w, "heldout_conditions")), ""};
  for (std::size_t i = v.held.size(); i < v.gap.size(); ++i) v.held.push_back("condition " + std::to_string(i + 1));
  v.best_name = text(get(w, "best_model")).empty() ? "best candidate" : "best: " + text(get(w, "best_model"));
  return v;
}

// floor_limited is indexed like where.conditions: its rows for the held-out conditions, by name.
std::vector<std::vector<bool>> floor_limited_held(const BandView& v) {
  std::vector<std::vector<bool>> floor_held;
  for (const auto& h : v.held) {
    floor_held.emplace_back();
    std::size_t k = 0;
    for (const json& c : get(v.w, "conditions")) {
      const json& f = get(v.w, "floor_limited");
      if (text(get(c, "name")) == h && f.is_array() && k < f.size() && f[k].is_array())
        for (const json& x : f[k]) floor_held.back().push_back(flag(x));
      ++k;
    }
  }
  return floor_held;
}

// a. The gap map, and the band notes.
std::string gap_map_section(Page& pg, const BandView& v) {
  std::string s = v.hz.empty() || v.gap.empty()
                      ? pg.lack(v.hz.empty() ? "where.bands_hz" : "where.gap_db")
                      : heat_map("gap-map",
                                 "Baseline gap, measured \xE2\x88\x92 predicted level (dB), held-out condition "
                                 "\xC3\x97 band",
                                 v.held, v.hz, v.gap, floor_limited_held(v),
                                 {"not scored (null)", "not scored", "floor-limited band",
                                  "red: measured louder than the baseline predicts; blue: quieter"});
  std::vector<std::pair<std::string, std::string>> notes;  // note, its bands
  const auto band_notes = texts(get(v.w, "band_notes"));
  for (std::size_t i = 0; i < band_notes.size(); ++i) {
    if (band_notes[i].empty()) continue;
    auto it = std::find_if(notes.begin(), notes.end(), [&](const auto& n) { return n.first == band_notes[i]; });
    if (it == notes.end()) it = notes.insert(notes.end(), {band_notes[i], ""});
    it->second += (it->second.empty() ? "" : ", ") + hz_label(at(v.hz, i, kNaN));
  }
  for (const auto& [n, bands] : notes) s += note("Band note <b>" + esc(n) + "</b>: " + bands + " Hz");
  return section("gap-map-section", "Where the gap is: band \xC3\x97 condition", s);
}

// b. Attenuation curves, one small plot per held-out condition.
std::string attenuation_section(Page& pg, const BandView& v) {
  const auto meas = rows_of(get(v.w, "att_meas_db")), base = rows_of(get(v.w, "att_baseline_db")),
             best = rows_of(get(v.w, "att_best_db"));
  std::string s;
  if (meas.empty() || v.hz.empty()) {
    s = pg.lack("where.att_meas_db");
  } else {
    s = "<p class=\"legend\"><span style=\"color:" + std::string(kMeasured) +
        "\">&#9679; measured</span><span style=\"color:" + kBaseline +
        "\">&#8211; &#8211; baseline</span><span style=\"color:" + kBest + "\">&mdash;&mdash; " + esc(v.best_name) +
        "</span>attenuation = CPL &minus; SPL<sub>A</sub></p><div class=\"grid\">";
    for (std::size_t i = 0; i < meas.size(); ++i) {
      const Series bi = at(base, i, Series{}), ti = at(best, i, Series{});
      Plot p("att-" + std::to_string(i), at(v.held, i, "condition " + std::to_string(i + 1)), band_axis(v.hz, true),
             linear_axis(extent({&meas[i], &bi, &ti}), "attenuation (dB)"), 330, 212, 26);
      p.line(v.hz, bi, {"", kBaseline, "5 3", false});
      p.line(v.hz, ti, {"", kBest, "", false});
      p.line(v.hz, meas[i], {"", kMeasured, "", true, false}, band_tips(v.hz, meas[i], "measured", " dB"));
      s += p.svg();
    }
    s += "</div>" + (best.empty() ? pg.lack("where.att_best_db (the best candidate's curves)") : "");
  }
  return section("attenuation", "Attenuation: measured vs baseline vs best candidate", s);
}

// c. Per-band gap before / after: a pair of bars filling 80 % of each band's width.
std::string band_gap_section(Page& pg, const BandView& v) {
  const json& verdict = get(v.r, "verdict");
  const auto before = nums(get(verdict, "band_before_db")), after = nums(get(verdict, "band_after_db"));
  const Series& hz = v.hz;
  std::string s;
  if (before.empty() || hz.empty()) {
    s = pg.lack("verdict.band_before_db");
  } else {
    Plot p("band-gap", "Per-band held-out gap, RMS over held-out conditions", band_axis(hz),
           linear_axis(extent({&before, &after}), "gap RMS (dB)", true));
    for (std::size_t i = 0; i < hz.size(); ++i) {
      const double bw = 0.4 * (p.X(hz[i] * kBandEdge) - p.X(hz[i] / kBandEdge)), b = at(before, i, kNaN),
                   a = at(after, i, kNaN);
      p.bar(p.X(hz[i]) - bw / 2, bw, b, kBaseline, sig(hz[i]) + " Hz, before: " + db(b) + " dB");
      p.bar(p.X(hz[i]) + bw / 2, bw, a, kBest, sig(hz[i]) + " Hz, after: " + db(a) + " dB");
    }
    p.legend({"before (baseline)", kBaseline, "", false, false});
    p.legend({"after (" + v.best_name + ")", kBest, "", false, false});
    s = p.svg();
  }
  return section("band-gap-section", "Per-band gap before and after", s);
}

// d. Microphones: offsets and own-curve gaps, and the calibration residuals.
std::string mics_section(Page& pg, const BandView& v) {
  const auto offs = nums(get(v.w, "mic_offset_db")), mic_rms = nums(get(v.w, "mic_gap_rms_db"));
  std::vector<std::string> mics = texts(get(v.w, "mics"));
  for (std::size_t i = mics.size(); i < std::max(offs.size(), mic_rms.size()); ++i)
    mics.push_back("mic " + std::to_string(i + 1));
  if (mics.empty()) return section("mics", "Microphones", pg.lack("where.mic_offset_db"));
  std::string s = bar_chart(
      "mic-offsets", "Per microphone: mean offset from the array and own-curve gap RMS", mics, "microphone",
      {{"offset from the array mean", kGreen, offs}, {"own-curve gap RMS (thesis metric)", kPurple, mic_rms}}, "dB");
  const auto mb = column_mean(rows_of(get(v.w, "mic_residual_baseline_db")), mics.size()),
             mt = column_mean(rows_of(get(v.w, "mic_residual_best_db")), mics.size());
  if (const auto [lo, hi] = extent({&mb, &mt}); lo == 0.0 && hi == 0.0)
    s += note(
        "Calibration residuals (mean over held-out conditions): 0.00 dB for every microphone, baseline and best "
        "model.");
  else if (finite(lo))
    s += bar_chart("mic-residuals", "Per microphone: calibration residual, mean over held-out conditions", mics,
                   "microphone", {{"baseline", kBaseline, mb}, {v.best_name, kBest, mt}}, "residual (dB)");
  return section("mics", "Microphones", s);
}

// e1. Mean gap vs input level per held-out condition, with the fitted slope.
std::string gap_vs_level_panel(Page& pg, const BandView& v) {
  const json& amp = get(v.w, "amplitude");
  const auto cpl = nums(get(amp, "cpl_overall_db")), mg = nums(get(amp, "mean_gap_db"));
  const double slope = num(get(amp, "slope_db_per_db"));
  if (cpl.empty()) return pg.lack("where.amplitude");
  Plot p("gap-vs-level", "Mean gap vs input level", linear_axis(extent({&cpl}), "overall CPL (dB)"),
         linear_axis(extent({&mg}), "mean gap (dB)", true), 500, 260);
  std::vector<std::string> tips;
  double mx = 0, my = 0, n = 0;
  for (std::size_t i = 0; i < cpl.size(); ++i) {
    tips.push_back(at(v.held, i, std::string("condition")) + ": CPL " + db(cpl[i]) + " dB, mean gap " +
                   db(at(mg, i, kNaN)) + " dB");
    if (finite(cpl[i]) && finite(at(mg, i, kNaN))) mx += cpl[i], my += mg[i], ++n;
  }
  if (finite(slope) && n > 1) {  // the slope drawn through the centroid (where a least-squares line passes)
    const double a = p.x_axis().lo, b = p.x_axis().hi;
    p.line({a, b}, {my / n + slope * (a - mx / n), my / n + slope * (b - mx / n)}, {"slope", "#999", "4 3", false});
  }
  p.line(cpl, mg, {"held-out condition", kBest, "", true, false}, tips);
  return "<div>" + p.svg() +
         note("Slope " + sig(slope, 3) +
              " dB/dB across held-out conditions (dashed, through their "
              "centroid); per cycle within conditions " +
              sig(num(get(amp, "cycle_slope_db_per_db")), 3) + " dB/dB; vs speed " +
              sig(num(get(v.w, "speed_slope_db_per_krpm")), 3) + " dB/krpm, vs injection timing " +
              sig(num(get(v.w, "soi_slope_db_per_deg")), 3) + " dB/deg BTDC, vs load " +
              sig(num(get(v.w, "load_slope_db_per_nm")), 3) + " dB/(N m).") +
         "</div>";
}

// e2. Mean baseline gap per crank window.
std::string crank_windows_panel(Page& pg, const BandView& v) {
  const auto start = nums(get(get(v.w, "crank_windows"), "start_deg")),
             wg = nums(get(get(v.w, "crank_windows"), "gap_db"));
  if (wg.empty()) return pg.lack("where.crank_windows");
  std::vector<std::string> cats;
  for (std::size_t i = 0; i < wg.size(); ++i) cats.push_back(finite(at(start, i, kNaN)) ? fixed(start[i], 0) : "?");
  return "<div>" +
         bar_chart("crank-windows", "Mean baseline gap per crank window", cats, "window start (\xC2\xB0 crank angle)",
                   {{"gap", kBaseline, wg}}, "gap (dB)", 500, 260) +
         "</div>";
}

// e3. Coherence per band.
std::string coherence_panel(Page& pg, const BandView& v) {
  const json& coh = get(v.w, "coherence");
  const auto cf = nums(get(coh, "coherent_fraction")), ps = nums(get(coh, "periodic_share")),
             fc = nums(get(coh, "fluctuation_coherence"));
  if (cf.empty() || v.hz.empty()) return pg.lack("where.coherence");
  Axis ax = linear_axis(extent({&cf, &ps, &fc}), "fraction");
  ax.hi = std::max(ax.hi, 1.0);
  Plot p("coherence", "Coherence per band (mean over fired conditions)", band_axis(v.hz, true), ax, 500, 260);
  p.line(v.hz, cf, {"coherent fraction", kBest, ""}, band_tips(v.hz, cf, "coherent fraction", ""));
  p.line(v.hz, ps, {"periodic share", kGreen, "5 3", false});
  p.line(v.hz, fc, {"fluctuation coherence", kPurple, "2 2", false});
  return "<div>" + p.svg() + "</div>";
}

// e4. The noise floor per band: combustion-independent, background run, microphone floor.
std::string noise_floor_panel(Page& pg, const BandView& v) {
  const Series& hz = v.hz;
  const auto fl = nums(get(get(v.w, "noise_floor"), "combustion_independent_db")),
             bg = nums(get(get(v.w, "noise_floor"), "background_db"));
  if (fl.empty() || hz.empty()) return pg.lack("where.noise_floor");
  Plot p("noise-floor", "Noise floor per band", band_axis(hz, true), linear_axis(extent({&fl, &bg}), "level (dB)"), 500,
         260);
  p.line(hz, fl, {"combustion-independent (motored excess)", kMeasured, ""},
         band_tips(hz, fl, "combustion-independent", " dB"));
  p.line(hz, bg, {"background run", kGreen, "5 3"}, band_tips(hz, bg, "background", " dB"));
  const auto mf = nums(get(get(v.w, "floors"), "mic_floor_db"));
  if (!mf.empty())
    p.line(hz, mf, {"microphone floor", kPurple, "2 2", false}, band_tips(hz, mf, "microphone floor", " dB"));
  return "<div>" + p.svg() + (finite(extent({&bg}).first) ? "" : note("Background run: none (all null).")) + "</div>";
}

// e. Smaller panels: gap vs level, crank windows, coherence, noise floor.
std::string panels_section(Page& pg, const BandView& v) {
  std::string s = gap_vs_level_panel(pg, v);
  s += crank_windows_panel(pg, v);
  s += coherence_panel(pg, v);
  s += noise_floor_panel(pg, v);
  return section("panels", "Gap vs level, crank angle, coherence, noise floor", el("div", {"class", "grid2"}, s));
}

// f. The conditions.
std::string conditions_section(Page& pg, const json& conds) {
  std::string s;
  for (const json& c : conds)
    if (c.is_object())
      s += row({esc(text(get(c, "name"))), esc(text(get(c, "role"))), fixed(num(get(c, "speed_rpm")), 0),
                fixed(num(get(c, "load_nm")), 1), fixed(num(get(c, "soi_deg_btdc")), 1), yesno(get(c, "motored")),
                yesno(get(c, "background")), esc(text(get(c, "cycles"))), esc(text(get(c, "mics")))});
  return section("conditions", "Conditions",
                 s.empty() ? pg.lack("where.conditions")
                           : table(row({"name", "role", "speed (rpm)", "load (N m)", "SOI (\xC2\xB0 BTDC)", "motored",
                                        "background", "cycles", "mics"},
                                       "", "th"),
                                   s, "txt"));
}

// 3. Band mode: the gap map, attenuation curves, per-band gap, microphones, smaller panels, conditions, floors.
std::string band_sections(Page& pg, const json& r) {
  const json& w = get(r, "where");
  if (!w.is_object()) return section("where", "Where the gap is", pg.lack("where (the per-band figures)"));
  const BandView view = band_view(r, w);
  std::string o = gap_map_section(pg, view);
  o += attenuation_section(pg, view);
  o += band_gap_section(pg, view);
  o += mics_section(pg, view);
  o += panels_section(pg, view);
  o += conditions_section(pg, get(w, "conditions"));
  o += floors_section(pg, get(w, "floors"), get(w, "conditions"));
  return o;
}

std::vector<std::string> level_tips(const Series& hz, const Series& y, const std::string& what, const std::string& u) {
  std::vector<std::string> t;
  for (std::size_t i = 0; i < hz.size(); ++i)
    t.push_back(sig(hz[i]) + " Hz, " + what + ": " + sig(at(y, i, kNaN)) + " " + u);
  return t;
}

// 4a. Per-band free-run error before / after against the output's own RMS. u: the data's units.
std::string band_error_section(Page& pg, const json& w, const std::string& u) {
  const auto hz = nums(get(w, "bands_hz")), out = nums(get(w, "output_rms")), eb = nums(get(w, "error_rms_before")),
             ea = nums(get(w, "error_rms_after"));
  std::string s;
  if (const auto [flo, fhi] = extent({&hz}, true); !finite(flo)) {
    s = pg.lack("where.bands_hz");
  } else {
    const auto [lo, hi] = extent({&out, &eb, &ea}, true);
    Plot p("band-error", "Per-band free-run error before / after vs output RMS",
           log_axis(flo / kBandEdge, fhi * kBandEdge, "1/3-octave band centre (Hz)", false),
           log_axis(lo, hi, "RMS (" + u + ")", true, 2.2), 1000, 320);
    p.line(hz, out, {"output RMS", "#9a9a9a", "5 3"}, level_tips(hz, out, "output RMS", u));
    p.line(hz, eb, {"error before (baseline)", kBaseline, ""}, level_tips(hz, eb, "error before", u));
    p.line(hz, ea, {"error after", kBest, ""}, level_tips(hz, ea, "error after", u));
    s = p.svg();
  }
  return section("band-error-section", "Where the error is: per band", s);
}

// The error-vs-amplitude bins: level range, its centre, the error before and after, and their table rows.
struct AmplitudeBins {
  Series mid, before, after, lo, hi;
  std::string rows;
};

AmplitudeBins amplitude_bins(const json& amp) {
  AmplitudeBins g;
  for (const json& x : amp) {
    if (!x.is_object()) continue;
    g.lo.push_back(num(get(x, "level_lo"))), g.hi.push_back(num(get(x, "level_hi")));
    g.mid.push_back(0.5 * (g.lo.back() + g.hi.back()));
    g.before.push_back(num(get(x, "error_rms_before"))), g.after.push_back(num(get(x, "error_rms_after")));
    g.rows += row({sig(g.lo.back()), sig(g.hi.back()), esc(text(get(x, "samples"))), sig(g.before.back()),
                   sig(g.after.back()), pct(g.after.back() / g.before.back())});
  }
  return g;
}

std::string amplitude_plot(const AmplitudeBins& g, const std::string& u) {
  const auto [lo, hi] = extent({&g.before, &g.after}, true);
  Plot p("amplitude-error", "Free-run error vs local output level (equally populated bins, marker at bin centre)",
         linear_axis(extent({&g.lo, &g.hi}), "local output level, RMS (" + u + ")", true),
         log_axis(lo, hi, "error RMS (" + u + ")", true, 2.2), 1000, 280);
  std::vector<std::string> tb, ta;
  for (std::size_t i = 0; i < g.mid.size(); ++i) {
    const std::string level = "level " + sig(g.lo[i]) + "\xE2\x80\x93" + sig(g.hi[i]);
    tb.push_back(level + ", before: " + sig(g.before[i]) + " " + u);
    ta.push_back(level + ", after: " + sig(g.after[i]) + " " + u);
    for (const auto& [y, c] : {std::pair{g.before[i], kBaseline}, std::pair{g.after[i], kBest}})  // the bin's extent
      if (finite(p.Y(y)) && finite(p.X(g.lo[i])) && finite(p.X(g.hi[i])))
        p.raw(el("line", {"x1", p.X(g.lo[i]), "x2", p.X(g.hi[i]), "y1", p.Y(y), "y2", p.Y(y), "stroke", c,
                          "stroke-width", 4.0, "stroke-opacity", 0.35}));
  }
  p.line(g.mid, g.before, {"error before (baseline)", kBaseline, ""}, tb);
  p.line(g.mid, g.after, {"error after", kBest, ""}, ta);
  return p.svg();
}

// 4b. Free-run error against the local output level.
std::string amplitude_section(Page& pg, const json& w, const std::string& u) {
  const AmplitudeBins g = amplitude_bins(get(w, "amplitude"));
  const std::string s =
      g.mid.empty()
          ? pg.lack("where.amplitude")
          : amplitude_plot(g, u) +
                table(row({"level from", "to", "samples", "error before", "error after", "after / before"}, "", "th"),
                      g.rows);
  return section("amplitude-section", "Error vs amplitude", s);
}

// 4c. The named test sets (--test).
std::string test_sets_section(Page& pg, const json& r, const std::string& u) {
  std::string rows;
  for (const json& t : get(r, "test_sets")) {
    if (!t.is_object()) continue;
    const auto range = nums(get(t, "range"));
    const double tb = num(get(t, "baseline_rms")), tt = num(get(t, "best_rms"));
    rows += row({esc(text(get(t, "name"))), range.size() == 2 ? fixed(range[0], 0) + " : " + fixed(range[1], 0) : kDash,
                 sig(tb), sig(tt), pct(tt / tb)});
  }
  return section("test-sets", "Test sets",
                 rows.empty() ? pg.lack("test_sets")
                              : table(row({"test set", "sample range", "baseline free-run RMS (" + esc(u) + ")",
                                           "best model free-run RMS (" + esc(u) + ")", "best / baseline"},
                                          "", "th"),
                                      rows));
}

// 4d. The explainable share of the error, and the held-out segments' RMS before and after.
std::string explainable_gap_section(Page& pg, const json& w, const std::string& u) {
  const json& eg = get(w, "explainable_gap");
  if (!eg.is_object()) return section("explainable-gap", "Explainable gap", pg.lack("where.explainable_gap"));
  std::string s = table(row({"model", "explainable share of the error", "p-value", "significant"}, "", "th"),
                        row({"baseline", closed_cell(num(get(eg, "baseline_fraction"))),
                             sig(num(get(eg, "baseline_p_value")), 2), yesno(get(eg, "baseline_significant"))}) +
                            row({"best model (remaining)", closed_cell(num(get(eg, "remaining_fraction"))),
                                 sig(num(get(eg, "remaining_p_value")), 2), yesno(get(eg, "remaining_significant"))}));
  const auto sb = nums(get(w, "heldout_segment_rms_before")), sa = nums(get(w, "heldout_segment_rms_after"));
  for (std::size_t i = 0; i < sb.size(); ++i)
    s += note("Held-out segment " + std::to_string(i + 1) + ": RMS " + sig(sb[i]) + " &rarr; " + sig(at(sa, i, kNaN)) +
              " " + esc(u));
  return section("explainable-gap", "Explainable gap", s);
}

// 4. Waveform mode: per-band error, error vs amplitude, test sets, explainable gap.
std::string waveform_sections(Page& pg, const json& r) {
  const json& w = get(r, "where");
  if (!w.is_object()) return section("where", "Where the error is", pg.lack("where (the per-band figures)"));
  const std::string u = pg.units.empty() ? "data units" : pg.units;
  std::string o = band_error_section(pg, w, u);
  o += amplitude_section(pg, w, u);
  o += test_sets_section(pg, r, u);
  o += explainable_gap_section(pg, w, u);
  return o;
}

std::string timing(const json& r) {
  std::string o;
  for (const json& x : get(r, "timing"))
    if (x.is_object())
      o += (o.empty() ? "" : " &middot; ") + esc(text(get(x, "stage"))) + " " + fixed(num(get(x, "seconds")), 2) + " s";
  const double sec = num(get(r, "seconds"));
  return o.empty() && !finite(sec)
             ? ""
             : el("footer", {"class", "small"}, "Run time " + fixed(sec, 2) + " s" + (o.empty() ? "" : ": " + o));
}

constexpr const char* kCss = R"css(
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"Helvetica Neue",Arial,sans-serif;margin:0;background:#f3f4f6;color:#1d2330;font-size:14px}
main{max-width:1100px;margin:0 auto;padding:14px 20px 40px}
header,section{background:#fff;border:1px solid #dde1e7;border-radius:6px;padding:12px 16px;margin:12px 0}
h2{font-size:17px;margin:0 0 8px}h3{font-size:14px;margin:14px 0 6px}
.vlabel{font-size:12px;text-transform:uppercase;letter-spacing:.08em;color:#57606a;margin-top:6px}
.verdict{font-size:42px;font-weight:700;line-height:1.1}
.v-named{color:#1a7f37}.v-none{color:#57606a}.v-unexplained{color:#b35900}.v-missing{color:#8a6d00}
.gapline{font-size:20px;margin:6px 0}.expl{font-size:15px}.small,.note{font-size:12px;color:#57606a;margin:3px 0}
code{font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,monospace;font-size:12px;word-break:break-all}
table{border-collapse:collapse;width:100%;font-size:13px}
th,td{padding:3px 8px;border-bottom:1px solid #e6e8eb;text-align:right;vertical-align:top;white-space:nowrap}
th{white-space:normal;background:#f6f8fa;font-weight:600}th:first-child,td:first-child{text-align:left;white-space:normal}
table.txt td:nth-child(-n+2),table.txt th:nth-child(-n+2){text-align:left;white-space:normal}
tr.vrow td{background:#fff4c2;font-weight:600}tr.base td{color:#57606a}
.tag{font-size:11px;font-weight:500;padding:0 6px;border-radius:8px;background:#e7ecf3;margin-left:6px}.vt{background:#1a7f37;color:#fff}
.err{color:#b00020;white-space:normal}.bar{display:inline-block;height:8px;background:#4c78a8;vertical-align:middle;margin-left:4px}
.missing{color:#7a5d00;background:#fff8e1;border:1px solid #f0d98a;padding:6px 10px;border-radius:4px;font-size:13px}
.grid{display:grid;grid-template-columns:repeat(3,1fr);gap:6px}.grid2{display:grid;grid-template-columns:repeat(2,1fr);gap:8px;align-items:start}
svg.plot{display:block;width:100%;height:auto}
svg text{font-size:11px;fill:#333}svg .ptitle{font-size:13px;font-weight:600;fill:#1d2330}svg .alabel{font-size:12px}
svg .grid{stroke:#e4e6ea}svg .tick{stroke:#777}.legend{font-size:13px;margin:2px 0 6px}.legend span{margin-right:14px}
)css";

}  // namespace

// The mode comes from "mode", else from which figures "where" holds; every section says in place what it lacks,
// and the top of the page lists all of it.
std::string report_html(const nlohmann::json& report) {
  Page pg;
  const json& r = report;
  const json& w = get(r, "where");
  std::string mode = text(get(r, "mode"));
  if (mode.empty())
    mode = get(w, "gap_db").is_array() ? "band" : get(w, "error_rms_before").is_array() ? "waveform" : "";
  pg.units = text(get(r, "units"));
  if (pg.units.empty() && mode == "band") pg.units = "dB";
  std::string body;
  if (!r.is_object() || r.empty()) {
    pg.missing.push_back(std::string("everything: the report is ") +
                         (r.is_object() ? "an empty object" : "not a JSON object"));
  } else {
    if (mode.empty()) pg.missing.push_back("mode (neither band nor waveform figures found)");
    body = candidates(pg, r, mode != "waveform") + (mode == "band" ? band_sections(pg, r) : "") +
           (mode == "waveform" ? waveform_sections(pg, r) : "") + timing(r);
  }
  const std::string top =
      r.is_object() ? header(pg, r, mode) : "<header><div class=\"verdict v-missing\">no report</div></header>";
  std::string missing;
  for (const auto& m : pg.missing) missing += (missing.empty() ? "" : "; ") + esc(m);
  const std::string verdict = text(get(get(r, "verdict"), "effect"));
  return "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
         "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>noisemon diagnose: " +
         esc(verdict.empty() ? "report" : verdict) + "</title><style>" + kCss + "</style></head><body><main>" +
         (missing.empty() ? ""
                          : el("p", {"class", "missing", "id", "missing"}, "Missing from this report: " + missing)) +
         top + body + "</main></body></html>\n";
}

}  // namespace noisemon::cli::report
