#include "cli/report/report_html.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "cli/report/html_page.hpp"

namespace noisemon::cli::report {
namespace {

using namespace html;

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
