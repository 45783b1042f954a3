// The waveform diagnosis's explainable-gap test: how much of a model's held-out error a missing term of the model
// could produce (regressed on the training ranges, scored on the held-out ones).
#include "model/diagnosis/explainable_gap.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace noisemon::model::diagnosis {

double rms_of(const std::vector<std::vector<double>>& e) {
  double s = 0.0;
  std::size_t n = 0;
  for (const auto& v : e)
    for (double x : v) {
      s += x * x;
      ++n;
    }
  return n ? std::sqrt(s / static_cast<double>(n)) : std::numeric_limits<double>::quiet_NaN();
}

std::vector<std::vector<double>> squared_difference(const std::vector<std::vector<double>>& before,
                                                    const std::vector<std::vector<double>>& after) {
  std::vector<std::vector<double>> d(before.size());
  for (std::size_t s = 0; s < before.size(); ++s) {
    d[s].resize(before[s].size());
    for (std::size_t i = 0; i < before[s].size(); ++i)
      d[s][i] = before[s][i] * before[s][i] - after[s][i] * after[s][i];
  }
  return d;
}

namespace {

// The explainable-gap test regresses the error on what a missing term of the model could produce. To first
// order, a missing force f(z, z') changes the output by the model's own linear dynamics driven by f along
// the model's trajectory; f is expanded in a basis of odd, even, smooth and switching functions of the
// standardised state (cubic, quadratic, friction-like, dead-zone-like ...). Lagged input covers linear
// misfit with short memory. Features: those responses (position and velocity), the lagged input, a constant.
constexpr std::size_t kBasis = 13;

std::array<double, kBasis> force_basis(double z, double v) {
  const double sz = std::tanh(z / 0.05), sv = std::tanh(v / 0.05);  // smoothed sign(z), sign(v)
  return {
      z,  v,  z * z - 1.0,        v * v - 1.0,       z * v, z * z * z, v * v * v, z * std::fabs(z), v * std::fabs(v),
      sz, sv, std::fabs(v) - 0.8, std::fabs(z) - 0.8};
}

struct RangeSignals {
  std::vector<double> u, e;  // whole range: input, error
  std::vector<std::array<double, 2 * kBasis>> dyn;
};

// Response of the linear part of m's primary mode to x, aligned with x: position (velocity when `velocity`).
std::vector<double> linear_response(const fit::WaveformModel& m, double fs, int steps, const std::vector<double>& x,
                                    bool velocity) {
  BlockParams p = m.block;
  p.k3 = p.b3 = 0.0;
  p.c0 = velocity ? 0.0 : 1.0;
  p.c1 = velocity ? 1.0 : 0.0;
  BlockModelOptions o;
  o.max_step_s = 1.0 / (fs * steps);
  o.refine = false;
  BlockModel bm(p, fs, o);
  const std::size_t lat = bm.latency_samples();
  std::vector<double> in(x);
  in.resize(x.size() + lat, x.empty() ? 0.0 : x.back());
  std::vector<double> out(in.size());
  bm.process(in.data(), out.data(), in.size());
  return std::vector<double>(out.begin() + static_cast<std::ptrdiff_t>(lat), out.end());
}

// The scale of the regressors, from the training ranges' scored samples: the input's mean and standard deviation,
// the state's rms; n: the number of samples.
struct Standardisation {
  double u_mean = 0.0, u_std = 1.0, z_rms = 1.0, v_rms = 1.0;
  std::size_t n = 0;
};

Standardisation standardisation(const std::vector<fit::WaveformTrace>& train_tr,
                                std::span<const fit::SampleRange> ranges, std::size_t settle,
                                std::span<const double> u) {
  double su = 0, su2 = 0, sz2 = 0, sv2 = 0;
  std::size_t n = 0;
  for (std::size_t s = 0; s < train_tr.size(); ++s)
    for (std::size_t j = settle; j < train_tr[s].y.size(); ++j) {
      const double uu = u[ranges[s].begin + j];
      su += uu;
      su2 += uu * uu;
      sz2 += train_tr[s].z[j] * train_tr[s].z[j];
      sv2 += train_tr[s].v[j] * train_tr[s].v[j];
      ++n;
    }
  const double dn = static_cast<double>(std::max<std::size_t>(n, 1));
  Standardisation st;
  st.n = n;
  st.u_mean = su / dn;
  st.u_std = std::sqrt(std::max(su2 / dn - st.u_mean * st.u_mean, 1e-300));
  st.z_rms = std::sqrt(std::max(sz2 / dn, 1e-300));
  st.v_rms = std::sqrt(std::max(sv2 / dn, 1e-300));
  return st;
}

// Per range: the standardised input, the error and the responses of the model's linear dynamics to the force
// basis along the model's trajectory.
std::vector<RangeSignals> range_signals(const fit::WaveformModel& m, double fs, int steps, const Standardisation& st,
                                        const std::vector<fit::WaveformTrace>& traces,
                                        std::span<const fit::SampleRange> ranges, std::span<const double> u,
                                        std::span<const double> y) {
  std::vector<RangeSignals> out;
  for (std::size_t s = 0; s < traces.size(); ++s) {
    const fit::WaveformTrace& t = traces[s];
    const std::size_t len = t.y.size();
    RangeSignals rs;
    rs.u.resize(len);
    rs.e.resize(len);
    for (std::size_t j = 0; j < len; ++j) {
      rs.u[j] = (u[ranges[s].begin + j] - st.u_mean) / st.u_std;
      rs.e[j] = t.y[j] - y[ranges[s].begin + j];
    }
    rs.dyn.resize(len);
    std::vector<std::vector<double>> phi(kBasis, std::vector<double>(len));
    for (std::size_t j = 0; j < len; ++j) {
      const auto b = force_basis(t.z[j] / st.z_rms, t.v[j] / st.v_rms);
      for (std::size_t k = 0; k < kBasis; ++k) phi[k][j] = b[k];
    }
    for (std::size_t k = 0; k < kBasis; ++k)
      for (int vel = 0; vel < 2; ++vel) {
        const auto g = linear_response(m, fs, steps, phi[k], vel == 1);
        const double scale = vel ? st.v_rms : st.z_rms;  // same size as the state it perturbs
        for (std::size_t j = 0; j < len; ++j) rs.dyn[j][2 * k + static_cast<std::size_t>(vel)] = g[j] / scale;
      }
    out.push_back(std::move(rs));
  }
  return out;
}

// The regressors of sample i: the dynamic responses, `lags` lagged inputs, a constant.
void fill_features(const RangeSignals& r, std::size_t i, std::size_t lags, Eigen::VectorXd& f) {
  Eigen::Index at = 0;
  for (double d : r.dyn[i]) f(at++) = d;
  for (std::size_t k = 0; k < lags; ++k) f(at++) = r.u[i >= k ? i - k : 0];
  f(at) = 1.0;
}

// Ridge regression of the training error on the features (every stride-th scored sample).
Eigen::VectorXd regress_error(const std::vector<RangeSignals>& train, std::size_t settle, std::size_t lags,
                              std::size_t stride) {
  const auto p = static_cast<Eigen::Index>(2 * kBasis + lags + 1);
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd atb = Eigen::VectorXd::Zero(p);
  Eigen::VectorXd f(p);
  for (const auto& s : train)
    for (std::size_t j = settle; j < s.e.size(); j += stride) {
      fill_features(s, j, lags, f);
      ata.selfadjointView<Eigen::Lower>().rankUpdate(f);
      atb.noalias() += f * s.e[j];
    }
  ata.triangularView<Eigen::StrictlyUpper>() = ata.transpose();
  // Ridge, relative to each regressor's own size: keeps noise-fitting small.
  const Eigen::VectorXd diag = ata.diagonal();
  ata.diagonal() += 1e-4 * diag + Eigen::VectorXd::Constant(p, 1e-12 * diag.maxCoeff());
  return ata.ldlt().solve(atb);
}

}  // namespace

ExplainableGap explainable_gap(const fit::WaveformModel& m, double fs, const WaveformDiagnosisOptions& opt,
                               const fit::WaveformSimOptions& sim, std::span<const double> u,
                               std::span<const double> y) {
  const std::size_t settle = sim.settle_samples;
  std::vector<fit::WaveformTrace> train_tr, held_tr;
  for (const fit::SampleRange& r : opt.train) train_tr.push_back(simulate_waveform_trace(m, fs, sim, u, y, r));
  for (const fit::SampleRange& r : opt.heldout) held_tr.push_back(simulate_waveform_trace(m, fs, sim, u, y, r));
  const Standardisation st = standardisation(train_tr, opt.train, settle, u);
  const int steps = sim.steps_per_sample > 0 ? sim.steps_per_sample : fit::choose_steps_per_sample(m, fs);
  const auto train = range_signals(m, fs, steps, st, train_tr, opt.train, u, y);
  const auto held = range_signals(m, fs, steps, st, held_tr, opt.heldout, u, y);

  // Lags of the input over the primary mode's decay time (2 m / b1), 8..32 samples.
  const double decay_samples = 2.0 * m.block.m / std::max(m.block.b1, 1e-300) * fs;
  const auto lags = static_cast<std::size_t>(std::clamp(std::round(decay_samples), 8.0, 32.0));
  const std::size_t stride = std::max<std::size_t>(1, st.n / 20000);  // enough rows for ~60 regressors
  const Eigen::VectorXd beta = regress_error(train, settle, lags, stride);

  Eigen::VectorXd f(beta.size());
  std::vector<std::vector<double>> before, after;
  for (const auto& s : held) {
    std::vector<double> b, a;
    for (std::size_t j = settle; j < s.e.size(); ++j) {
      fill_features(s, j, lags, f);
      b.push_back(s.e[j]);
      a.push_back(s.e[j] - f.dot(beta));
    }
    before.push_back(std::move(b));
    after.push_back(std::move(a));
  }
  ExplainableGap g;
  g.heldout_rms = rms_of(before);
  g.heldout_rms_after = rms_of(after);
  g.fraction = 1.0 - g.heldout_rms_after / g.heldout_rms;
  g.test =
      block_bootstrap_test(squared_difference(before, after), opt.block_samples, opt.bootstrap_resamples, opt.seed);
  g.significant = g.test.p_value < opt.alpha && g.fraction >= opt.min_gain;
  return g;
}

}  // namespace noisemon::model::diagnosis
