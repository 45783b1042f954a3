// The building blocks of report.html (report_html.hpp): JSON access that never throws (a missing key, a null or
// a value of the wrong type reads as empty / NaN), the page's colours, and its sections and tables. The band and
// waveform sections are each in a file of their own (report_html_bands.cpp, report_html_waveform.cpp).
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <string>
#include <vector>

#include "cli/report/svg_plot.hpp"

namespace noisemon::cli::report::html {

using nlohmann::json;
using namespace svg;

// The page's colours.
inline constexpr const char* kMeasured = "#1b1b1b";
inline constexpr const char* kBaseline = "#e07b00";  // baseline / before
inline constexpr const char* kBest = "#1f6fd1";      // best candidate / after
inline constexpr const char* kGreen = "#2ca02c";
inline constexpr const char* kPurple = "#8c6bb1";

inline std::string pct(double f) { return finite(f) ? fixed(100.0 * f, 1) + " %" : kDash; }

// ---- JSON access: never throws; a missing key, a null or a value of the wrong type reads as empty / NaN ----

inline const json& get(const json& j, const char* key) {
  static const json kNull;
  if (!j.is_object()) return kNull;
  const auto it = j.find(key);
  return it == j.end() ? kNull : *it;
}
inline double num(const json& j) { return j.is_number() ? j.get<double>() : kNaN; }
inline bool flag(const json& j) { return j.is_boolean() && j.get<bool>(); }
inline std::string yesno(const json& j) { return j.is_boolean() ? (j.get<bool>() ? "yes" : "no") : kDash; }
inline Series nums(const json& j) {
  Series v;
  if (j.is_array())
    for (const json& x : j) v.push_back(num(x));
  return v;
}
inline std::vector<Series> rows_of(const json& j) {
  std::vector<Series> v;
  if (j.is_array())
    for (const json& r : j) v.push_back(nums(r));
  return v;
}
inline std::string text(const json& j) {
  if (j.is_string()) return j.get<std::string>();
  if (j.is_boolean()) return j.get<bool>() ? "yes" : "no";
  if (j.is_number_integer() || j.is_number_unsigned()) return j.dump();
  return j.is_number_float() ? sig(j.get<double>(), 6) : "";
}
inline std::vector<std::string> texts(const json& j) {
  std::vector<std::string> v;
  if (j.is_array())
    for (const json& x : j) v.push_back(text(x));
  else if (j.is_string())
    v.push_back(j.get<std::string>());
  return v;
}
inline std::string joined(const json& j, const std::string& sep) {
  std::string s;
  for (const auto& x : texts(j)) s += (s.empty() ? "" : sep) + esc(x);
  return s.empty() ? kDash : s;
}
template <class T>
inline T at(const std::vector<T>& v, std::size_t i, T fallback) {
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

inline std::string section(const std::string& id, const std::string& title, const std::string& body) {
  return el("section", {"id", id}, el("h2", {}, esc(title)) + body);
}
inline std::string row(std::initializer_list<std::string> cells, const std::string& cls = "", const char* cell = "td") {
  std::string o;
  for (const auto& c : cells) o += std::string("<") + cell + ">" + c + "</" + cell + ">";
  return el("tr", {"class", cls}, o);
}
inline std::string table(const std::string& head, const std::string& body, const std::string& cls = "") {
  return el("table", {"class", cls}, el("thead", {}, head) + "<tbody>" + body + "</tbody>");
}
inline std::string note(const std::string& html) { return el("p", {"class", "note"}, html); }
inline std::string closed_cell(double f) {
  const double w = finite(f) ? 60.0 * std::clamp(f, 0.0, 1.0) : 0.0;
  return pct(f) + " <span class=\"bar\" style=\"width:" + fixed(w, 0) + "px\"></span>";
}
inline std::string param_count(const json& c) {
  return get(c, "parameters").is_number() ? text(get(c, "parameters")) : std::to_string(get(c, "params").size());
}

// 1. Verdict, gap before -> after, explanation, baseline, command, data, metric, protocol.

// The band-mode sections (floors, gap map, attenuation, band gaps, microphones, panels, conditions).
std::string band_sections(Page& pg, const json& r);
// The waveform-mode sections (band error, amplitude, test sets, explainable gap).
std::string waveform_sections(Page& pg, const json& r);

}  // namespace noisemon::cli::report::html
