// report.html's band-mode sections.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "cli/report/html_page.hpp"

namespace noisemon::cli::report::html {
namespace {

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

}  // namespace

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

}  // namespace noisemon::cli::report::html
