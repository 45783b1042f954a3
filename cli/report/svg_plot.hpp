// A small SVG plotting kit for self-contained pages (no scripts, fonts or URLs): number formatting and HTML
// escaping, elements built from attribute lists, linear, log, 1/3-octave band and category axes, a plot with
// lines, markers, bars and a legend, grouped bar charts and a band heat map. Every marker, bar and cell carries a
// <title> tooltip with its value; nothing here knows what the numbers are (cli/report/report_html.cpp does).
#pragma once

#include <cmath>
#include <initializer_list>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "dsp/math_constants.hpp"

namespace noisemon::cli::report::svg {

using Series = std::vector<double>;
inline bool finite(double v) { return std::isfinite(v); }

// ---- Formatting: a value that is not finite shows as kDash ----

constexpr const char* kDash = "\xE2\x80\x94";  // an em dash: no value
std::string esc(std::string_view s);           // HTML-escaped: & < > " '
std::string fixed(double v, int decimals);     // "%.*f", never "-0.00"
std::string sig(double v, int digits = 4);     // "%.*g"
// dB: 2 decimals; two significant digits below 0.005 (a tiny noise figure is not "0.00").
std::string db(double v);
std::string hz_label(double f);                          // 31.5, 500, 1k, 12.5k
inline std::string px(double v) { return fixed(v, 2); }  // an SVG coordinate

// An element <name k="v" ...>inner</name> (<name .../> without inner) from alternating attribute names and values
// (strings or numbers); attributes with an empty value are left out.
struct Val {
  Val(const char* v) : s(v) {}
  Val(std::string v) : s(std::move(v)) {}
  Val(double v) : s(px(v)) {}
  std::string s;
};
std::string el(const char* name, std::initializer_list<Val> attrs, const std::string& inner = "");
inline std::string tip(const std::string& t) { return el("title", {}, esc(t)); }

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

// Finite (and, for a log axis, positive) extent of several series; NaNs when there is none.
std::pair<double, double> extent(std::initializer_list<const Series*> series, bool positive = false);
Axis linear_axis(std::pair<double, double> r, std::string label, bool with_zero = false);
// Log axis labelled at 1, 2, 5 x 10^k (at 1 x 10^k only beyond dense_decades; at its ends if no label falls inside).
Axis log_axis(double lo, double hi, std::string label, bool pad, double dense_decades = 3.2);
extern const double kBandEdge;  // 1/3-octave band centre to band edge, 2^(1/6)
// Band axis: labels at the standard centres 31.5 ... 16k (every other one when `thin`), minor ticks at every band.
Axis band_axis(const Series& hz, bool thin = false);
Axis category_axis(const std::vector<std::string>& names, std::string label);

// ---- A plot: frame, grid, tick labels, axis titles, a legend row under the title; lines, markers and bars placed
// through the axis mapping above, each marker and bar with a <title> tooltip holding its value.

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
  void line(const Series& xs, const Series& ys, const Style& s, const std::vector<std::string>& tips = {});
  // A bar centred at pixel xc, wpx wide, from the value axis' zero (clamped into the axis) to v.
  void bar(double xc, double wpx, double v, const std::string& colour, const std::string& t);
  void hline(double v, const std::string& colour);
  void raw(const std::string& svg) { body_ += svg; }
  void legend(const Style& s);

  std::string svg() const;

 private:
  static double map(const Axis& a, double v, double p0, double p1);
  std::string x_ticks() const;
  std::string y_ticks() const;
  std::string axis_labels() const;
  std::string legend_row() const;

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
// Grouped bars over categories: slot i centred at category i, the series side by side in 80 % of the slot. The
// tooltips give the values in dB.
std::string bar_chart(const std::string& id, const std::string& title, const std::vector<std::string>& cats,
                      const std::string& xlabel, const std::vector<Bars>& series, const std::string& ylabel,
                      double w = 1000, double h = 260);

// What a heat map's key says: the hatched cells (null values; `null_tip` in their tooltips), the cells with a dot,
// and what the colours mean.
struct HeatKey {
  std::string null_cells, null_tip, dotted_cells, colours;
};
// Heat map of rows x 1/3-octave bands in dB: the frame is x0 = 130, y0 = 48, pw = 780, ph = 20 * rows; cell (r, c)
// is the rect at x = x0 + c * pw / bands, y = y0 + 20 r, coloured blue - white - red over +-M about 0 dB (M a round
// number >= the largest |value|), with a colour bar; null cells hatched grey; `dots` marks cells with a dot.
std::string heat_map(const std::string& id, const std::string& title, const std::vector<std::string>& rows,
                     const Series& hz, const std::vector<Series>& v, const std::vector<std::vector<bool>>& dots,
                     const HeatKey& key);

}  // namespace noisemon::cli::report::svg
