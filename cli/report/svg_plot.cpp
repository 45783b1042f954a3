#include "cli/report/svg_plot.hpp"

#include <algorithm>
#include <cstdio>

namespace noisemon::cli::report::svg {

// ---- Formatting ----

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
std::string sig(double v, int digits) {
  if (!finite(v)) return kDash;
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}
std::string db(double v) { return finite(v) && v != 0.0 && std::fabs(v) < 0.005 ? sig(v, 2) : fixed(v, 2); }
std::string hz_label(double f) { return finite(f) && f >= 1000 ? sig(f / 1000, 3) + "k" : sig(f, 4); }

std::string el(const char* name, std::initializer_list<Val> attrs, const std::string& inner) {
  std::string o = std::string("<") + name;
  for (auto it = attrs.begin(); it != attrs.end() && it + 1 != attrs.end(); it += 2)
    if (!(it + 1)->s.empty()) o += " " + it->s + "=\"" + esc((it + 1)->s) + "\"";
  return inner.empty() ? o + "/>" : o + ">" + inner + "</" + name + ">";
}

// ---- Axes ----

namespace {

double nice_step(double raw) {
  if (!(raw > 0) || !finite(raw)) return 1.0;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * mag >= raw * (1 - 1e-9)) return m * mag;
  return 10.0 * mag;
}
std::string log_label(double v) {  // 0.5, 20, 1e-5 (not 1e-05)
  std::string s = sig(v, 3);
  if (const auto k = s.find("e-0"); k != std::string::npos) s.erase(k + 2, 1);
  if (const auto k = s.find("e+"); k != std::string::npos) s.erase(k + 1, s[k + 2] == '0' ? 2 : 1);
  return s;
}

}  // namespace

std::pair<double, double> extent(std::initializer_list<const Series*> series, bool positive) {
  double lo = kNaN, hi = kNaN;
  for (const Series* s : series)
    for (double v : *s)
      if (finite(v) && (!positive || v > 0))
        lo = finite(lo) ? std::min(lo, v) : v, hi = finite(hi) ? std::max(hi, v) : v;
  return {lo, hi};
}
Axis linear_axis(std::pair<double, double> r, std::string label, bool with_zero) {
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
Axis log_axis(double lo, double hi, std::string label, bool pad, double dense_decades) {
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
const double kBandEdge = std::pow(2.0, 1.0 / 6.0);
Axis band_axis(const Series& hz, bool thin) {
  const auto [f0, f1] = extent({&hz}, true);
  if (!finite(f0)) return log_axis(20.0, 20000.0, "1/3-octave band centre (Hz)", false);
  Axis a{f0 / kBandEdge, f1 * kBandEdge, true, "1/3-octave band centre (Hz)", {}};
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

// ---- Plot ----

void Plot::line(const Series& xs, const Series& ys, const Style& s, const std::vector<std::string>& tips) {
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
    body_ += el("path", {"d", d.substr(1), "fill", "none", "stroke", s.colour, "stroke-width", 1.8, "stroke-dasharray",
                         s.dash});
  body_ += dots;
  legend(s);
}
void Plot::bar(double xc, double wpx, double v, const std::string& colour, const std::string& t) {
  const double y = Y(v), y0 = Y(std::clamp(0.0, y_.lo, y_.hi));
  if (!finite(y) || !finite(xc)) return;
  body_ += el("rect",
              {"x", xc - wpx / 2, "y", std::min(y, y0), "width", wpx, "height", std::max(std::fabs(y0 - y), 0.5),
               "fill", colour},
              tip(t));
}
void Plot::hline(double v, const std::string& colour) {
  if (finite(Y(v))) body_ += el("line", {"x1", kLeft, "x2", kLeft + pw(), "y1", Y(v), "y2", Y(v), "stroke", colour});
}
void Plot::legend(const Style& s) {
  if (!s.name.empty() && std::none_of(legend_.begin(), legend_.end(), [&](const Style& l) { return l.name == s.name; }))
    legend_.push_back(s);
}

std::string Plot::x_ticks() const {
  const double bottom = top_ + ph();
  std::string o;
  for (const Tick& t : x_.ticks) {
    const double x = X(t.v);
    if (!finite(x)) continue;
    if (!t.label.empty() && x_.grid) o += el("line", {"class", "grid", "x1", x, "x2", x, "y1", top_, "y2", bottom});
    o += el("line", {"class", "tick", "x1", x, "x2", x, "y1", bottom, "y2", bottom + (t.label.empty() ? 3 : 5)});
    if (!t.label.empty()) o += el("text", {"x", x, "y", bottom + 16, "text-anchor", "middle"}, esc(t.label));
  }
  return o;
}
std::string Plot::y_ticks() const {
  std::string o;
  for (const Tick& t : y_.ticks) {
    const double y = Y(t.v);
    if (!finite(y)) continue;
    if (!t.label.empty()) o += el("line", {"class", "grid", "x1", kLeft, "x2", kLeft + pw(), "y1", y, "y2", y});
    o += el("line", {"class", "tick", "x1", kLeft - (t.label.empty() ? 3 : 5), "x2", kLeft, "y1", y, "y2", y});
    if (!t.label.empty()) o += el("text", {"x", kLeft - 8, "y", y + 4, "text-anchor", "end"}, esc(t.label));
  }
  return o;
}
std::string Plot::axis_labels() const {
  return el("text", {"class", "alabel", "x", kLeft + pw() / 2, "y", h_ - 8, "text-anchor", "middle"}, esc(x_.label)) +
         el("text",
            {"class", "alabel", "transform", "translate(14 " + px(top_ + ph() / 2) + ") rotate(-90)", "text-anchor",
             "middle"},
            esc(y_.label));
}
std::string Plot::legend_row() const {
  std::string o;
  double lx = kLeft;
  for (const Style& s : legend_) {
    o += s.line ? el("line", {"x1", lx, "x2", lx + 18, "y1", 31.0, "y2", 31.0, "stroke", s.colour, "stroke-width", 2.0,
                              "stroke-dasharray", s.dash})
                : el("rect", {"x", lx + 4, "y", 25.0, "width", 10.0, "height", 10.0, "fill", s.colour});
    o += el("text", {"x", lx + 23, "y", 35.0}, esc(s.name));
    lx += 36 + 6.2 * static_cast<double>(s.name.size());
  }
  return o;
}
std::string Plot::svg() const {
  std::string o = el("text", {"class", "ptitle", "x", kLeft, "y", 16.0}, esc(title_)) +
                  el("rect", {"class", "frame", "x", kLeft, "y", top_, "width", pw(), "height", ph(), "fill", "#fff"});
  o += x_ticks();
  o += y_ticks();
  o += body_ + el("rect", {"x", kLeft, "y", top_, "width", pw(), "height", ph(), "fill", "none", "stroke", "#888"});
  o += axis_labels();
  o += legend_row();
  return el("svg",
            {"id", id_, "class", "plot", "viewBox", "0 0 " + px(w_) + " " + px(h_), "width", w_, "height", h_, "role",
             "img", "aria-label", title_},
            o);
}
double Plot::map(const Axis& a, double v, double p0, double p1) {
  if (!finite(v) || (a.log && (v <= 0 || a.lo <= 0))) return kNaN;
  auto t = [&](double u) { return a.log ? std::log10(u) : u; };
  return p0 + (p1 - p0) * (t(v) - t(a.lo)) / (t(a.hi) - t(a.lo));
}

std::string bar_chart(const std::string& id, const std::string& title, const std::vector<std::string>& cats,
                      const std::string& xlabel, const std::vector<Bars>& series, const std::string& ylabel, double w,
                      double h) {
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

// ---- Heat map ----

namespace {

double nice_ceil(double x) {  // a round number >= x (the colour scale's end)
  if (!(x > 0) || !finite(x)) return 1.0;
  const double mag = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0})
    if (m * mag >= x * (1 - 1e-9)) return m * mag;
  return 10.0 * mag;
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

template <class T>
T at(const std::vector<T>& v, std::size_t i, T fallback) {
  return i < v.size() ? v[i] : fallback;
}

// The heat map's geometry (see heat_map) and colour scale.
struct HeatGrid {
  static constexpr double kLeftEdge = 130, kTop = 48, kCellHeight = 20, kWidth = 780, kSvgWidth = 1000;
  std::size_t bands;
  double cell_width, height, bar_height, svg_height;
  double scale;  // M: +-M spans the colours
  std::string hatch_fill;
};

HeatGrid heat_grid(const std::string& id, std::size_t rows, std::size_t bands, const std::vector<Series>& v) {
  HeatGrid g;
  g.bands = bands;
  g.cell_width = HeatGrid::kWidth / std::max(1.0, static_cast<double>(bands));
  g.height = HeatGrid::kCellHeight * static_cast<double>(rows);
  g.bar_height = std::max(g.height, 120.0);
  g.svg_height = HeatGrid::kTop + g.bar_height + 48;
  double m = 0;
  for (const auto& r : v)
    for (double x : r)
      if (finite(x)) m = std::max(m, std::fabs(x));
  g.scale = nice_ceil(m);
  g.hatch_fill = "url(#" + id + "-hatch)";
  return g;
}

// The hatch pattern, the title and the key row.
std::string heat_head(const std::string& id, const std::string& title, const HeatKey& key) {
  const double left = HeatGrid::kLeftEdge;
  const std::string hatch = id + "-hatch", hatch_fill = "url(#" + hatch + ")";
  std::string o = el(
      "defs", {},
      el("pattern",
         {"id", hatch, "width", 6.0, "height", 6.0, "patternUnits", "userSpaceOnUse", "patternTransform", "rotate(45)"},
         el("rect", {"width", 6.0, "height", 6.0, "fill", "#e6e6e6"}) +
             el("line", {"x1", 0.5, "y1", 0.0, "x2", 0.5, "y2", 6.0, "stroke", "#b4b4b4", "stroke-width", 2.0})));
  o += el("text", {"class", "ptitle", "x", left, "y", 16.0}, esc(title));
  o += el("rect", {"x", left, "y", 25.0, "width", 12.0, "height", 12.0, "fill", hatch_fill, "stroke", "#999"}) +
       el("text", {"x", left + 17, "y", 35.0}, key.null_cells) +
       el("circle", {"cx", left + 140, "cy", 31.0, "r", 2.5, "fill", "#222"}) +
       el("text", {"x", left + 148, "y", 35.0}, key.dotted_cells) +
       el("text", {"x", left + 290, "y", 35.0}, key.colours);
  return o;
}

// The row names and the cells, with their dots.
std::string heat_cells(const HeatGrid& g, const std::vector<std::string>& rows, const Series& hz,
                       const std::vector<Series>& v, const std::vector<std::vector<bool>>& dots, const HeatKey& key) {
  const double left = HeatGrid::kLeftEdge, top = HeatGrid::kTop, ch = HeatGrid::kCellHeight, cw = g.cell_width;
  std::string o;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const std::string name = rows[r].size() > 20 ? rows[r].substr(0, 19) + "\xE2\x80\xA6" : rows[r];
    o += el("text", {"x", left - 6, "y", top + (static_cast<double>(r) + 0.5) * ch + 4, "text-anchor", "end"},
            esc(name) + tip(rows[r]));
    for (std::size_t c = 0; c < g.bands; ++c) {
      const double val = r < v.size() ? at(v[r], c, kNaN) : kNaN;
      const double x = left + static_cast<double>(c) * cw, y = top + static_cast<double>(r) * ch;
      o += el("rect",
              {"x", x, "y", y, "width", cw, "height", ch, "fill", finite(val) ? diverging(val / g.scale) : g.hatch_fill,
               "stroke", "#fff", "stroke-width", 0.5},
              tip(rows[r] + ", " + sig(hz[c]) + " Hz: " + (finite(val) ? db(val) + " dB" : key.null_tip)));
      if (r < dots.size() && at(dots[r], c, false))
        o += el("circle", {"cx", x + cw / 2, "cy", y + ch / 2, "r", 2.5, "fill", "#222"});
    }
  }
  return o;
}

// Columns are bands: labelled where a band is one of the standard centres.
std::string heat_band_labels(const HeatGrid& g, const Series& hz) {
  const double left = HeatGrid::kLeftEdge, top = HeatGrid::kTop, ph = g.height;
  std::string o;
  for (const Tick& t : band_axis(hz).ticks)
    for (std::size_t c = 0; c < g.bands && !t.label.empty(); ++c)
      if (hz[c] > 0 && std::fabs(std::log10(hz[c] / t.v)) < 0.03) {
        const double x = left + (static_cast<double>(c) + 0.5) * g.cell_width;
        o += el("line", {"class", "tick", "x1", x, "x2", x, "y1", top + ph, "y2", top + ph + 5}) +
             el("text", {"x", x, "y", top + ph + 17, "text-anchor", "middle"}, esc(t.label));
      }
  o += el("text", {"class", "alabel", "x", left + HeatGrid::kWidth / 2, "y", top + ph + 36, "text-anchor", "middle"},
          "1/3-octave band centre (Hz)");
  return o;
}

// The colour bar: +M at the top, -M at the bottom.
std::string heat_colour_bar(const HeatGrid& g) {
  const double top = HeatGrid::kTop, barh = g.bar_height, m = g.scale;
  const double bx = HeatGrid::kLeftEdge + HeatGrid::kWidth + 30;
  std::string o;
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
  return o;
}

}  // namespace

std::string heat_map(const std::string& id, const std::string& title, const std::vector<std::string>& rows,
                     const Series& hz, const std::vector<Series>& v, const std::vector<std::vector<bool>>& dots,
                     const HeatKey& key) {
  const HeatGrid g = heat_grid(id, rows.size(), hz.size(), v);
  std::string o = heat_head(id, title, key);
  o += el("rect", {"class", "frame", "x", HeatGrid::kLeftEdge, "y", HeatGrid::kTop, "width", HeatGrid::kWidth, "height",
                   g.height, "fill", "none"});
  o += heat_cells(g, rows, hz, v, dots, key);
  o += heat_band_labels(g, hz);
  o += heat_colour_bar(g);
  const double W = HeatGrid::kSvgWidth, H = g.svg_height;
  return el("svg",
            {"id", id, "class", "plot", "viewBox", "0 0 " + px(W) + " " + px(H), "width", W, "height", H, "role", "img",
             "aria-label", title},
            o);
}

}  // namespace noisemon::cli::report::svg
