// report.html's waveform-mode sections.
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "cli/report/html_page.hpp"

namespace noisemon::cli::report::html {
namespace {

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

}  // namespace

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

}  // namespace noisemon::cli::report::html
