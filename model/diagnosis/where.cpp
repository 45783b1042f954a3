// Where the baseline's gap lies (DiagnosisResult::where, plotted in report.html): the roles and masks, the floors,
// the gap per band and held-out condition, measured and predicted attenuation, the gap against the input level
// (per condition and cycle by cycle), speed, injection timing and load, per microphone, per crank window, and the
// coherent fraction per band.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "dsp/weighting.hpp"
#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kRef2 = 4e-10;  // (20 uPa)^2

double level_db(double ms) { return ms > 0 ? 10.0 * std::log10(ms / kRef2) : kNaN; }

bool contains(const std::vector<std::size_t>& v, std::size_t k) { return std::find(v.begin(), v.end(), k) != v.end(); }

// One line of the floor summary: the conditions whose names share the part before the first '_'.
struct FloorGroup {
  std::string name;
  int runs = 0, bands_min = 1 << 30, bands_max = 0, windows = 0, cells = 0;
  double from_hz = kNaN;
};

// Condition k's pressure floor: how it is judged, stated and estimated, and its level per band.
void report_pressure_floor(const Context& cx, std::size_t k, Where& wh) {
  constexpr double kBar = 1e5;
  const fit::BandDataset& data = *cx.data;
  const fit::ConditionData& d = data.conditions[k];
  const fit::PressureFloor& f = cx.pressure_floors[k];
  const std::size_t nb = data.band_count();
  wh.pressure_floor_judged_by.push_back(f.density.empty() ? "none" : f.stated ? "stated" : "estimated");
  wh.pressure_floor_stated_bar.push_back(f.stated ? d.info.pressure_floor_pa / kBar : kNaN);
  wh.pressure_floor_estimated_bar.push_back(f.estimated_rms_per_sample_pa(d.info.encoder_rate_hz) / kBar);
  wh.pressure_floor_estimated_grid_bar.push_back(f.estimated_rms_on_grid_pa(data) / kBar);
  std::vector<double> lv(nb, kNaN);
  for (std::size_t b = 0; b < nb && b < f.band_ms.size(); ++b) lv[b] = level_db(f.band_ms[b]);
  wh.pressure_floor_db.push_back(lv);
}

// Condition k's cells at a floor, counted into wh and its group.
void count_floor_cells(const Context& cx, std::size_t k, Where& wh, std::vector<FloorGroup>& groups) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  int bands = 0, windows = 0;
  double from = kNaN;
  for (std::size_t b = 0; b < nb; ++b) {
    if (cx.floor_limited[k][b]) {
      ++bands;
      if (!std::isfinite(from) || data.bands[b].nominal_hz < from) from = data.bands[b].nominal_hz;
    }
    if (!cx.fast[b] || !cx.base_mask[k][b]) continue;
    for (std::size_t w = 0; w < kW; ++w) windows += cx.pfloor_win[k][b * kW + w] ? 1 : 0;
  }
  wh.floor_limited_bands.push_back(bands);
  wh.floor_limited_windows.push_back(windows);
  const std::string& name = data.conditions[k].info.name;
  const std::string g = name.substr(0, name.find('_'));
  auto it = std::find_if(groups.begin(), groups.end(), [&](const FloorGroup& x) { return x.name == g; });
  if (it == groups.end()) it = groups.insert(groups.end(), FloorGroup{g});
  ++it->runs;
  it->bands_min = std::min(it->bands_min, bands);
  it->bands_max = std::max(it->bands_max, bands);
  it->windows += windows;
  for (std::size_t b = 0; b < nb; ++b) it->cells += cx.fast[b] && cx.base_mask[k][b] ? static_cast<int>(kW) : 0;
  if (std::isfinite(from) && !(it->from_hz <= from)) it->from_hz = from;
}

std::string summary_line(const FloorGroup& g, std::size_t nb) {
  char line[256];
  const std::string range = g.bands_min == g.bands_max
                                ? std::to_string(g.bands_min)
                                : std::to_string(g.bands_min) + "-" + std::to_string(g.bands_max);
  std::snprintf(
      line, sizeof line,
      "%s (%d run%s): %s of %zu bands floor-limited%s; %d of %d crank-window cells at the pressure floor",
      g.name.c_str(), g.runs, g.runs == 1 ? "" : "s", range.c_str(), nb,
      std::isfinite(g.from_hz) ? (" from " + std::to_string(static_cast<int>(g.from_hz)) + " Hz up").c_str() : "",
      g.windows, g.windows + g.cells);
  return line;
}

// The microphones' floor per band: the background runs' level, else the median quiet-window level of the fired
// training conditions.
void report_mic_floor(const Context& cx, Where& wh) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  wh.mic_floor_db.assign(nb, kNaN);
  const bool has_bg = std::any_of(cx.background_ms.begin(), cx.background_ms.end(), [](double x) { return x > 0; });
  wh.mic_floor_source = has_bg ? "background runs" : "quiet crank windows";
  std::vector<std::vector<double>> quiet;
  if (!has_bg)
    for (std::size_t k : cx.train_fired) quiet.push_back(fit::quiet_window_mic_ms(data, k));
  for (std::size_t b = 0; b < nb; ++b) {
    std::vector<double> v;
    for (const auto& q : quiet)
      if (std::isfinite(q[b])) v.push_back(q[b]);
    wh.mic_floor_db[b] = level_db(has_bg ? cx.background_ms[b] : median(v));
  }
}

// Per condition its name and role; per band its notes, the motored runs' and the background runs' level.
void roles_and_levels(const Context& cx, Where& wh) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  for (std::size_t b = 0; b < nb; ++b) wh.band_hz.push_back(data.bands[b].nominal_hz);
  wh.band_notes = cx.band_notes;
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    const fit::ConditionData& d = data.conditions[k];
    wh.conditions.push_back(d.info.name);
    const bool t = contains(cx.train_fired, k), h = contains(cx.heldout, k);
    wh.roles.push_back(d.info.background ? "floor"
                       : d.info.motored  ? "reference"
                       : t && h          ? "train+heldout"
                       : t               ? "train"
                       : h               ? "heldout"
                                         : "unused");
  }
  wh.scored = cx.base_mask;
  wh.floor_limited = cx.floor_limited;
  wh.noise_dominated = cx.noise_dominated;
  report_floors(cx, wh);
  wh.floor_db.assign(nb, kNaN);
  wh.background_db.assign(nb, kNaN);
  for (std::size_t b = 0; b < nb; ++b) {
    double s = 0.0;
    int n = 0;
    for (std::size_t r : cx.refs) {
      s += cx.motored_excess[r][b];
      ++n;
    }
    if (n > 0 && s > 0) wh.floor_db[b] = 10.0 * std::log10(s / n / 4e-10);
    if (!cx.backgrounds.empty() && cx.background_ms[b] > 0)
      wh.background_db[b] = 10.0 * std::log10(cx.background_ms[b] / 4e-10);
  }
}

// Condition d's measured attenuation and CPL per band, and its overall CPL.
void input_levels(const fit::BandDataset& data, const fit::ConditionData& d, Where& wh) {
  const std::size_t nb = data.band_count(), nc = d.cycle_count();
  std::vector<double> att_m(nb, kNaN), cpl_b(nb, kNaN);
  for (std::size_t b = 0; b < nb; ++b) {
    double c = 0.0, m = 0.0;
    for (std::size_t cy = 0; cy < nc; ++cy) {
      c += d.cpl_ms[cy * nb + b];
      m += d.mic_avg_ms(cy, b);
    }
    if (c > 0 && m > 0) att_m[b] = db(c / m) - dsp::a_weighting_db(data.bands[b].exact_mid_hz);
    if (c > 0) cpl_b[b] = 10.0 * std::log10(c / nc / 4e-10);
  }
  wh.cpl_overall_db.push_back(overall_cpl_db(data, d));
  wh.att_meas.push_back(att_m);
  wh.cpl_db.push_back(cpl_b);
}

// Per cycle of condition k: the mean gap over the scored bands against the cycle's overall CPL, each as its
// deviation from the condition's mean, appended to xs, ys.
void cycle_gap_vs_level(const Context& cx, std::size_t k, const fit::ConditionPrediction& p,
                        std::vector<double>& cycle_x, std::vector<double>& cycle_y) {
  const fit::BandDataset& data = *cx.data;
  const fit::ConditionData& d = data.conditions[k];
  const std::size_t nb = data.band_count(), nc = d.cycle_count();
  std::vector<double> xs, ys;
  for (std::size_t cy = 0; cy < nc; ++cy) {
    double g = 0.0, c = 0.0;
    int nn = 0;
    for (std::size_t b = 0; b < nb; ++b) {
      if (!data.bands[b].nyquist_cut) c += d.cpl_ms[cy * nb + b];
      if (!cx.base_mask[k][b]) continue;
      const double m = d.mic_avg_ms(cy, b), q = p.cycle_ms[cy * nb + b];
      if (m > 0 && q > 0) {
        g += db(m / q);
        ++nn;
      }
    }
    if (nn == 0 || !(c > 0)) continue;
    xs.push_back(10.0 * std::log10(c));
    ys.push_back(g / nn);
  }
  const double mx = xs.empty() ? 0 : std::accumulate(xs.begin(), xs.end(), 0.0) / xs.size();
  const double my = ys.empty() ? 0 : std::accumulate(ys.begin(), ys.end(), 0.0) / ys.size();
  for (std::size_t i = 0; i < xs.size(); ++i) {
    cycle_x.push_back(xs[i] - mx);
    cycle_y.push_back(ys[i] - my);
  }
}

// The baseline's gap per held-out condition, against its input level, speed, injection timing and load.
void gap_against_conditions(const Context& cx, const Evaluated& base, Where& wh) {
  const fit::BandDataset& data = *cx.data;
  std::vector<double> speeds, sois, loads, cycle_x, cycle_y;
  for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
    const fit::ConditionData& d = data.conditions[cx.heldout[h]];
    const std::vector<double>& gaps = base.score.gaps[h];
    wh.gap_per_condition_rms.push_back(fit::rms_db(gaps));
    wh.mean_gap_db.push_back(mean_finite(gaps));
    input_levels(data, d, wh);
    speeds.push_back(d.mean_speed_rpm() / 1000.0);
    sois.push_back(d.info.soi_deg_btdc);
    loads.push_back(d.info.load_nm);
    cycle_gap_vs_level(cx, cx.heldout[h], base.preds[h], cycle_x, cycle_y);
  }
  wh.amplitude_slope_db_per_db = linear_slope(wh.cpl_overall_db, wh.mean_gap_db);
  wh.cycle_amplitude_slope_db_per_db = linear_slope(cycle_x, cycle_y);
  wh.speed_slope_db_per_krpm = linear_slope(speeds, wh.mean_gap_db);
  wh.soi_slope_db_per_deg = linear_slope(sois, wh.mean_gap_db);
  wh.load_slope_db_per_nm = linear_slope(loads, wh.mean_gap_db);
}

// Per microphone: its offset from the array and the thesis metric of its own curve, over the held-out conditions.
void gap_per_microphone(const Context& cx, const Evaluated& base, Where& wh) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count(), M = data.conditions[cx.heldout.front()].mics;
  wh.mic_offset_db.assign(M, 0.0);
  wh.mic_gap_rms_db.assign(M, 0.0);
  for (std::size_t m = 0; m < M; ++m) wh.mics.push_back("mic" + std::to_string(m + 1));
  const fit::ExtendedModel none;
  for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
    const std::size_t k = cx.heldout[h];
    const fit::ConditionData& d = data.conditions[k];
    const std::vector<double> off = mic_offsets(d, measured_side(d, none), cx.base_mask[k], nullptr);
    const std::size_t nc = d.cycle_count();
    for (std::size_t m = 0; m < M && m < d.mics; ++m) {
      wh.mic_offset_db[m] += off[m] / static_cast<double>(cx.heldout.size());
      std::vector<double> g(nb, kNaN);
      for (std::size_t b = 0; b < nb; ++b) {
        if (!cx.base_mask[k][b]) continue;
        double a = 0.0, q = 0.0;
        for (std::size_t cy = 0; cy < nc; ++cy) {
          a += d.mic_ms[(cy * d.mics + m) * nb + b];
          q += base.preds[h].cycle_ms[cy * nb + b];
        }
        if (a > 0 && q > 0) g[b] = db(a / q);
      }
      wh.mic_gap_rms_db[m] += fit::rms_db(g) / static_cast<double>(cx.heldout.size());
    }
  }
}

// Per crank window: the baseline's mean gap over the fast bands, and per band, over the held-out conditions.
void gap_per_window(const ModelScore& baseline, std::size_t nb, Where& wh) {
  wh.window_gap_db.assign(kW, 0.0);
  for (std::size_t w = 0; w < kW; ++w) {
    wh.window_start_deg.push_back(-360.0 + 720.0 * static_cast<double>(w) / kW);
    double s = 0.0;
    int n = 0;
    for (const auto& g : baseline.window_gaps)
      if (std::isfinite(g[w])) {
        s += g[w];
        ++n;
      }
    wh.window_gap_db[w] = n > 0 ? s / n : kNaN;
    std::vector<double> per_band(nb, kNaN);
    for (std::size_t b = 0; b < nb; ++b) {
      double sb = 0.0;
      int nn = 0;
      for (const auto& g : baseline.cell_gaps)
        if (std::isfinite(g[w * nb + b])) sb += g[w * nb + b], ++nn;
      if (nn > 0) per_band[b] = sb / nn;
    }
    wh.window_band_gap_db.push_back(per_band);
  }
}

// Per band, the mean over the fired conditions of the coherent fraction, fluctuation coherence and periodic share.
void coherence(const Context& cx, Where& wh) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  wh.coherent_fraction.assign(nb, 0.0);
  wh.fluct_coherence.assign(nb, 0.0);
  wh.periodic_share.assign(nb, 0.0);
  for (std::size_t b = 0; b < nb; ++b) {
    double a = 0.0, f = 0.0, p = 0.0;
    int n = 0;
    for (std::size_t k : cx.fired) {
      const fit::ConditionData& d = data.conditions[k];
      if (!std::isfinite(d.coherent_fraction[b])) continue;
      a += d.coherent_fraction[b];
      f += d.fluct_coherence[b];
      p += d.periodic_share[b];
      ++n;
    }
    wh.coherent_fraction[b] = n > 0 ? a / n : kNaN;
    wh.fluct_coherence[b] = n > 0 ? f / n : kNaN;
    wh.periodic_share[b] = n > 0 ? p / n : kNaN;
  }
}

}  // namespace

double overall_cpl_db(const fit::BandDataset& data, const fit::ConditionData& d) {
  const std::size_t nb = data.band_count(), nc = d.cycle_count();
  double cpl = 0.0;
  for (std::size_t b = 0; b < nb; ++b) {
    if (data.bands[b].nyquist_cut) continue;
    double c = 0.0;
    for (std::size_t cy = 0; cy < nc; ++cy) c += d.cpl_ms[cy * nb + b];
    cpl += c / nc;
  }
  return 10.0 * std::log10(cpl / 4e-10);
}

double mean_finite(const std::vector<double>& v) {
  double s = 0.0;
  int n = 0;
  for (double x : v)
    if (std::isfinite(x)) {
      s += x;
      ++n;
    }
  return n > 0 ? s / n : kNaN;
}

double linear_slope(const std::vector<double>& xs, const std::vector<double>& ys) {
  std::vector<double> x, y;
  for (std::size_t i = 0; i < xs.size() && i < ys.size(); ++i)
    if (std::isfinite(xs[i]) && std::isfinite(ys[i])) {
      x.push_back(xs[i]);
      y.push_back(ys[i]);
    }
  const std::size_t n = x.size();
  if (n < 2) return kNaN;
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n, my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return sxx > 0 ? sxy / sxx : kNaN;
}

void report_floors(const Context& cx, Where& wh) {
  std::vector<FloorGroup> groups;
  for (std::size_t k = 0; k < cx.data->conditions.size(); ++k) {
    report_pressure_floor(cx, k, wh);
    count_floor_cells(cx, k, wh, groups);
  }
  for (const FloorGroup& g : groups) wh.floor_summary.push_back(summary_line(g, cx.data->band_count()));
  report_mic_floor(cx, wh);
}

void describe_where(const Context& cx, const Evaluated& base, DiagnosisResult& res) {
  Where& wh = res.where;
  roles_and_levels(cx, wh);
  wh.gap = res.baseline.gaps;
  wh.gap_per_band_rms = res.verdict.band_before_db;
  gap_against_conditions(cx, base, wh);
  wh.att_base = res.baseline.att_pred;
  gap_per_microphone(cx, base, wh);
  gap_per_window(res.baseline, cx.data->band_count(), wh);
  coherence(cx, wh);
}

}  // namespace noisemon::model::diagnosis
