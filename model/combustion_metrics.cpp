#include "model/combustion_metrics.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace noisemon::model {
namespace {

constexpr double kGasConstant = 287.0;  // J/(kg K), air
constexpr double kValleyHalfWidthDeg = 2.0;
constexpr double
    kPegExponentLow = 1.20,
    kPegExponentHigh = 1.45,
    kPegExponentStep =
        0.005;  // a fitted pegging n  // dp/dtheta max: the window's initial descent, followed on this average

struct Grid {
  std::span<const double> p;
  double first, step;
  const double* volume;  // V and dV/dtheta at each angle (m3, m3/deg)
  const double* dvolume;
  double angle(std::size_t i) const { return first + step * static_cast<double>(i); }
  double last() const { return angle(p.size() - 1); }
  // Index range [lo, hi] of the samples within [a, b] deg.
  std::pair<std::size_t, std::size_t> range(double a, double b) const {
    const double lo = std::max(0.0, std::ceil((a - first) / step - 1e-9));
    const double hi = std::min(static_cast<double>(p.size() - 1), std::floor((b - first) / step + 1e-9));
    return {static_cast<std::size_t>(lo), static_cast<std::size_t>(std::max(lo, hi))};
  }
  // The data reach [a, b] to within 2 deg (or a step) at both ends: the integrals' ends are dead centres, where
  // the volume hardly changes (a TDC correction of a degree or two leaves a cycle table's ends that short).
  bool covers(double a, double b) const {
    const double slack = std::max(step, 2.0);
    return first <= a + slack && last() >= b - slack;
  }
  double at(double theta) const { return interpolate(p.data(), theta); }
  double volume_at(double theta) const { return interpolate(volume, theta); }
  double interpolate(const double* v, double theta) const {
    const double x = std::clamp((theta - first) / step, 0.0, static_cast<double>(p.size() - 1));
    const auto i = std::min(static_cast<std::size_t>(x), p.size() - 2);
    return v[i] + (x - static_cast<double>(i)) * (v[i + 1] - v[i]);
  }
};

// Least-squares slope over +-half samples (the Savitzky-Golay first derivative), per degree; NaN at the ends.
void slope_per_deg(const Grid& g, int half, std::vector<double>& out) {
  const std::size_t n = g.p.size();
  out.assign(n, kNaN);
  const double h = half;
  const double den = g.step * h * (h + 1) * (2 * h + 1) / 3.0;
  for (std::size_t i = static_cast<std::size_t>(half); i + static_cast<std::size_t>(half) < n; ++i) {
    double s = 0.0;
    for (int k = 1; k <= half; ++k) s += k * (g.p[i + k] - g.p[i - k]);
    out[i] = s / den;
  }
}

// Integral of p dV over [a, b] deg (trapezoid on the samples, dV/dtheta analytic), J.
double work_j(const Grid& g, double a, double b) {
  const auto [lo, hi] = g.range(a, b);
  double w = 0.0;
  for (std::size_t i = lo; i < hi; ++i) w += 0.5 * g.step * (g.p[i] * g.dvolume[i] + g.p[i + 1] * g.dvolume[i + 1]);
  return w;
}

void peak(const Grid& g, CombustionMetrics& m) {
  const auto it = std::max_element(g.p.begin(), g.p.end());
  const auto i = static_cast<std::size_t>(it - g.p.begin());
  m.peak_pressure_pa = *it;
  m.peak_angle_deg = g.angle(i);
  if (i == 0 || i + 1 == g.p.size()) return;
  // The vertex of the parabola through the three samples around the maximum.
  const double a = g.p[i - 1], b = g.p[i], c = g.p[i + 1], curv = a - 2 * b + c;
  if (curv >= 0) return;
  const double d = 0.5 * (a - c) / curv;
  m.peak_angle_deg += d * g.step;
  m.peak_pressure_pa = b - 0.25 * (a - c) * d;
}

// The start of the combustion window (see MetricsOptions).
double rise_from_deg(const MetricsOptions& o) {
  if (std::isfinite(o.rise_from_deg)) return o.rise_from_deg;
  if (std::isfinite(o.soi_deg_btdc)) return -o.soi_deg_btdc;
  return o.heat_release_from_deg;
}

// dp/dtheta max in the combustion window, after the slope's initial descent: a slope still falling where the window
// opens is the tail of what came before it (the compression, or a fumigated fuel's early burn), not this window's
// rise. The descent is followed on the slope averaged over +-kValleyHalfWidthDeg, so that noise does not end it.
void max_rise(const Grid& g, const std::vector<double>& slope, const MetricsOptions& o, CombustionMetrics& m) {
  auto [lo, hi] = g.range(rise_from_deg(o), o.rise_to_deg);
  const auto half = static_cast<std::size_t>(std::max(1.0, std::round(kValleyHalfWidthDeg / g.step)));
  const auto smooth = [&](std::size_t i) {
    double s = 0.0;
    int n = 0;
    for (std::size_t k = i > half ? i - half : 0; k <= std::min(i + half, slope.size() - 1); ++k)
      if (std::isfinite(slope[k])) s += slope[k], ++n;
    return n > 0 ? s / n : kNaN;
  };
  while (lo < hi && smooth(lo + 1) < smooth(lo)) ++lo;
  for (std::size_t i = lo; i <= hi; ++i)
    if (std::isfinite(slope[i]) && !(slope[i] <= m.max_rise_pa_per_deg)) {
      m.max_rise_pa_per_deg = slope[i];
      m.max_rise_angle_deg = g.angle(i);
    }
}

// Apparent heat release (Heywood eq. 9.25) over the window, and the angles where its cumulative sum, counted from
// its minimum before its maximum, reaches 10, 50 and 90 % of that rise.
void heat_release(const Grid& g, const std::vector<double>& slope, const MetricsOptions& o, std::vector<double>& q,
                  CombustionMetrics& m) {
  const auto [lo, hi] = g.range(o.heat_release_from_deg, o.heat_release_to_deg);
  // m R of the trapped charge, for the temperature (and gamma) at each angle.
  double mass_r = kNaN;
  if (o.gamma_of_temperature && g.covers(o.ivc_deg, o.ivc_deg))
    mass_r = g.at(o.ivc_deg) * g.volume_at(o.ivc_deg) / o.intake_temperature_k;
  if (o.gamma_of_temperature && !(mass_r > 0)) return;
  auto gamma = [&](std::size_t i) {
    if (!o.gamma_of_temperature) return o.gamma;
    const double t = g.p[i] * g.volume[i] / mass_r;
    return 1.338 - 6.0e-5 * t + 1.0e-8 * t * t;
  };
  auto rate = [&](std::size_t i) {
    const double y = gamma(i);
    return y / (y - 1.0) * g.p[i] * g.dvolume[i] + 1.0 / (y - 1.0) * g.volume[i] * slope[i];
  };
  q.assign(1, 0.0);
  for (std::size_t i = lo; i < hi; ++i) {
    if (!std::isfinite(slope[i]) || !std::isfinite(slope[i + 1])) return;
    q.push_back(q.back() + 0.5 * g.step * (rate(i) + rate(i + 1)));
  }
  const auto top = static_cast<std::size_t>(std::max_element(q.begin(), q.end()) - q.begin());
  const auto bottom = static_cast<std::size_t>(
      std::min_element(q.begin(), q.begin() + static_cast<std::ptrdiff_t>(top) + 1) - q.begin());
  const double total = q[top] - q[bottom];
  // Without combustion the rise is noise and heat-transfer residue, a few % of the compression work; with it, several
  // times that work.
  const double compression = std::abs(work_j(g, -180.0, 0.0));
  if (!(total > 0.2 * compression)) return;
  m.heat_release_j = total;
  double* angles[] = {&m.ca05_deg, &m.ca10_deg, &m.ca50_deg, &m.ca90_deg};
  const double fractions[] = {0.05, 0.1, 0.5, 0.9};
  for (int f = 0; f < 4; ++f) {
    const double target = q[bottom] + fractions[f] * total;
    for (std::size_t j = bottom; j < top; ++j)
      if (q[j + 1] >= target) {
        const double x = (target - q[j]) / (q[j + 1] - q[j]);
        *angles[f] = g.angle(lo + j) + x * g.step;
        break;
      }
  }
}

// The polytropic over [a, b]: ln p = ln K - n ln V by least squares; n NaN where p is not positive or the grid does
// not reach the window.
struct Polytropic {
  double n = kNaN, ln_k = kNaN;
};
Polytropic polytropic_fit(const Grid& g, double a, double b) {
  if (!g.covers(a, b)) return {};
  const auto [lo, hi] = g.range(a, b);
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const double n = static_cast<double>(hi - lo + 1);
  for (std::size_t i = lo; i <= hi; ++i) {
    if (!(g.p[i] > 0)) return {};
    const double x = std::log(g.volume[i]), y = std::log(g.p[i]);
    sx += x, sy += y, sxx += x * x, sxy += x * y;
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  return {-slope, (sy - slope * sx) / n};
}

// The motored-equivalent slope at theta: the compression's polytropic K V^-n carried on, dp/dtheta = -n p V' / V.
double motored_slope(const Polytropic& c, const EngineGeometry& e, double theta) {
  if (!std::isfinite(c.n) || !std::isfinite(theta)) return kNaN;
  const double v = e.volume_m3(theta), p = std::exp(c.ln_k - c.n * std::log(v));
  return -c.n * p * e.dvolume_m3_per_deg(theta) / v;
}

// Eng (SAE 2002-01-2859): RI = (beta (dp/dt)max)^2 / (2 gamma pmax) sqrt(gamma R Tmax), Tmax from the ideal gas law
// with the charge trapped at intake valve closing.
double ringing_intensity(const Grid& g, const EngineGeometry& e, double speed_rpm, const MetricsOptions& o,
                         const CombustionMetrics& m) {
  if (!(speed_rpm > 0) || !std::isfinite(m.max_rise_pa_per_deg) || !g.covers(o.ivc_deg, o.ivc_deg)) return kNaN;
  const double p_ivc = g.at(o.ivc_deg);
  if (!(p_ivc > 0) || !(m.peak_pressure_pa > 0)) return kNaN;
  const double t_max =
      o.intake_temperature_k * m.peak_pressure_pa * e.volume_m3(m.peak_angle_deg) / (p_ivc * e.volume_m3(o.ivc_deg));
  const double dpdt = m.max_rise_pa_per_deg * 6.0 * speed_rpm;  // deg/s = 6 rpm
  const double b = o.ringing_beta_s * dpdt;
  return b * b / (2.0 * o.gamma * m.peak_pressure_pa) * std::sqrt(o.gamma * kGasConstant * t_max);
}

void check(std::span<const double> p, double step, const EngineGeometry& e, const MetricsOptions& o) {
  if (!(e.bore_m > 0) || !(e.stroke_m > 0) || !(e.compression_ratio > 1) || !(e.conrod_m > 0.5 * e.stroke_m))
    throw std::invalid_argument(
        "engine geometry: bore, stroke and rod must be positive, the rod longer than the crank "
        "(half the stroke) and the compression ratio above 1");
  if (!(step > 0) || !(step <= 2.0))
    throw std::invalid_argument("crank-angle step must be in (0, 2] deg, got " + std::to_string(step));
  const int half = static_cast<int>(std::lround(o.derivative_half_width_deg / step));
  if (p.size() < 2 * static_cast<std::size_t>(std::max(half, 1)) + 3)
    throw std::invalid_argument("a cycle of " + std::to_string(p.size()) + " samples is too short for the metrics");
  if (!(o.gamma > 1)) throw std::invalid_argument("gamma must be above 1");
}

// V and dV/dtheta at the grid's angles, kept in the workspace for as long as the grid and the geometry stay.
void volume_tables(std::size_t n, double first, double step, const EngineGeometry& e, MetricsWorkspace& w) {
  if (w.volume_m3.size() == n && w.volume_first_deg == first && w.volume_step_deg == step && w.volume_engine == e)
    return;
  w.volume_m3.resize(n);
  w.dvolume_m3_per_deg.resize(n);
  const Grid g{{}, first, step, nullptr, nullptr};
  for (std::size_t i = 0; i < n; ++i) {
    w.volume_m3[i] = e.volume_m3(g.angle(i));
    w.dvolume_m3_per_deg[i] = e.dvolume_m3_per_deg(g.angle(i));
  }
  w.volume_first_deg = first;
  w.volume_step_deg = step;
  w.volume_engine = e;
}

// The intake pegging's offset: the window's mean set to the intake pressure.
double intake_offset(const Grid& g, const MetricsOptions& o) {
  const auto [lo, hi] = g.range(o.peg_intake_deg - o.peg_half_width_deg, o.peg_intake_deg + o.peg_half_width_deg);
  double sum = 0.0;
  for (std::size_t i = lo; i <= hi; ++i) sum += g.p[i];
  return o.peg_intake_pa - sum / static_cast<double>(hi - lo + 1);
}

// The polytropic pegging's offset for exponent n: p + offset = K V^-n over the window, by least squares in K and the
// offset; *sse: the residual sum of squares.
double polytropic_offset(const Grid& g, const MetricsOptions& o, double n, double* sse) {
  const auto [lo, hi] = g.range(o.peg_poly_from_deg, o.peg_poly_to_deg);
  double sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
  const double m = static_cast<double>(hi - lo + 1);
  for (std::size_t i = lo; i <= hi; ++i) {
    const double x = std::pow(g.volume[i], -n), y = g.p[i];
    sx += x, sy += y, sxx += x * x, sxy += x * y, syy += y * y;
  }
  const double k = (m * sxy - sx * sy) / (m * sxx - sx * sx), c = (sy - k * sx) / m;  // p = k x + c
  *sse = std::max(0.0, syy - k * sxy - c * sy);
  return -c;
}

// The pegging's offset and exponent (NaN for intake pegging); (0, NaN) without pegging.
std::pair<double, double> pegging(const Grid& g, const MetricsOptions& o) {
  if (o.pegging == Pegging::kIntake) {
    if (!g.covers(o.peg_intake_deg - o.peg_half_width_deg, o.peg_intake_deg + o.peg_half_width_deg))
      return {kNaN, kNaN};
    return {intake_offset(g, o), kNaN};
  }
  if (o.pegging == Pegging::kPolytropic && !g.covers(o.peg_poly_from_deg, o.peg_poly_to_deg)) return {kNaN, kNaN};
  if (o.pegging != Pegging::kPolytropic) return {0.0, kNaN};
  double sse = 0.0;
  if (std::isfinite(o.peg_exponent)) return {polytropic_offset(g, o, o.peg_exponent, &sse), o.peg_exponent};
  double best = std::numeric_limits<double>::infinity(), offset = 0.0, exponent = kNaN;
  for (double n = kPegExponentLow; n <= kPegExponentHigh + 1e-9; n += kPegExponentStep) {
    const double off = polytropic_offset(g, o, n, &sse);
    if (sse < best) best = sse, offset = off, exponent = n;
  }
  return {offset, exponent};
}

// The cascade over x in place, forward then backward (zero phase, the magnitude squared).
void filter_both_ways(const std::vector<dsp::Biquad>& sections, std::vector<double>& x) {
  for (int pass = 0; pass < 2; ++pass) {
    for (const dsp::Biquad& s : sections) {
      double z1 = 0.0, z2 = 0.0;  // transposed direct form II
      for (double& v : x) {
        const double y = s.b0 * v + z1;
        z1 = s.b1 * v - s.a1 * y + z2;
        z2 = s.b2 * v - s.a2 * y;
        v = y;
      }
    }
    std::reverse(x.begin(), x.end());
  }
}

// MAPO: the largest |band-passed pressure| in the window (MetricsOptions), on the grid's own sample rate.
double mapo(const Grid& g, double speed_rpm, const MetricsOptions& o, MetricsWorkspace& w) {
  const double fs = speed_rpm / 60.0 * 360.0 / g.step;
  if (!(speed_rpm > 0) || !(o.mapo_low_hz < 0.4 * fs) || !g.covers(o.mapo_from_deg, o.mapo_to_deg)) return kNaN;
  const double high = std::min(o.mapo_high_hz, 0.45 * fs);
  if (w.mapo_filter.empty() || std::abs(fs / w.mapo_fs_hz - 1.0) > 0.01 || w.mapo_low_hz != o.mapo_low_hz ||
      w.mapo_high_hz != high) {
    w.mapo_filter = dsp::butterworth_bandpass(2, o.mapo_low_hz, high, fs);
    w.mapo_fs_hz = fs, w.mapo_low_hz = o.mapo_low_hz, w.mapo_high_hz = high;
  }
  w.band.assign(g.p.begin(), g.p.end());
  filter_both_ways(w.mapo_filter, w.band);
  const auto [lo, hi] = g.range(o.mapo_from_deg, o.mapo_to_deg);
  double most = 0.0;
  for (std::size_t i = lo; i <= hi; ++i) most = std::max(most, std::abs(w.band[i]));
  return most;
}

}  // namespace

CombustionMetrics combustion_metrics(std::span<const double> pressure_pa, double first_deg, double step_deg,
                                     const EngineGeometry& engine, double speed_rpm, const MetricsOptions& options) {
  MetricsWorkspace scratch;
  return combustion_metrics(pressure_pa, first_deg, step_deg, engine, speed_rpm, options, scratch);
}

CombustionMetrics combustion_metrics(std::span<const double> pressure_pa, double first_deg, double step_deg,
                                     const EngineGeometry& engine, double speed_rpm, const MetricsOptions& options,
                                     MetricsWorkspace& scratch) {
  check(pressure_pa, step_deg, engine, options);
  volume_tables(pressure_pa.size(), first_deg, step_deg, engine, scratch);
  const Grid raw{pressure_pa, first_deg, step_deg, scratch.volume_m3.data(), scratch.dvolume_m3_per_deg.data()};
  const auto [offset, exponent] = pegging(raw, options);
  std::span<const double> pressure = pressure_pa;
  if (options.pegging != Pegging::kNone) {
    scratch.pegged.assign(pressure_pa.begin(), pressure_pa.end());
    for (double& p : scratch.pegged) p += offset;
    pressure = scratch.pegged;
  }
  const Grid g{pressure, first_deg, step_deg, scratch.volume_m3.data(), scratch.dvolume_m3_per_deg.data()};
  const int half = std::max(1, static_cast<int>(std::lround(options.derivative_half_width_deg / step_deg)));
  std::vector<double>& slope = scratch.slope;
  slope_per_deg(g, half, slope);
  CombustionMetrics m;
  peak(g, m);
  max_rise(g, slope, options, m);
  const double vd = engine.displacement_m3();
  m.imep_gross_pa = g.covers(-180.0, 180.0) ? work_j(g, -180.0, 180.0) / vd : kNaN;
  m.imep_net_pa = g.covers(-360.0, 360.0) ? work_j(g, -360.0, 360.0) / vd : kNaN;
  m.pmep_pa = m.imep_net_pa - m.imep_gross_pa;
  const Polytropic compression = polytropic_fit(g, options.compression_from_deg, options.compression_to_deg);
  m.n_compression = compression.n;
  m.n_expansion = polytropic_fit(g, options.expansion_from_deg, options.expansion_to_deg).n;
  m.max_rise_motored_pa_per_deg = motored_slope(compression, engine, m.max_rise_angle_deg);
  heat_release(g, slope, options, scratch.heat, m);
  m.ringing_intensity_w_per_m2 = ringing_intensity(g, engine, speed_rpm, options, m);
  m.mapo_pa = mapo(g, speed_rpm, options, scratch);
  m.burn_duration_deg = m.ca90_deg - m.ca10_deg;
  m.pegging_offset_pa = offset;
  m.pegging_exponent = exponent;
  return m;
}

}  // namespace noisemon::model
