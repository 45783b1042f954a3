// What the verdict leaves unexplained: the held-out gap of the selected model (the baseline's when the verdict is
// `none` or `unexplained`), where it lies and how it scales across the held-out conditions. A name is not the whole
// answer: an engineer reads here whether what remains is noise (small, flat, no trend) or a structure no candidate
// has (a band range, a trend with speed or load).
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kRangeShare = 0.5;  // the band range: bands whose RMS is at least this share of the largest

std::string fixed(double x, int digits) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, x);
  return buf;
}

std::string hz(double f) {
  return f >= 1000.0 ? fixed(f / 1000.0, f >= 10000.0 ? 0 : 1) + " kHz" : fixed(f, 0) + " Hz";
}

// The largest per-band RMS and the contiguous range around it of bands at least kRangeShare of it.
void band_range(const Context& cx, const std::vector<double>& band_rms, RemainingGap& r) {
  const auto& bands = cx.data->bands;
  std::size_t top = band_rms.size();
  for (std::size_t b = 0; b < band_rms.size(); ++b)
    if (std::isfinite(band_rms[b]) && (top == band_rms.size() || band_rms[b] > band_rms[top])) top = b;
  if (top == band_rms.size()) return;
  r.largest_band_hz = bands[top].nominal_hz;
  r.largest_band_db = band_rms[top];
  std::size_t lo = top, hi = top;
  const auto within = [&](std::size_t b) {
    return std::isfinite(band_rms[b]) && band_rms[b] >= kRangeShare * band_rms[top];
  };
  while (lo > 0 && within(lo - 1)) --lo;
  while (hi + 1 < band_rms.size() && within(hi + 1)) ++hi;
  r.from_hz = bands[lo].nominal_hz;
  r.to_hz = bands[hi].nominal_hz;
}

// Mean gap (measured over predicted) per held-out condition against its speed, load and overall input level.
void trends(const Context& cx, const ModelScore& m, RemainingGap& r) {
  std::vector<double> speed, load, level, mean;
  for (std::size_t h = 0; h < cx.heldout.size() && h < m.gaps.size(); ++h) {
    const fit::ConditionData& d = cx.data->conditions[cx.heldout[h]];
    speed.push_back(d.mean_speed_rpm() / 1000.0);
    load.push_back(d.info.load_nm);
    level.push_back(overall_cpl_db(*cx.data, d));
    mean.push_back(mean_finite(m.gaps[h]));
  }
  r.mean_gap_db = mean;
  r.speed_slope_db_per_krpm = linear_slope(speed, mean);
  r.load_slope_db_per_nm = linear_slope(load, mean);
  r.level_slope_db_per_db = linear_slope(level, mean);
}

std::string dominant_part(const ModelScore& m) {
  const double bands = m.part_band_ms, mics = m.part_mic, windows = m.part_window_ms;
  if (mics >= bands && mics >= windows) return "microphones";
  return windows > bands ? "crank windows" : "bands";
}

std::string summary_line(const RemainingGap& r, double tolerance_db) {
  std::string s = "what remains (" + r.model + "): " + fixed(r.gap_db, 2) + " dB held-out gap, mostly in the " + r.part;
  if (r.gap_db <= tolerance_db) s += ", within the tolerance";
  if (std::isfinite(r.largest_band_hz))
    s += "; largest " + fixed(r.largest_band_db, 1) + " dB at " + hz(r.largest_band_hz) +
         (r.from_hz < r.to_hz ? " (" + hz(r.from_hz) + " to " + hz(r.to_hz) + ")" : "");
  if (std::isfinite(r.speed_slope_db_per_krpm)) s += "; " + fixed(r.speed_slope_db_per_krpm, 2) + " dB per krpm";
  if (std::isfinite(r.load_slope_db_per_nm)) s += ", " + fixed(r.load_slope_db_per_nm, 3) + " dB per N m";
  if (std::isfinite(r.level_slope_db_per_db)) s += ", " + fixed(r.level_slope_db_per_db, 2) + " dB per dB of input";
  return s;
}

}  // namespace

RemainingGap describe_remaining(const Context& cx, const ModelScore& after, const std::vector<double>& band_rms) {
  RemainingGap r;
  r.model = after.name;
  r.gap_db = after.heldout_gap_db;
  r.part = dominant_part(after);
  band_range(cx, band_rms, r);
  trends(cx, after, r);
  r.summary = summary_line(r, cx.opt->tolerance_db);
  return r;
}

}  // namespace noisemon::model::diagnosis
