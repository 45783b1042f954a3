#include "daemon/report/report_html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace noisemon::daemon {
namespace {

using nlohmann::json;
using Series = std::vector<double>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
bool finite(double v) { return std::isfinite(v); }

// ---- Formatting ----

constexpr const char* kDash = "\xE2\x80\x94";  // an em dash: no value
std::string esc(std::string_view s) {
  std::string o;
  for (const char& c : s) {
    const char* e = c == '&'    ? "&amp;"
                    : c == '<'  ? "&lt;"
                    : c == '>'  ? "&gt;"
                    : c == '"'  ? "&quot;"
                    : c == '\'' ? "&#39;"
                                : nullptr;
    o += e ? std::string_view(e) : std::string_view(&c, 1);
  }
  return o;
}
std::string fixed(double v, int decimals) {
  if (!finite(v)) return kDash;
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  const std::string s = b;
  return s[0] == '-' && s.find_first_not_of("-0.") == std::string::npos ? s.substr(1) : s;  // no "-0.00"
}
std::string sig(double v, int digits = 4) {
  if (!finite(v)) return kDash;
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}
// dB: 2 decimals; two significant digits below 0.005 (a tiny noise figure is not "0.00").
std::string db(double v) { return finite(v) && v != 0.0 && std::fabs(v) < 0.005 ? sig(v, 2) : fixed(v, 2); }
std::string hz_label(double f) { return finite(f) && f >= 1000 ? sig(f / 1000, 3) + "k" : sig(f, 4); }
std::string pct(double f) { return finite(f) ? fixed(100.0 * f, 1) + " %" : kDash; }
std::string px(double v) { return fixed(v, 2); }  // an SVG coordinate

// An element <name k="v" ...>inner</name> (<name .../> without inner) from alternating attribute names and values
// (strings or numbers); attributes with an empty value are left out.
struct Val {
  Val(const char* v) : s(v) {}
  Val(std::string v) : s(std::move(v)) {}
  Val(double v) : s(px(v)) {}
  std::string s;
};
std::string el(const char* name, std::initializer_list<Val> attrs, const std::string& inner = "") {
  std::string o = std::string("<") + name;
  for (auto it = attrs.begin(); it != attrs.end() && it + 1 != attrs.end(); it += 2)
    if (!(it + 1)->s.empty()) o += " " + it->s + "=\"" + esc((it + 1)->s) + "\"";
  return inner.empty() ? o + "/>" : o + ">" + inner + "</" + name + ">";
}
std::string tip(const std::string& t) { return el("title", {}, esc(t)); }

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

// ---- Axes. A plot's frame is its <rect class="frame" x=x0 y=y0 width=pw height=ph> (SVG user units). A value v
// maps, with t = log10 on a log axis and the identity otherwise, to
//   x = x0 + pw * (t(v) - t(lo)) / (t(hi) - t(lo)),   y = y0 + ph * (1 - (t(v) - t(lo)) / (t(hi) - t(lo))).
// A linear axis spans [floor(min / s) * s, ceil(max / s) * s], s the smallest 1, 2 or 5 x 10^k >= (max - min) / 5
// (zero included for magnitudes and signed gaps); a 1/3-octave band axis spans the band edges [first centre /
// 2^(1/6), last centre * 2^(1/6)], log; a padded log axis spans [min / p, max * p], p = 10^(0.05 * max(0.2,
// decades)); a category axis spans [-0.5, n - 0.5] with category i at i.

struct Tick {
  double v;
  std::string label;  // empty: a minor tick (mark only, no grid line)
};
struct Axis {
  double lo = 0.0, hi = 1.0;
  bool log = false;
  std::string label;
  std::vector<Tick> ticks;
  bool grid = true;  // grid lines at the labelled ticks
};

double nice_step(double raw) {
  if (!(raw > 0) || !finite(raw)) return 1.0;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * mag >= raw * (1 - 1e-9)) return m * mag;
  return 10.0 * mag;
}
double nice_ceil(double x) {  // a round number >= x (the colour scale's end)
  if (!(x > 0) || !finite(x)) return 1.0;
  const double mag = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0})
    if (m * mag >= x * (1 - 1e-9)) return m * mag;
  return 10.0 * mag;
}
// Finite (and, for a log axis, positive) extent of several series; NaNs when there is none.
std::pair<double, double> extent(std::initializer_list<const Series*> series, bool positive = false) {
  double lo = kNaN, hi = kNaN;
  for (const Series* s : series)
    for (double v : *s)
      if (finite(v) && (!positive || v > 0))
        lo = finite(lo) ? std::min(lo, v) : v, hi = finite(hi) ? std::max(hi, v) : v;
  return {lo, hi};
}
Axis linear_axis(std::pair<double, double> r, std::string label, bool with_zero = false) {
  auto [lo, hi] = r;
  if (!finite(lo) || !finite(hi)) lo = 0.0, hi = 1.0;
  if (with_zero) lo = std::min(lo, 0.0), hi = std::max(hi, 0.0);
  if (hi - lo <= 1e-12 * std::max(1.0, std::fabs(hi))) {
    const double d = lo != 0.0 ? 0.1 * std::fabs(lo) : 1.0;
    lo -= d, hi += d;
  }
  const double s = nice_step((hi - lo) / 5.0);
  Axis a{std::floor(lo / s + 1e-9) * s, std::ceil(hi / s - 1e-9) * s, false, std::move(label), {}};
  const int decimals = std::max(0, -static_cast<int>(std::floor(std::log10(s) + 1e-9)));
  for (int i = 0; a.lo + i * s <= a.hi + 1e-9 * s; ++i) {
    const double v = std::fabs(a.lo + i * s) < 1e-9 * s ? 0.0 : a.lo + i * s;
    a.ticks.push_back({v, fixed(v, decimals)});
  }
  return a;
}
std::string log_label(double v) {  // 0.5, 20, 1e-5 (not 1e-05)
  std::string s = sig(v, 3);
  if (const auto k = s.find("e-0"); k != std::string::npos) s.erase(k + 2, 1);
  if (const auto k = s.find("e+"); k != std::string::npos) s.erase(k + 1, s[k + 2] == '0' ? 2 : 1);
  return s;
}
// Log axis labelled at 1, 2, 5 x 10^k (at 1 x 10^k only beyond dense_decades; at its ends if no label falls inside).
Axis log_axis(double lo, double hi, std::string label, bool pad, double dense_decades = 3.2) {
  if (!(lo > 0) || !finite(lo)) lo = 1.0;
  if (!(hi > lo) || !finite(hi)) hi = lo * 10.0;
  if (pad) {
    const double p = std::pow(10.0, 0.05 * std::max(0.2, std::log10(hi / lo)));
    lo /= p, hi *= p;
  }
  Axis a{lo, hi, true, std::move(label), {}};
  const bool dense = std::log10(hi / lo) <= dense_decades;
  for (int k = static_cast<int>(std::floor(std::log10(lo))); k <= static_cast<int>(std::ceil(std::log10(hi))); ++k)
    for (int m = 1; m <= 9; ++m)
      if (const double v = m * std::pow(10.0, k); v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9))
        a.ticks.push_back({v, m == 1 || (dense && (m == 2 || m == 5)) ? log_label(v) : std::string()});
  if (std::count_if(a.ticks.begin(), a.ticks.end(), [](const Tick& t) { return !t.label.empty(); }) < 2)
    a.ticks.push_back({lo, sig(lo, 3)}), a.ticks.push_back({hi, sig(hi, 3)});
  return a;
}
const double kEdge = std::pow(2.0, 1.0 / 6.0);  // 1/3-octave band centre to band edge
// Band axis: labels at the standard centres 31.5 ... 16k (every other one when `thin`), minor ticks at every band.
Axis band_axis(const Series& hz, bool thin = false) {
  const auto [f0, f1] = extent({&hz}, true);
  if (!finite(f0)) return log_axis(20.0, 20000.0, "1/3-octave band centre (Hz)", false);
  Axis a{f0 / kEdge, f1 * kEdge, true, "1/3-octave band centre (Hz)", {}};
  int n = 0;
  for (double f : {31.5, 63.0, 125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0, 16000.0})
    if (f >= a.lo && f <= a.hi) a.ticks.push_back({f, thin && n++ % 2 ? "" : hz_label(f)});
  for (double f : hz)
    if (finite(f) && f > 0) a.ticks.push_back({f, ""});
  return a;
}
Axis category_axis(const std::vector<std::string>& names, std::string label) {
  Axis a{-0.5, static_cast<double>(names.size()) - 0.5, false, std::move(label), {}, false};
  for (std::size_t i = 0; i < names.size(); ++i) a.ticks.push_back({static_cast<double>(i), names[i]});
  return a;
}

// ---- SVG plot builder: frame, grid, tick labels, axis titles, a legend row under the title; lines, markers and
// bars placed through the axis mapping above, each marker and bar with a <title> tooltip holding its value.

constexpr const char* kMeasured = "#1b1b1b";
constexpr const char* kBaseline = "#e07b00";  // baseline / before
constexpr const char* kBest = "#1f6fd1";      // best candidate / after
constexpr const char* kGreen = "#2ca02c";
constexpr const char* kPurple = "#8c6bb1";

struct Style {
  std::string name, colour, dash;
  bool markers = true, line = true;
};

class Plot {
 public:
  static constexpr double kLeft = 64, kRight = 18, kBottom = 44;
  // top: 44 leaves a legend row under the title; 26 (no legend) for small multiples.
  Plot(std::string id, std::string title, Axis x, Axis y, double w = 1000, double h = 300, double top = 44)
      : id_(std::move(id)), title_(std::move(title)), x_(std::move(x)), y_(std::move(y)), w_(w), h_(h), top_(top) {}
  double pw() const { return w_ - kLeft - kRight; }
  double ph() const { return h_ - top_ - kBottom; }
  double X(double v) const { return map(x_, v, kLeft, kLeft + pw()); }
  double Y(double v) const { return map(y_, v, top_ + ph(), top_); }
  const Axis& x_axis() const { return x_; }

  // A polyline broken at unplottable points, with markers whose tooltips are tips[i].
  void line(const Series& xs, const Series& ys, const Style& s, const std::vector<std::string>& tips = {}) {
    std::string d, dots;
    for (std::size_t i = 0, pen = 0; i < xs.size() && i < ys.size(); ++i) {
      const double x = X(xs[i]), y = Y(ys[i]);
      if (!finite(x) || !finite(y)) {
        pen = 0;
        continue;
      }
      d += (pen++ ? " L" : " M") + px(x) + " " + px(y);
      if (s.markers)
        dots += el("circle", {"cx", x, "cy", y, "r", 2.6, "fill", s.colour},
                   tip(i < tips.size() ? tips[i] : s.name + ": " + sig(xs[i]) + ", " + sig(ys[i])));
    }
    if (s.line && !d.empty())
      body_ += el("path", {"d", d.substr(1), "fill", "none", "stroke", s.colour, "stroke-width", 1.8,
                           "stroke-dasharray", s.dash});
    body_ += dots;
    legend(s);
  }
  // A bar centred at pixel xc, wpx wide, from the value axis' zero (clamped into the axis) to v.
  void bar(double xc, double wpx, double v, const std::string& colour, const std::string& t) {
    const double y = Y(v), y0 = Y(std::clamp(0.0, y_.lo, y_.hi));
    if (!finite(y) || !finite(xc)) return;
    body_ += el("rect",
                {"x", xc - wpx / 2, "y", std::min(y, y0), "width", wpx, "height", std::max(std::fabs(y0 - y), 0.5),
                 "fill", colour},
                tip(t));
  }
  void hline(double v, const std::string& colour) {
    if (finite(Y(v))) body_ += el("line", {"x1", kLeft, "x2", kLeft + pw(), "y1", Y(v), "y2", Y(v), "stroke", colour});
  }
  void raw(const std::string& svg) { body_ += svg; }
  void legend(const Style& s) {
    if (!s.name.empty() &&
        std::none_of(legend_.begin(), legend_.end(), [&](const Style& l) { return l.name == s.name; }))
      legend_.push_back(s);
  }

  std::string svg() const {
    const double bottom = top_ + ph();
    std::string o =
        el("text", {"class", "ptitle", "x", kLeft, "y", 16.0}, esc(title_)) +
        el("rect", {"class", "frame", "x", kLeft, "y", top_, "width", pw(), "height", ph(), "fill", "#fff"});
    for (const Tick& t : x_.ticks) {
      const double x = X(t.v);
      if (!finite(x)) continue;
      if (!t.label.empty() && x_.grid) o += el("line", {"class", "grid", "x1", x, "x2", x, "y1", top_, "y2", bottom});
      o += el("line", {"class", "tick", "x1", x, "x2", x, "y1", bottom, "y2", bottom + (t.label.empty() ? 3 : 5)});
      if (!t.label.empty()) o += el("text", {"x", x, "y", bottom + 16, "text-anchor", "middle"}, esc(t.label));
    }
    for (const Tick& t : y_.ticks) {
      const double y = Y(t.v);
      if (!finite(y)) continue;
      if (!t.label.empty()) o += el("line", {"class", "grid", "x1", kLeft, "x2", kLeft + pw(), "y1", y, "y2", y});
      o += el("line", {"class", "tick", "x1", kLeft - (t.label.empty() ? 3 : 5), "x2", kLeft, "y1", y, "y2", y});
      if (!t.label.empty()) o += el("text", {"x", kLeft - 8, "y", y + 4, "text-anchor", "end"}, esc(t.label));
    }
    o += body_ + el("rect", {"x", kLeft, "y", top_, "width", pw(), "height", ph(), "fill", "none", "stroke", "#888"});
    o += el("text", {"class", "alabel", "x", kLeft + pw() / 2, "y", h_ - 8, "text-anchor", "middle"}, esc(x_.label));
    o += el("text",
            {"class", "alabel", "transform", "translate(14 " + px(top_ + ph() / 2) + ") rotate(-90)", "text-anchor",
             "middle"},
            esc(y_.label));
    double lx = kLeft;
    for (const Style& s : legend_) {
      o += s.line ? el("line", {"x1", lx, "x2", lx + 18, "y1", 31.0, "y2", 31.0, "stroke", s.colour, "stroke-width",
                                2.0, "stroke-dasharray", s.dash})
                  : el("rect", {"x", lx + 4, "y", 25.0, "width", 10.0, "height", 10.0, "fill", s.colour});
      o += el("text", {"x", lx + 23, "y", 35.0}, esc(s.name));
      lx += 36 + 6.2 * static_cast<double>(s.name.size());
    }
    return el("svg",
              {"id", id_, "class", "plot", "viewBox", "0 0 " + px(w_) + " " + px(h_), "width", w_, "height", h_, "role",
               "img", "aria-label", title_},
              o);
  }

 private:
  static double map(const Axis& a, double v, double p0, double p1) {
    if (!finite(v) || (a.log && (v <= 0 || a.lo <= 0))) return kNaN;
    auto t = [&](double u) { return a.log ? std::log10(u) : u; };
    return p0 + (p1 - p0) * (t(v) - t(a.lo)) / (t(a.hi) - t(a.lo));
  }
  std::string id_, title_;
  Axis x_, y_;
  double w_, h_, top_;
  std::string body_;
  std::vector<Style> legend_;
};

struct Bars {
  std::string name, colour;
  Series v;
};
// Grouped bars over categories: slot i centred at category i, the series side by side in 80 % of the slot.
std::string bar_chart(const std::string& id, const std::string& title, const std::vector<std::string>& cats,
                      const std::string& xlabel, const std::vector<Bars>& series, const std::string& ylabel,
                      double w = 1000, double h = 260) {
  Series all;
  for (const auto& s : series) all.insert(all.end(), s.v.begin(), s.v.end());
  Plot p(id, title, category_axis(cats, xlabel), linear_axis(extent({&all}), ylabel, true), w, h);
  const double slot = p.pw() / std::max(1.0, static_cast<double>(cats.size()));
  const double bw = 0.8 * slot / std::max(1.0, static_cast<double>(series.size()));
  p.hline(0.0, "#555");
  for (std::size_t k = 0; k < series.size(); ++k) {
    p.legend({series[k].name, series[k].colour, "", false, false});
    for (std::size_t i = 0; i < cats.size() && i < series[k].v.size(); ++i)
      p.bar(p.X(static_cast<double>(i)) - 0.4 * slot + (static_cast<double>(k) + 0.5) * bw, bw * 0.92, series[k].v[i],
            series[k].colour, cats[i] + ", " + series[k].name + ": " + db(series[k].v[i]) + " dB");
  }
  return p.svg();
}

// Diverging colour, blue - near white - red, for t in [-1, 1].
std::string diverging(double t) {
  static const int stops[5][3] = {{33, 102, 172}, {103, 169, 207}, {247, 247, 247}, {239, 138, 98}, {178, 24, 43}};
  const double u = (std::clamp(finite(t) ? t : 0.0, -1.0, 1.0) + 1.0) * 2.0;
  const int i = std::min(3, static_cast<int>(u));
  int c[3];
  for (int k = 0; k < 3; ++k)
    c[k] = static_cast<int>(std::lround(stops[i][k] + (u - i) * (stops[i + 1][k] - stops[i][k])));
  char b[8];
  std::snprintf(b, sizeof b, "#%02x%02x%02x", c[0], c[1], c[2]);
  return b;
}

// Heat map of rows x bands: the frame is x0 = 130, y0 = 48, pw = 780, ph = 20 * rows; cell (r, c) is the rect at
// x = x0 + c * pw / bands, y = y0 + 20 r, coloured over +-M about 0 dB (M a round number >= the largest |value|);
// null cells hatched grey; `dots` marks cells with a dot.
std::string heat_map(const std::string& id, const std::string& title, const std::vector<std::string>& rows,
                     const Series& hz, const std::vector<Series>& v, const std::vector<std::vector<bool>>& dots) {
  const double left = 130, top = 48, ch = 20, pw = 780, W = 1000;
  const std::size_t nb = hz.size();
  const double cw = pw / std::max(1.0, static_cast<double>(nb)), ph = ch * static_cast<double>(rows.size());
  const double barh = std::max(ph, 120.0), H = top + barh + 48;
  double m = 0;
  for (const auto& r : v)
    for (double x : r)
      if (finite(x)) m = std::max(m, std::fabs(x));
  m = nice_ceil(m);
  const std::string hatch = id + "-hatch", hatch_fill = "url(#" + hatch + ")";
  std::string o = el(
      "defs", {},
      el("pattern",
         {"id", hatch, "width", 6.0, "height", 6.0, "patternUnits", "userSpaceOnUse", "patternTransform", "rotate(45)"},
         el("rect", {"width", 6.0, "height", 6.0, "fill", "#e6e6e6"}) +
             el("line", {"x1", 0.5, "y1", 0.0, "x2", 0.5, "y2", 6.0, "stroke", "#b4b4b4", "stroke-width", 2.0})));
  o += el("text", {"class", "ptitle", "x", left, "y", 16.0}, esc(title));
  o += el("rect", {"x", left, "y", 25.0, "width", 12.0, "height", 12.0, "fill", hatch_fill, "stroke", "#999"}) +
       el("text", {"x", left + 17, "y", 35.0}, "not scored (null)") +
       el("circle", {"cx", left + 140, "cy", 31.0, "r", 2.5, "fill", "#222"}) +
       el("text", {"x", left + 148, "y", 35.0}, "floor-limited band") +
       el("text", {"x", left + 290, "y", 35.0}, "red: measured louder than the baseline predicts; blue: quieter");
  o += el("rect", {"class", "frame", "x", left, "y", top, "width", pw, "height", ph, "fill", "none"});
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const std::string name = rows[r].size() > 20 ? rows[r].substr(0, 19) + "\xE2\x80\xA6" : rows[r];
    o += el("text", {"x", left - 6, "y", top + (static_cast<double>(r) + 0.5) * ch + 4, "text-anchor", "end"},
            esc(name) + tip(rows[r]));
    for (std::size_t c = 0; c < nb; ++c) {
      const double val = r < v.size() ? at(v[r], c, kNaN) : kNaN;
      const double x = left + static_cast<double>(c) * cw, y = top + static_cast<double>(r) * ch;
      o += el("rect",
              {"x", x, "y", y, "width", cw, "height", ch, "fill", finite(val) ? diverging(val / m) : hatch_fill,
               "stroke", "#fff", "stroke-width", 0.5},
              tip(rows[r] + ", " + sig(hz[c]) + " Hz: " + (finite(val) ? db(val) + " dB" : "not scored")));
      if (r < dots.size() && at(dots[r], c, false))
        o += el("circle", {"cx", x + cw / 2, "cy", y + ch / 2, "r", 2.5, "fill", "#222"});
    }
  }
  for (const Tick& t : band_axis(hz).ticks)  // columns are bands: label those at the standard centres
    for (std::size_t c = 0; c < nb && !t.label.empty(); ++c)
      if (hz[c] > 0 && std::fabs(std::log10(hz[c] / t.v)) < 0.03) {
        const double x = left + (static_cast<double>(c) + 0.5) * cw;
        o += el("line", {"class", "tick", "x1", x, "x2", x, "y1", top + ph, "y2", top + ph + 5}) +
             el("text", {"x", x, "y", top + ph + 17, "text-anchor", "middle"}, esc(t.label));
      }
  o += el("text", {"class", "alabel", "x", left + pw / 2, "y", top + ph + 36, "text-anchor", "middle"},
          "1/3-octave band centre (Hz)");
  const double bx = left + pw + 30;  // the colour bar: +M at the top, -M at the bottom
  for (int i = 0; i < 40; ++i)
    o += el("rect", {"x", bx, "y", top + barh * i / 40, "width", 14.0, "height", barh / 40 + 0.3, "fill",
                     diverging(1.0 - (i + 0.5) / 20)});
  o += el("rect", {"x", bx, "y", top, "width", 14.0, "height", barh, "fill", "none", "stroke", "#888"}) +
       el("text", {"x", bx, "y", top - 6}, "dB");
  for (int i = 0; i <= 4; ++i) {
    const double val = m * (1.0 - 0.5 * i), y = top + barh * i / 4.0;
    o += el("line", {"class", "tick", "x1", bx + 14, "x2", bx + 18, "y1", y, "y2", y}) +
         el("text", {"x", bx + 21, "y", y + 4}, (val > 0 ? "+" : "") + fixed(val, m < 2 ? 2 : 1));
  }
  return el("svg",
            {"id", id, "class", "plot", "viewBox", "0 0 " + px(W) + " " + px(H), "width", W, "height", H, "role", "img",
             "aria-label", title},
            o);
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
std::string candidates(Page& pg, const json& r, bool band) {
  const json& v = get(r, "verdict");
  const std::string effect = text(get(v, "effect"));
  const double after = num(get(v, "heldout_rms_after_db"));
  std::vector<std::string> verdict_set{effect};
  for (const auto& a : texts(get(v, "also"))) verdict_set.push_back(a);
  auto effects_of = [](const json& c) {
    std::vector<std::string> e = texts(get(c, "effects"));
    if (e.empty()) e.push_back(text(get(c, "effect")));
    return e;
  };
  // The verdict's row: the combination of the verdict with its "also" effects when one was scored (band mode),
  // else the first first-round candidate of the verdict's effect.
  const json* target = nullptr;
  if (band && verdict_set.size() > 1)
    for (const json& c : get(r, "combinations"))
      if (!target && c.is_object() && effects_of(c) == verdict_set) target = &c;
  for (const json& c : get(r, "candidates"))
    if (!target && c.is_object() && !effect.empty() && effects_of(c).front() == effect && !flag(get(c, "second_round")))
      target = &c;
  const std::string u = esc(pg.units);
  const std::string head =
      band ? row({"effect", "held-out gap (dB)", "thesis metric (dB)", "train (dB)", "closed", "significant",
                  "win fraction", "improvement, p05 (dB)", "closes: bands / mics / windows (dB)", "parameters"},
                 "", "th")
           : row({"effect", "held-out RMS (" + u + ")", "closed", "significant", "p-value", "round", "parameters"}, "",
                 "th");
  std::string body;
  if (const json& b = get(r, "baseline"); b.is_object()) {
    const std::string name = "<i>baseline (" + esc(text(get(b, "model"))) + ")</i>";
    body += band ? row({name, db(num(get(b, "heldout_rms_db"))), db(num(get(b, "heldout_thesis_rms_db"))),
                        db(num(get(b, "train_rms_db"))), "", "", "", "", "", param_count(b)},
                       "base")
                 : row({name, pg.val(num(get(b, "heldout_rms_db"))), "", "", "", "", param_count(b)}, "base");
  }
  bool any = false;
  auto emit = [&](const json& c, bool combination) {
    if (!c.is_object()) return;
    any = true;
    std::string name;
    for (const auto& e : effects_of(c)) name += (name.empty() ? "" : " + ") + esc(e);
    const bool second = flag(get(c, "second_round"));
    const double h = num(get(c, "heldout_rms_db"));
    if (combination) name += "<span class=\"tag\">combination</span>";
    if (second) name += "<span class=\"tag\">2nd round</span>";
    if (&c == target) name += "<span class=\"tag vt\">verdict</span>";
    if (finite(h) && finite(after) && std::fabs(h - after) <= 1e-9 * std::fabs(after))
      name += "<span class=\"tag\">= after</span>";
    if (flag(get(c, "thesis_metric_worse"))) name += "<span class=\"tag\">thesis metric worse</span>";
    if (const std::string e = text(get(c, "error")); !e.empty()) name += el("div", {"class", "small err"}, esc(e));
    const json& closes = get(c, "closes_db");
    const std::string parts = closes.is_object() ? db(num(get(closes, "thesis_bands"))) + " / " +
                                                       db(num(get(closes, "mic_calibration"))) + " / " +
                                                       db(num(get(closes, "crank_windows")))
                                                 : "";
    const std::string closed = closed_cell(num(get(c, "gap_closed_fraction")));
    body +=
        band ? row({name, db(h), db(num(get(c, "heldout_thesis_rms_db"))), db(num(get(c, "train_rms_db"))), closed,
                    yesno(get(c, "significant")), fixed(num(get(c, "win_fraction")), 2),
                    db(num(get(c, "improvement_db"))) + ", " + db(num(get(c, "improvement_p05_db"))), parts,
                    param_count(c)},
                   &c == target ? "vrow" : "")
             : row({name, pg.val(h), closed, yesno(get(c, "significant")), sig(num(get(c, "p_value")), 2),
                    second ? "2" : "1", param_count(c)},
                   &c == target ? "vrow" : "");
  };
  for (const json& c : get(r, "candidates")) emit(c, false);
  for (const json& c : get(r, "combinations")) emit(c, true);
  std::string o = table(head, body) + (any ? "" : pg.lack("candidates"));
  o += note(
      band ? "Closed: share of the baseline's held-out gap the candidate removes; closes: by how many dB it reduces "
             "each part of the gap (the thesis band gap, the microphone-calibration residual, the crank-window gap; "
             "negative: it makes that part worse). Significant: the bootstrap win fraction and the improvement pass "
             "the thresholds in the protocol, and the held-out thesis metric is not worse than the baseline's."
           : "Closed: share of the held-out RMS removed (2nd-round candidates are fitted on top of the first-round "
             "winner; their share is relative to it). &ldquo;= after&rdquo; marks the model whose held-out RMS "
             "the verdict reports as after.");
  if (const json& na = get(r, "not_applicable"); na.is_array() && !na.empty()) {
    std::string rows;
    for (const json& n : na) rows += row({esc(text(get(n, "effect"))), esc(text(get(n, "reason")))});
    o += el("h3", {}, "Not applicable to this data") + table(row({"effect", "reason"}, "", "th"), rows, "txt");
  }
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
  return section("floors", "Floors (never fitted, never scored)",
                 el("ul", {}, lines) + table(head, rows, "txt") +
                     note("Microphone floor from the " + esc(text(get(f, "mic_floor_source"))) +
                          ". A band is floor-limited where the microphones are within the margin of the background "
                          "runs' level, or the cylinder pressure within the margin of the pressure chain's floor (every "
                          "prediction subtracts what that floor drives; cells within the margin are upper bounds)."));
}

// 3. Band mode: the gap map, attenuation curves, per-band gap, microphones, smaller panels, conditions.
std::string band_sections(Page& pg, const json& r) {
  const json& w = get(r, "where");
  if (!w.is_object()) return section("where", "Where the gap is", pg.lack("where (the per-band figures)"));
  const Series hz = nums(get(w, "bands_hz"));
  const auto gap = rows_of(get(w, "gap_db"));
  std::vector<std::string> held = texts(get(w, "heldout_conditions"));
  for (std::size_t i = held.size(); i < gap.size(); ++i) held.push_back("condition " + std::to_string(i + 1));
  std::vector<std::vector<bool>> floor_held;  // floor_limited is indexed like where.conditions: map it by name
  for (const auto& h : held) {
    floor_held.emplace_back();
    std::size_t k = 0;
    for (const json& c : get(w, "conditions")) {
      const json& f = get(w, "floor_limited");
      if (text(get(c, "name")) == h && f.is_array() && k < f.size() && f[k].is_array())
        for (const json& x : f[k]) floor_held.back().push_back(flag(x));
      ++k;
    }
  }
  std::string o, s;

  // a. the gap map, and the band notes
  s = hz.empty() || gap.empty() ? pg.lack(hz.empty() ? "where.bands_hz" : "where.gap_db")
                                : heat_map("gap-map",
                                           "Baseline gap, measured \xE2\x88\x92 predicted level (dB), "
                                           "held-out condition \xC3\x97 band",
                                           held, hz, gap, floor_held);
  std::vector<std::pair<std::string, std::string>> notes;  // note, its bands
  const auto band_notes = texts(get(w, "band_notes"));
  for (std::size_t i = 0; i < band_notes.size(); ++i) {
    if (band_notes[i].empty()) continue;
    auto it = std::find_if(notes.begin(), notes.end(), [&](const auto& n) { return n.first == band_notes[i]; });
    if (it == notes.end()) it = notes.insert(notes.end(), {band_notes[i], ""});
    it->second += (it->second.empty() ? "" : ", ") + hz_label(at(hz, i, kNaN));
  }
  for (const auto& [n, bands] : notes) s += note("Band note <b>" + esc(n) + "</b>: " + bands + " Hz");
  o += section("gap-map-section", "Where the gap is: band \xC3\x97 condition", s);

  // b. attenuation curves, one small plot per held-out condition
  const auto meas = rows_of(get(w, "att_meas_db")), base = rows_of(get(w, "att_baseline_db")),
             best = rows_of(get(w, "att_best_db"));
  const std::string best_name =
      text(get(w, "best_model")).empty() ? "best candidate" : "best: " + text(get(w, "best_model"));
  if (meas.empty() || hz.empty()) {
    s = pg.lack("where.att_meas_db");
  } else {
    s = "<p class=\"legend\"><span style=\"color:" + std::string(kMeasured) +
        "\">&#9679; measured</span><span style=\"color:" + kBaseline +
        "\">&#8211; &#8211; baseline</span><span style=\"color:" + kBest + "\">&mdash;&mdash; " + esc(best_name) +
        "</span>attenuation = CPL &minus; SPL<sub>A</sub></p><div class=\"grid\">";
    for (std::size_t i = 0; i < meas.size(); ++i) {
      const Series bi = at(base, i, Series{}), ti = at(best, i, Series{});
      Plot p("att-" + std::to_string(i), at(held, i, "condition " + std::to_string(i + 1)), band_axis(hz, true),
             linear_axis(extent({&meas[i], &bi, &ti}), "attenuation (dB)"), 330, 212, 26);
      p.line(hz, bi, {"", kBaseline, "5 3", false});
      p.line(hz, ti, {"", kBest, "", false});
      p.line(hz, meas[i], {"", kMeasured, "", true, false}, band_tips(hz, meas[i], "measured", " dB"));
      s += p.svg();
    }
    s += "</div>" + (best.empty() ? pg.lack("where.att_best_db (the best candidate's curves)") : "");
  }
  o += section("attenuation", "Attenuation: measured vs baseline vs best candidate", s);

  // c. per-band gap before / after: a pair of bars filling 80 % of each band's width
  const json& v = get(r, "verdict");
  const auto before = nums(get(v, "band_before_db")), after = nums(get(v, "band_after_db"));
  if (before.empty() || hz.empty()) {
    s = pg.lack("verdict.band_before_db");
  } else {
    Plot p("band-gap", "Per-band held-out gap, RMS over held-out conditions", band_axis(hz),
           linear_axis(extent({&before, &after}), "gap RMS (dB)", true));
    for (std::size_t i = 0; i < hz.size(); ++i) {
      const double bw = 0.4 * (p.X(hz[i] * kEdge) - p.X(hz[i] / kEdge)), b = at(before, i, kNaN),
                   a = at(after, i, kNaN);
      p.bar(p.X(hz[i]) - bw / 2, bw, b, kBaseline, sig(hz[i]) + " Hz, before: " + db(b) + " dB");
      p.bar(p.X(hz[i]) + bw / 2, bw, a, kBest, sig(hz[i]) + " Hz, after: " + db(a) + " dB");
    }
    p.legend({"before (baseline)", kBaseline, "", false, false});
    p.legend({"after (" + best_name + ")", kBest, "", false, false});
    s = p.svg();
  }
  o += section("band-gap-section", "Per-band gap before and after", s);

  // d. microphones
  const auto offs = nums(get(w, "mic_offset_db")), mic_rms = nums(get(w, "mic_gap_rms_db"));
  std::vector<std::string> mics = texts(get(w, "mics"));
  for (std::size_t i = mics.size(); i < std::max(offs.size(), mic_rms.size()); ++i)
    mics.push_back("mic " + std::to_string(i + 1));
  if (mics.empty()) {
    s = pg.lack("where.mic_offset_db");
  } else {
    s = bar_chart(
        "mic-offsets", "Per microphone: mean offset from the array and own-curve gap RMS", mics, "microphone",
        {{"offset from the array mean", kGreen, offs}, {"own-curve gap RMS (thesis metric)", kPurple, mic_rms}}, "dB");
    const auto mb = column_mean(rows_of(get(w, "mic_residual_baseline_db")), mics.size()),
               mt = column_mean(rows_of(get(w, "mic_residual_best_db")), mics.size());
    if (const auto [lo, hi] = extent({&mb, &mt}); lo == 0.0 && hi == 0.0)
      s += note(
          "Calibration residuals (mean over held-out conditions): 0.00 dB for every microphone, baseline and best "
          "model.");
    else if (finite(lo))
      s += bar_chart("mic-residuals", "Per microphone: calibration residual, mean over held-out conditions", mics,
                     "microphone", {{"baseline", kBaseline, mb}, {best_name, kBest, mt}}, "residual (dB)");
  }
  o += section("mics", "Microphones", s);

  // e. smaller panels: gap vs level, crank windows, coherence, noise floor
  s.clear();
  const json& amp = get(w, "amplitude");
  const auto cpl = nums(get(amp, "cpl_overall_db")), mg = nums(get(amp, "mean_gap_db"));
  const double slope = num(get(amp, "slope_db_per_db"));
  if (cpl.empty()) {
    s += pg.lack("where.amplitude");
  } else {
    Plot p("gap-vs-level", "Mean gap vs input level", linear_axis(extent({&cpl}), "overall CPL (dB)"),
           linear_axis(extent({&mg}), "mean gap (dB)", true), 500, 260);
    std::vector<std::string> tips;
    double mx = 0, my = 0, n = 0;
    for (std::size_t i = 0; i < cpl.size(); ++i) {
      tips.push_back(at(held, i, std::string("condition")) + ": CPL " + db(cpl[i]) + " dB, mean gap " +
                     db(at(mg, i, kNaN)) + " dB");
      if (finite(cpl[i]) && finite(at(mg, i, kNaN))) mx += cpl[i], my += mg[i], ++n;
    }
    if (finite(slope) && n > 1) {  // the slope drawn through the centroid (where a least-squares line passes)
      const double a = p.x_axis().lo, b = p.x_axis().hi;
      p.line({a, b}, {my / n + slope * (a - mx / n), my / n + slope * (b - mx / n)}, {"slope", "#999", "4 3", false});
    }
    p.line(cpl, mg, {"held-out condition", kBest, "", true, false}, tips);
    s += "<div>" + p.svg() +
         note("Slope " + sig(slope, 3) +
              " dB/dB across held-out conditions (dashed, through their "
              "centroid); per cycle within conditions " +
              sig(num(get(amp, "cycle_slope_db_per_db")), 3) + " dB/dB; vs speed " +
              sig(num(get(w, "speed_slope_db_per_krpm")), 3) + " dB/krpm, vs injection timing " +
              sig(num(get(w, "soi_slope_db_per_deg")), 3) + " dB/deg BTDC, vs load " +
              sig(num(get(w, "load_slope_db_per_nm")), 3) + " dB/(N m).") +
         "</div>";
  }
  const auto start = nums(get(get(w, "crank_windows"), "start_deg")), wg = nums(get(get(w, "crank_windows"), "gap_db"));
  if (wg.empty()) {
    s += pg.lack("where.crank_windows");
  } else {
    std::vector<std::string> cats;
    for (std::size_t i = 0; i < wg.size(); ++i) cats.push_back(finite(at(start, i, kNaN)) ? fixed(start[i], 0) : "?");
    s += "<div>" +
         bar_chart("crank-windows", "Mean baseline gap per crank window", cats, "window start (\xC2\xB0 crank angle)",
                   {{"gap", kBaseline, wg}}, "gap (dB)", 500, 260) +
         "</div>";
  }
  const json& coh = get(w, "coherence");
  const auto cf = nums(get(coh, "coherent_fraction")), ps = nums(get(coh, "periodic_share")),
             fc = nums(get(coh, "fluctuation_coherence"));
  if (cf.empty() || hz.empty()) {
    s += pg.lack("where.coherence");
  } else {
    Axis ax = linear_axis(extent({&cf, &ps, &fc}), "fraction");
    ax.hi = std::max(ax.hi, 1.0);
    Plot p("coherence", "Coherence per band (mean over fired conditions)", band_axis(hz, true), ax, 500, 260);
    p.line(hz, cf, {"coherent fraction", kBest, ""}, band_tips(hz, cf, "coherent fraction", ""));
    p.line(hz, ps, {"periodic share", kGreen, "5 3", false});
    p.line(hz, fc, {"fluctuation coherence", kPurple, "2 2", false});
    s += "<div>" + p.svg() + "</div>";
  }
  const auto fl = nums(get(get(w, "noise_floor"), "combustion_independent_db")),
             bg = nums(get(get(w, "noise_floor"), "background_db"));
  if (fl.empty() || hz.empty()) {
    s += pg.lack("where.noise_floor");
  } else {
    Plot p("noise-floor", "Noise floor per band", band_axis(hz, true), linear_axis(extent({&fl, &bg}), "level (dB)"),
           500, 260);
    p.line(hz, fl, {"combustion-independent (motored excess)", kMeasured, ""},
           band_tips(hz, fl, "combustion-independent", " dB"));
    p.line(hz, bg, {"background run", kGreen, "5 3"}, band_tips(hz, bg, "background", " dB"));
    const auto mf = nums(get(get(w, "floors"), "mic_floor_db"));
    if (!mf.empty()) p.line(hz, mf, {"microphone floor", kPurple, "2 2", false}, band_tips(hz, mf, "microphone floor", " dB"));
    s += "<div>" + p.svg() + (finite(extent({&bg}).first) ? "" : note("Background run: none (all null).")) + "</div>";
  }
  o += section("panels", "Gap vs level, crank angle, coherence, noise floor", el("div", {"class", "grid2"}, s));

  // f. conditions
  const json& conds = get(w, "conditions");
  s.clear();
  for (const json& c : conds)
    if (c.is_object())
      s += row({esc(text(get(c, "name"))), esc(text(get(c, "role"))), fixed(num(get(c, "speed_rpm")), 0),
                fixed(num(get(c, "load_nm")), 1), fixed(num(get(c, "soi_deg_btdc")), 1), yesno(get(c, "motored")),
                yesno(get(c, "background")), esc(text(get(c, "cycles"))), esc(text(get(c, "mics")))});
  o += section("conditions", "Conditions",
               s.empty() ? pg.lack("where.conditions")
                         : table(row({"name", "role", "speed (rpm)", "load (N m)", "SOI (\xC2\xB0 BTDC)", "motored",
                                      "background", "cycles", "mics"},
                                     "", "th"),
                                 s, "txt"));
  o += floors_section(pg, get(w, "floors"), conds);
  return o;
}

// 4. Waveform mode: per-band error, error vs amplitude, test sets, explainable gap.
std::string waveform_sections(Page& pg, const json& r) {
  const json& w = get(r, "where");
  if (!w.is_object()) return section("where", "Where the error is", pg.lack("where (the per-band figures)"));
  const std::string u = pg.units.empty() ? "data units" : pg.units;
  std::string o, s;
  const auto hz = nums(get(w, "bands_hz")), out = nums(get(w, "output_rms")), eb = nums(get(w, "error_rms_before")),
             ea = nums(get(w, "error_rms_after"));
  if (const auto [flo, fhi] = extent({&hz}, true); !finite(flo)) {
    s = pg.lack("where.bands_hz");
  } else {
    const auto [lo, hi] = extent({&out, &eb, &ea}, true);
    Plot p("band-error", "Per-band free-run error before / after vs output RMS",
           log_axis(flo / kEdge, fhi * kEdge, "1/3-octave band centre (Hz)", false),
           log_axis(lo, hi, "RMS (" + u + ")", true, 2.2), 1000, 320);
    auto tips = [&](const Series& y, const std::string& what) {
      std::vector<std::string> t;
      for (std::size_t i = 0; i < hz.size(); ++i)
        t.push_back(sig(hz[i]) + " Hz, " + what + ": " + sig(at(y, i, kNaN)) + " " + u);
      return t;
    };
    p.line(hz, out, {"output RMS", "#9a9a9a", "5 3"}, tips(out, "output RMS"));
    p.line(hz, eb, {"error before (baseline)", kBaseline, ""}, tips(eb, "error before"));
    p.line(hz, ea, {"error after", kBest, ""}, tips(ea, "error after"));
    s = p.svg();
  }
  o += section("band-error-section", "Where the error is: per band", s);

  const json& amp = get(w, "amplitude");
  Series mid, b, a, los, his;
  std::string rows;
  for (const json& g : amp) {
    if (!g.is_object()) continue;
    los.push_back(num(get(g, "level_lo"))), his.push_back(num(get(g, "level_hi")));
    mid.push_back(0.5 * (los.back() + his.back()));
    b.push_back(num(get(g, "error_rms_before"))), a.push_back(num(get(g, "error_rms_after")));
    rows += row({sig(los.back()), sig(his.back()), esc(text(get(g, "samples"))), sig(b.back()), sig(a.back()),
                 pct(a.back() / b.back())});
  }
  if (mid.empty()) {
    s = pg.lack("where.amplitude");
  } else {
    const auto [lo, hi] = extent({&b, &a}, true);
    Plot p("amplitude-error", "Free-run error vs local output level (equally populated bins, marker at bin centre)",
           linear_axis(extent({&los, &his}), "local output level, RMS (" + u + ")", true),
           log_axis(lo, hi, "error RMS (" + u + ")", true, 2.2), 1000, 280);
    std::vector<std::string> tb, ta;
    for (std::size_t i = 0; i < mid.size(); ++i) {
      const std::string level = "level " + sig(los[i]) + "\xE2\x80\x93" + sig(his[i]);
      tb.push_back(level + ", before: " + sig(b[i]) + " " + u), ta.push_back(level + ", after: " + sig(a[i]) + " " + u);
      for (const auto& [y, c] : {std::pair{b[i], kBaseline}, std::pair{a[i], kBest}})  // the bin's extent
        if (finite(p.Y(y)) && finite(p.X(los[i])) && finite(p.X(his[i])))
          p.raw(el("line", {"x1", p.X(los[i]), "x2", p.X(his[i]), "y1", p.Y(y), "y2", p.Y(y), "stroke", c,
                            "stroke-width", 4.0, "stroke-opacity", 0.35}));
    }
    p.line(mid, b, {"error before (baseline)", kBaseline, ""}, tb);
    p.line(mid, a, {"error after", kBest, ""}, ta);
    s = p.svg() +
        table(row({"level from", "to", "samples", "error before", "error after", "after / before"}, "", "th"), rows);
  }
  o += section("amplitude-section", "Error vs amplitude", s);

  rows.clear();
  for (const json& t : get(r, "test_sets")) {
    if (!t.is_object()) continue;
    const auto range = nums(get(t, "range"));
    const double tb = num(get(t, "baseline_rms")), tt = num(get(t, "best_rms"));
    rows += row({esc(text(get(t, "name"))), range.size() == 2 ? fixed(range[0], 0) + " : " + fixed(range[1], 0) : kDash,
                 sig(tb), sig(tt), pct(tt / tb)});
  }
  o += section("test-sets", "Test sets",
               rows.empty() ? pg.lack("test_sets")
                            : table(row({"test set", "sample range", "baseline free-run RMS (" + esc(u) + ")",
                                         "best model free-run RMS (" + esc(u) + ")", "best / baseline"},
                                        "", "th"),
                                    rows));

  const json& eg = get(w, "explainable_gap");
  if (!eg.is_object()) {
    s = pg.lack("where.explainable_gap");
  } else {
    s = table(row({"model", "explainable share of the error", "p-value", "significant"}, "", "th"),
              row({"baseline", closed_cell(num(get(eg, "baseline_fraction"))), sig(num(get(eg, "baseline_p_value")), 2),
                   yesno(get(eg, "baseline_significant"))}) +
                  row({"best model (remaining)", closed_cell(num(get(eg, "remaining_fraction"))),
                       sig(num(get(eg, "remaining_p_value")), 2), yesno(get(eg, "remaining_significant"))}));
    const auto sb = nums(get(w, "heldout_segment_rms_before")), sa = nums(get(w, "heldout_segment_rms_after"));
    for (std::size_t i = 0; i < sb.size(); ++i)
      s += note("Held-out segment " + std::to_string(i + 1) + ": RMS " + sig(sb[i]) + " &rarr; " +
                sig(at(sa, i, kNaN)) + " " + esc(u));
  }
  o += section("explainable-gap", "Explainable gap", s);
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

}  // namespace noisemon::daemon
