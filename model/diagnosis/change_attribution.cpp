#include "model/diagnosis/change_attribution.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <numbers>

namespace noisemon::model::diagnosis {

namespace {

constexpr double kAdditiveSplitHz =
    1000.0;                      // additive sound centred below: test-cell noise; above: the engine's impacts
constexpr int kBandPoints = 16;  // frequencies averaged over a band for the spectral templates

double lin(double db) { return std::pow(10.0, db / 10.0); }
double db(double x) { return 10.0 * std::log10(x); }

// The change as observed, and one candidate's prediction of it, on the same three parts.
struct Delta {
  std::vector<double> gap, cpl, mic;  // per band, per band, per microphone (NaN: not observed)
};

struct Observed {
  Delta value, sigma;
  std::size_t count = 0;  // finite observations
};

Observed observe(const GapChange& c, double floor_db) {
  Observed o;
  const std::size_t nb = c.band_hz.size(), nm = c.mic_before.size();
  auto quad = [&](double s) { return std::sqrt(s * s + floor_db * floor_db); };
  for (std::size_t b = 0; b < nb; ++b) {
    const bool used = c.band_used[b] != 0;
    const double gap = (c.measured_after[b] - c.predicted_after[b]) - (c.measured_before[b] - c.predicted_before[b]);
    o.value.gap.push_back(used && std::isfinite(gap) ? gap : kNaN);
    o.sigma.gap.push_back(quad(c.band_sigma_db[b]));
    const double cpl = c.cpl_after[b] - c.cpl_before[b];
    o.value.cpl.push_back(used && std::isfinite(cpl) ? cpl : kNaN);
    o.sigma.cpl.push_back(quad(c.cpl_sigma_db[b]));
  }
  double before = 0.0, after = 0.0;
  std::size_t mics = 0;
  for (std::size_t m = 0; m < nm; ++m)
    if (std::isfinite(c.mic_before[m]) && std::isfinite(c.mic_after[m])) {
      before += lin(c.mic_before[m]);
      after += lin(c.mic_after[m]);
      ++mics;
    }
  for (std::size_t m = 0; m < nm; ++m) {
    const double offset = (c.mic_after[m] - db(after / mics)) - (c.mic_before[m] - db(before / mics));
    o.value.mic.push_back(mics > 1 && std::isfinite(offset) ? offset : kNaN);
    o.sigma.mic.push_back(quad(c.mic_sigma_db[m]));
  }
  for (const auto* part : {&o.value.gap, &o.value.cpl, &o.value.mic})
    o.count +=
        static_cast<std::size_t>(std::count_if(part->begin(), part->end(), [](double v) { return std::isfinite(v); }));
  return o;
}

Delta zero_delta(const Observed& o) {
  return {std::vector<double>(o.value.gap.size(), 0.0), std::vector<double>(o.value.cpl.size(), 0.0),
          std::vector<double>(o.value.mic.size(), 0.0)};
}

double chi2(const Observed& o, const Delta& d) {
  double sum = 0.0;
  auto add = [&](const std::vector<double>& y, const std::vector<double>& s, const std::vector<double>& p) {
    for (std::size_t i = 0; i < y.size(); ++i)
      if (std::isfinite(y[i])) sum += (y[i] - p[i]) * (y[i] - p[i]) / (s[i] * s[i]);
  };
  add(o.value.gap, o.sigma.gap, d.gap);
  add(o.value.cpl, o.sigma.cpl, d.cpl);
  add(o.value.mic, o.sigma.mic, d.mic);
  return sum;
}

// The minimum of f over [lo, hi]: a grid, then golden-section search around its best point (one evaluation a step).
double minimize_1d(const std::function<double(double)>& f, double lo, double hi, double* at) {
  constexpr int kGrid = 24, kSteps = 30;
  double best_x = lo, best = f(lo);
  for (int i = 1; i <= kGrid; ++i) {
    const double x = lo + (hi - lo) * i / kGrid;
    if (const double v = f(x); v < best) best = v, best_x = x;
  }
  const double step = (hi - lo) / kGrid, g = (std::sqrt(5.0) - 1.0) / 2.0;
  double a = std::max(lo, best_x - step), b = std::min(hi, best_x + step);
  double x1 = b - g * (b - a), x2 = a + g * (b - a), f1 = f(x1), f2 = f(x2);
  for (int i = 0; i < kSteps; ++i) {
    if (f1 < f2) {
      b = x2, x2 = x1, f2 = f1;
      x1 = b - g * (b - a), f1 = f(x1);
    } else {
      a = x1, x1 = x2, f1 = f2;
      x2 = a + g * (b - a), f2 = f(x2);
    }
  }
  const double x = f1 < f2 ? x1 : x2, v = std::min(f1, f2);
  if (v < best) best = v, best_x = x;
  *at = best_x;
  return best;
}

// Log-spaced frequencies across the 1/3-octave band of a nominal centre.
std::vector<double> band_points(double nominal_hz) {
  std::vector<double> f;
  for (int i = 0; i < kBandPoints; ++i)
    f.push_back(nominal_hz * std::pow(10.0, (-0.05 + 0.1 * (i + 0.5) / kBandPoints)));
  return f;
}

// 10 lg of the band's mean of a power response.
double band_db(double nominal_hz, const std::function<double(double)>& power) {
  double sum = 0.0;
  for (const double f : band_points(nominal_hz)) sum += power(f);
  return db(sum / kBandPoints);
}

CandidateFit make_fit(const std::string& effect, std::vector<std::pair<std::string, double>> params, int parameters,
                      double chi2_value, std::size_t n) {
  CandidateFit fit;
  fit.effect = effect;
  fit.params = std::move(params);
  fit.parameters = parameters;
  fit.chi2 = chi2_value;
  fit.criterion = chi2_value + parameters * std::log(static_cast<double>(std::max<std::size_t>(n, 2)));
  return fit;
}

// ------------------------------------------------------------------------------------------ the candidates

// mic_gain: microphone m reads G dB more; the array's energy mean rises by its share, every other offset falls by that.
CandidateFit fit_mic_gain(const GapChange& c, const Observed& o) {
  CandidateFit best = make_fit("mic_gain", {}, 2, std::numeric_limits<double>::infinity(), o.count);
  double total = 0.0;
  for (const double l : c.mic_before)
    if (std::isfinite(l)) total += lin(l);
  for (std::size_t m = 0; m < c.mic_before.size(); ++m) {
    if (!std::isfinite(o.value.mic[m])) continue;
    const double share = lin(c.mic_before[m]) / total;
    auto predict = [&](double g_db) {
      Delta d = zero_delta(o);
      const double rise = db(1.0 + share * (lin(g_db) - 1.0));
      std::fill(d.gap.begin(), d.gap.end(), rise);
      for (std::size_t j = 0; j < d.mic.size(); ++j) d.mic[j] = (j == m ? g_db : 0.0) - rise;
      return d;
    };
    double g_db = 0.0;
    const double value = minimize_1d([&](double g) { return chi2(o, predict(g)); }, -30.0, 30.0, &g_db);
    if (value < best.chi2) best = make_fit("mic_gain", {{"mic", m + 1.0}, {"db", g_db}}, 2, value, o.count);
  }
  return best;
}

// transducer_noise: white noise of one-sided density D (Pa^2/Hz) in the measured pressure; the prediction follows the
// CPL (the block is linear in the band's power at small changes), the microphones hear nothing of it.
CandidateFit fit_transducer_noise(const GapChange& c, const Observed& o) {
  constexpr double p0 = 2e-5;
  auto predict = [&](double log_density) {
    Delta d = zero_delta(o);
    for (std::size_t b = 0; b < c.band_hz.size(); ++b) {
      if (!std::isfinite(c.cpl_before[b])) continue;
      const double bandwidth = c.band_hz[b] * (std::pow(10.0, 0.05) - std::pow(10.0, -0.05));
      const double rise = db(1.0 + std::pow(10.0, log_density) * bandwidth / (lin(c.cpl_before[b]) * p0 * p0));
      d.cpl[b] = rise;
      d.gap[b] = -rise;
    }
    return d;
  };
  double x = 0.0;
  const double value = minimize_1d([&](double v) { return chi2(o, predict(v)); }, -14.0, 10.0, &x);
  std::vector<std::pair<std::string, double>> params{{"density_db", db(std::pow(10.0, x) / (p0 * p0))}};
  if (c.pressure_edge_rate_hz > 0.0)
    params.insert(params.begin(), {"bar", std::sqrt(std::pow(10.0, x) * c.pressure_edge_rate_hz / 2.0) / 1e5});
  return make_fit("transducer_noise", std::move(params), 1, value, o.count);
}

// Stationary sound raises every crank window by the same power (one parameter); crank-angle-locked impacts raise some
// windows only (a power per window where it pays). The weight of "stationary" from the windows' measured levels;
// NaN without windows.
double stationary_weight(const GapChange& c, double floor_db) {
  std::vector<double> y, s, m;
  for (std::size_t w = 0; w < c.window_after.size() && w < c.window_before.size(); ++w)
    if (std::isfinite(c.window_after[w]) && std::isfinite(c.window_before[w])) {
      y.push_back(c.window_after[w] - c.window_before[w]);
      s.push_back(std::sqrt(c.window_sigma_db[w] * c.window_sigma_db[w] + floor_db * floor_db));
      m.push_back(lin(c.window_before[w]));
    }
  if (y.size() < 3) return kNaN;
  const double penalty = std::log(static_cast<double>(y.size()));
  auto stationary_chi2 = [&](double log_power) {
    double sum = 0.0;
    for (std::size_t w = 0; w < y.size(); ++w)
      sum += std::pow((y[w] - db(1.0 + std::pow(10.0, log_power) / m[w])) / s[w], 2);
    return sum;
  };
  const auto [lo, hi] = std::minmax_element(m.begin(), m.end());
  double at = 0.0;
  const double chi2_stationary = minimize_1d(stationary_chi2, std::log10(*lo) - 6.0, std::log10(*hi) + 4.0, &at);
  double chi2_locked = 0.0;
  int locked_parameters = 0;
  for (std::size_t w = 0; w < y.size(); ++w) {
    const double z2 = (y[w] / s[w]) * (y[w] / s[w]);
    if (y[w] > 0.0 && z2 > penalty)
      ++locked_parameters;
    else
      chi2_locked += z2;
  }
  const double stationary = chi2_stationary + penalty, locked = chi2_locked + locked_parameters * penalty;
  return 1.0 / (1.0 + std::exp(-0.5 * (locked - stationary)));
}

// Additive sound at every microphone, per band: its power in closed form per band, a band counted (a parameter)
// only where it pays for itself (its chi-square drop exceeds ln n). Stationary (background_noise) or crank-angle-
// locked (mechanical_noise) by the crank windows; without them, by where its power is centred.
CandidateFit fit_additive(const GapChange& c, const Observed& o, double floor_db, double* named_weight) {
  Delta d = zero_delta(o);
  const double penalty = std::log(static_cast<double>(std::max<std::size_t>(o.count, 2)));
  double power = 0.0, centre = 0.0;
  int parameters = 0;
  for (std::size_t b = 0; b < c.band_hz.size(); ++b) {
    const double y = o.value.gap[b];
    if (!std::isfinite(y) || y <= 0.0 || y * y / (o.sigma.gap[b] * o.sigma.gap[b]) < penalty) continue;
    const double added = lin(c.measured_before[b]) * (lin(y) - 1.0);  // A-weighted band power, re (20 uPa)^2
    d.gap[b] = y;
    power += added;
    centre += added * std::log2(c.band_hz[b]);
    ++parameters;
  }
  if (parameters == 0) return make_fit("background_noise", {}, 0, std::numeric_limits<double>::infinity(), o.count);
  double before = 0.0, after = 0.0;
  for (const double l : c.mic_before)
    if (std::isfinite(l)) before += lin(l), after += lin(l) + power;
  for (std::size_t m = 0; m < d.mic.size(); ++m)
    if (std::isfinite(c.mic_before[m])) d.mic[m] = db(1.0 + power / lin(c.mic_before[m])) - db(after / before);
  const double centre_hz = std::exp2(centre / power);
  const double stationary = stationary_weight(c, floor_db);
  const bool background = std::isfinite(stationary) ? stationary >= 0.5 : centre_hz < kAdditiveSplitHz;
  *named_weight = std::isfinite(stationary) ? (background ? stationary : 1.0 - stationary) : 1.0;
  std::vector<std::pair<std::string, double>> params{{"db", db(power)}, {"centre_hz", centre_hz}};
  if (std::isfinite(stationary)) params.emplace_back("stationary", stationary);
  return make_fit(background ? "background_noise" : "mechanical_noise", std::move(params), parameters, chi2(o, d),
                  o.count);
}

// The model block's transfer H(f) = (c0 + j w c1) / (k1 - m w^2 + j w b1) (its linear part).
std::complex<double> block_transfer(const BlockParams& p, double f_hz) {
  const double w = 2.0 * std::numbers::pi * f_hz;
  return std::complex<double>(p.c0, w * p.c1) / std::complex<double>(p.k1 - p.m * w * w, w * p.b1);
}

// second_mode: a further resonance in phase with the block at f2, in either of the two ways a panel radiates: on the
// block's output (the structure's response rises by |1 + g R|^2: the virtual engine's form) or driven by the same
// pressure beside the block (the diagnosis's parallel mode: |H + g |H(f2)| R|^2 / |H|^2, H the model block's
// transfer: where the block is weak the mode's own path shows whole; M >= 0, a panel adds its sound, an absorber
// acts on the output). g = 10^(M/20) - 1, R the unit-peak band-pass at f2 with quality Q. The better form is reported.
// No phase is fitted: a mode out of phase imitates a shift of the block's own resonance, which is the cubic candidates'
// (tried, a phase took them over).
CandidateFit fit_second_mode(const GapChange& c, const Observed& o, const BlockParams& block) {
  CandidateFit best = make_fit("second_mode", {}, 3, std::numeric_limits<double>::infinity(), o.count);
  const std::size_t nb = c.band_hz.size();
  std::vector<double> f(nb * kBandPoints);
  for (std::size_t b = 0; b < nb; ++b) {
    const std::vector<double> points = band_points(c.band_hz[b]);
    std::copy(points.begin(), points.end(), f.begin() + static_cast<std::ptrdiff_t>(b * kBandPoints));
  }
  for (const bool parallel : {false, true}) {
    std::vector<std::complex<double>> h(f.size(), 1.0), r(f.size());
    std::vector<double> h2(nb, 0.0);
    for (std::size_t k = 0; k < f.size(); ++k) {
      if (parallel) h[k] = block_transfer(block, f[k]);
      h2[k / kBandPoints] += std::norm(h[k]);
    }
    Delta d = zero_delta(o);
    for (double f2 = 50.0; f2 < 18000.0; f2 *= std::pow(2.0, 1.0 / 12.0))
      for (const double q : {2.5, 5.0, 10.0}) {
        const double scale = parallel ? std::abs(block_transfer(block, f2)) : 1.0;
        for (std::size_t k = 0; k < f.size(); ++k) {
          const std::complex<double> jw(0.0, f[k] * f2 / q);
          r[k] = scale * jw / (f2 * f2 - f[k] * f[k] + jw);
        }
        auto chi2_at = [&](double m_db) {
          const double g = std::pow(10.0, m_db / 20.0) - 1.0;
          for (std::size_t b = 0; b < nb; ++b) {
            if (!std::isfinite(o.value.gap[b])) continue;
            double sum = 0.0;
            for (std::size_t k = b * kBandPoints; k < (b + 1) * kBandPoints; ++k) sum += std::norm(h[k] + g * r[k]);
            d.gap[b] = db(sum / h2[b]);
          }
          return chi2(o, d);
        };
        double m_db = 0.0;
        // A panel beside the block adds its sound (M >= 0); an absorber acts on the structure's output.
        const double value = minimize_1d(chi2_at, parallel ? 0.0 : -20.0, 30.0, &m_db);
        if (value < best.chi2)
          best = make_fit("second_mode", {{"hz", f2}, {"db", m_db}, {"q", q}, {"parallel", parallel ? 1.0 : 0.0}}, 3,
                          value, o.count);
      }
  }
  return best;
}

// speed_dependence: the structural transfer's gain, the same dB in every band.
// Its least-squares value is the bands' weighted mean change.
CandidateFit fit_uniform_gain(const GapChange& c, const Observed& o) {
  double num = 0.0, den = 0.0;
  for (std::size_t b = 0; b < c.band_hz.size(); ++b)
    if (std::isfinite(o.value.gap[b])) {
      const double w = 1.0 / (o.sigma.gap[b] * o.sigma.gap[b]);
      num += w * o.value.gap[b];
      den += w;
    }
  const double gain = den > 0.0 ? num / den : 0.0;
  Delta d = zero_delta(o);
  std::fill(d.gap.begin(), d.gap.end(), gain);
  return make_fit("speed_dependence", {{"gain_db", gain}}, 1, chi2(o, d), o.count);
}

// cubic_damping, cubic_stiffness: the model block's damping b1 or stiffness k1 raised (the effective linear part of an
// amplitude-dependent term at this amplitude): 10 lg |H'(f)|^2 / |H(f)|^2 over each band, H = (c0 + j w c1) /
// (k1 - m w^2 + j w b1), the rise fitted as a factor 1 ... 100 on b1, 1 ... 4 on k1.
std::vector<CandidateFit> fit_cubic(const GapChange& c, const Observed& o, const BlockParams& p) {
  auto denominator2 = [&](double f, double k1, double b1) {
    const double w = 2.0 * std::numbers::pi * f, re = k1 - p.m * w * w, im = w * b1;
    return re * re + im * im;
  };
  Delta d = zero_delta(o);
  auto chi2_at = [&](double k1, double b1) {
    for (std::size_t b = 0; b < c.band_hz.size(); ++b)
      if (std::isfinite(o.value.gap[b]))
        d.gap[b] =
            band_db(c.band_hz[b], [&](double f) { return denominator2(f, p.k1, p.b1) / denominator2(f, k1, b1); });
    return chi2(o, d);
  };
  double log_b = 0.0, log_k = 0.0;
  const double chi2_b =
      minimize_1d([&](double x) { return chi2_at(p.k1, p.b1 * std::pow(10.0, x)); }, 0.0, 2.0, &log_b);
  const double chi2_k =
      minimize_1d([&](double x) { return chi2_at(p.k1 * std::pow(10.0, x), p.b1); }, 0.0, std::log10(4.0), &log_k);
  const double f0 = std::sqrt(p.k1 / p.m) / (2.0 * std::numbers::pi);
  const double k_factor = std::pow(10.0, log_k);
  return {make_fit("cubic_damping", {{"delta_b1", p.b1 * (std::pow(10.0, log_b) - 1.0)}}, 1, chi2_b, o.count),
          make_fit("cubic_stiffness",
                   {{"delta_k1", p.k1 * (k_factor - 1.0)}, {"f0_shift_hz", f0 * (std::sqrt(k_factor) - 1.0)}}, 1,
                   chi2_k, o.count)};
}

std::string explain(const Attribution& a, const CandidateFit& best, const CandidateFit& none) {
  if (a.effect == "unexplained")
    return "no candidate closes half of the change (the best, " + best.effect + ", closes " +
           std::to_string(static_cast<int>(std::lround(100.0 * a.explained))) + " %)";
  std::string text = a.effect + " closes " + std::to_string(static_cast<int>(std::lround(100.0 * a.explained))) +
                     " % of the change (chi2 " + std::to_string(static_cast<int>(std::lround(none.chi2))) + " -> " +
                     std::to_string(static_cast<int>(std::lround(best.chi2))) + ")";
  if (a.effect == "background_noise" || a.effect == "mechanical_noise") {
    const bool windows =
        std::any_of(a.params.begin(), a.params.end(), [](const auto& p) { return p.first == "stationary"; });
    text += std::string("; additive, ") + (a.effect == "background_noise" ? "stationary" : "crank-angle-locked") +
            (windows ? " by the crank windows' levels"
                     : " by its spectrum's centre alone (the reports carry no crank-window levels)");
  }
  return text;
}

}  // namespace

Attribution attribute_change(const GapChange& change, const AttributionOptions& options) {
  const Observed o = observe(change, options.model_error_db);
  std::vector<CandidateFit> fits{make_fit("none", {}, 0, chi2(o, zero_delta(o)), o.count)};
  const CandidateFit none = fits.front();
  fits.push_back(fit_mic_gain(change, o));
  fits.push_back(fit_transducer_noise(change, o));
  double additive_weight = 1.0;
  fits.push_back(fit_additive(change, o, options.model_error_db, &additive_weight));
  fits.push_back(fit_second_mode(change, o, options.model_block));
  fits.push_back(fit_uniform_gain(change, o));
  for (auto& f : fit_cubic(change, o, options.model_block)) fits.push_back(std::move(f));
  std::erase_if(fits, [](const CandidateFit& f) { return !std::isfinite(f.criterion); });
  std::sort(fits.begin(), fits.end(), [](const auto& a, const auto& b) { return a.criterion < b.criterion; });
  double total = 0.0;
  for (auto& f : fits) total += (f.weight = std::exp(-0.5 * (f.criterion - fits.front().criterion)));
  for (auto& f : fits) f.weight /= total;
  Attribution a;
  a.candidates = fits;
  const CandidateFit& best = fits.front().effect == "none" && fits.size() > 1 ? fits[1] : fits.front();
  a.explained = none.chi2 > 0.0 ? 1.0 - best.chi2 / none.chi2 : 0.0;
  a.effect = a.explained >= options.min_explained && best.effect != "none" ? best.effect : "unexplained";
  if (a.effect != "unexplained") a.params = best.params;
  a.confidence = a.effect == "unexplained" ? 0.0 : best.weight;
  if (a.effect == "background_noise" || a.effect == "mechanical_noise") a.confidence *= additive_weight;
  a.explanation = explain(a, best, none);
  return a;
}

}  // namespace noisemon::model::diagnosis
