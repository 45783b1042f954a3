#include "model/fit/waveform_fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <complex>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>

#include "model/fit/waveform_sim.hpp"

namespace noisemon::model::fit {
namespace {

constexpr double kFiniteDifference = 1e-5;       // in the O(1) fitting coordinates
constexpr double kLogBound = 6.907755278982137;  // ln(1e3): log parameters move at most a factor 1e3
constexpr double kCubicUpper = 1e3;

using detail::check_range;
using detail::least_squares_gains;
using detail::signal_rms;
using detail::simulate_with_steps;
using detail::state_rms;
using detail::StateRms;
using detail::steps_for;

// ---------------------------------------------------------------------------------------------- fitting

struct ParamMap {
  std::string name;
  bool log = false;
  double ref = 0.0;    // log: value at theta = 0
  double scale = 1.0;  // linear: value = scale * theta
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  double value(double theta) const { return log ? ref * std::exp(theta) : scale * theta; }
  double theta(double v) const { return log ? std::log(v / ref) : v / scale; }
  double derivative(double theta) const { return log ? ref * std::exp(theta) : scale; }
};

struct FitContext {
  std::span<const double> u, y;
  double fs = 0.0;
  WaveformSimOptions sim;
  int steps = 1;
  std::vector<SampleRange> train;
  WaveformModel base;
  std::vector<ParamMap> maps;
  std::size_t n_scored = 0;

  WaveformModel decode(const double* theta) const {
    WaveformModel m = base;
    for (std::size_t k = 0; k < maps.size(); ++k) set_parameter(m, maps[k].name, maps[k].value(theta[k]));
    return m;
  }
  // Scaled residuals (model - measured) / sqrt(N) over the scored training samples; false if not finite.
  bool residuals(const double* theta, double* r) const {
    const WaveformModel m = decode(theta);
    const double w = 1.0 / std::sqrt(static_cast<double>(n_scored));
    std::size_t at = 0;
    for (const SampleRange& seg : train) {
      const auto out = simulate_with_steps(m, fs, sim, steps, u, y, seg);
      for (std::size_t j = sim.settle_samples; j < out.size(); ++j) {
        const double e = (out[j] - y[seg.begin + j]) * w;
        if (!std::isfinite(e)) return false;
        r[at++] = e;
      }
    }
    return true;
  }
  // Row-major N x p Jacobian of the scaled residuals by finite differences: forward from the residuals r0
  // at theta (half the simulations: what the solver iterates with), or central (for the covariance).
  bool jacobian(const double* theta, const double* r0, double* jac) const {
    const std::size_t p = maps.size();
    std::vector<double> th(theta, theta + p), rp(n_scored), rm(n_scored);
    for (std::size_t k = 0; k < p; ++k) {
      th[k] = theta[k] + kFiniteDifference;
      if (!residuals(th.data(), rp.data())) return false;
      if (r0) {
        std::copy(r0, r0 + n_scored, rm.begin());
        th[k] = theta[k];
      } else {
        th[k] = theta[k] - kFiniteDifference;
        if (!residuals(th.data(), rm.data())) return false;
        th[k] = theta[k];
      }
      const double h = r0 ? kFiniteDifference : 2.0 * kFiniteDifference;
      for (std::size_t i = 0; i < n_scored; ++i) jac[i * p + k] = (rp[i] - rm[i]) / h;
    }
    return true;
  }
};

class FreeRunCost final : public ceres::CostFunction {
 public:
  explicit FreeRunCost(const FitContext& ctx) : ctx_(ctx) {
    set_num_residuals(static_cast<int>(ctx.n_scored));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(ctx.maps.size()));
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    if (!ctx_.residuals(parameters[0], residuals)) return false;
    if (jacobians && jacobians[0]) return ctx_.jacobian(parameters[0], residuals, jacobians[0]);
    return true;
  }

 private:
  const FitContext& ctx_;
};

class ProgressCallback final : public ceres::IterationCallback {
 public:
  ProgressCallback(const FitContext& ctx, const double* theta, const WaveformFitOptions& opt,
                   std::chrono::steady_clock::time_point t0)
      : ctx_(ctx), theta_(theta), opt_(opt), t0_(t0) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (opt_.progress) {
      WaveformFitProgress p;
      p.iteration = s.iteration;
      p.train_rms = std::sqrt(2.0 * s.cost);
      p.step_accepted = s.step_is_successful;
      p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
      p.model = ctx_.decode(theta_);
      opt_.progress(p);
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitContext& ctx_;
  const double* theta_;
  const WaveformFitOptions& opt_;
  std::chrono::steady_clock::time_point t0_;
};

std::size_t scored_count(std::span<const SampleRange> ranges, std::size_t settle) {
  std::size_t n = 0;
  for (const SampleRange& r : ranges) n += r.size() - settle;
  return n;
}

void validate(std::span<const double> u, std::span<const double> y, const WaveformFitOptions& opt) {
  if (u.size() != y.size()) throw std::invalid_argument("waveform fit: input and output differ in length");
  if (!(opt.fs_hz > 0) || !std::isfinite(opt.fs_hz)) throw std::invalid_argument("waveform fit: fs must be positive");
  if (opt.train.empty()) throw std::invalid_argument("waveform fit: no training range");
  for (const SampleRange& r : opt.train) check_range(r, u.size(), opt.sim.settle_samples);
  for (const SampleRange& r : opt.heldout) check_range(r, u.size(), opt.sim.settle_samples);
  if (opt.free_params.empty()) throw std::invalid_argument("waveform fit: no free parameter");
  for (std::size_t i = 0; i < opt.free_params.size(); ++i) {
    const auto& names = waveform_parameter_names();
    if (std::find(names.begin(), names.end(), opt.free_params[i]) == names.end())
      throw std::invalid_argument("waveform fit: unknown parameter '" + opt.free_params[i] + "'");
    for (std::size_t j = 0; j < i; ++j)
      if (opt.free_params[j] == opt.free_params[i])
        throw std::invalid_argument("waveform fit: parameter '" + opt.free_params[i] + "' given twice");
  }
}

// Block length for the sandwich covariance and the bootstraps: about 50 blocks, at least 64 samples.
std::size_t block_length(std::size_t n) { return std::max<std::size_t>(64, n / 50); }

struct CoreResult {
  WaveformModel model;
  int iterations = 0;
  bool converged = false;
  std::string message;
};

CoreResult solve(FitContext& ctx, const WaveformFitOptions& opt, std::chrono::steady_clock::time_point t0) {
  const std::size_t p = ctx.maps.size();
  std::vector<double> theta(p);
  for (std::size_t k = 0; k < p; ++k)
    theta[k] =
        std::clamp(ctx.maps[k].theta(get_parameter(ctx.base, ctx.maps[k].name)), ctx.maps[k].lower, ctx.maps[k].upper);
  ceres::Problem::Options popt;
  ceres::Problem problem(popt);
  problem.AddResidualBlock(new FreeRunCost(ctx), nullptr, theta.data());
  for (std::size_t k = 0; k < p; ++k) {
    const int i = static_cast<int>(k);
    if (std::isfinite(ctx.maps[k].lower)) problem.SetParameterLowerBound(theta.data(), i, ctx.maps[k].lower);
    if (std::isfinite(ctx.maps[k].upper)) problem.SetParameterUpperBound(theta.data(), i, ctx.maps[k].upper);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = opt.max_iterations;
  so.function_tolerance = opt.function_tolerance;
  so.parameter_tolerance = 1e-10;
  so.gradient_tolerance = 1e-14;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.num_threads = 1;
  so.update_state_every_iteration = true;
  ProgressCallback cb(ctx, theta.data(), opt, t0);
  so.callbacks.push_back(&cb);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  CoreResult out;
  out.model = ctx.decode(theta.data());
  out.iterations = static_cast<int>(summary.iterations.size()) - 1;
  out.converged = summary.termination_type == ceres::CONVERGENCE;
  out.message = summary.message;
  if (!summary.IsSolutionUsable()) throw std::runtime_error("waveform fit failed: " + summary.message);
  return out;
}

// Parameter maps around the start model (see the header for the choices).
std::vector<ParamMap> make_maps(const WaveformModel& start, const std::vector<std::string>& free, const StateRms& st,
                                double u_rms, double y_rms, double fs_hz) {
  std::vector<ParamMap> maps;
  for (const std::string& name : free) {
    ParamMap pm;
    pm.name = name;
    const double v = get_parameter(start, name);
    if (name == "k1" || name == "b1" || name == "k1_2" || name == "b1_2") {
      if (!(v > 0))
        throw std::invalid_argument("waveform fit: the start value of " + name + " must be positive to be fitted");
      pm.log = true;
      pm.ref = v;
      pm.lower = -kLogBound;
      pm.upper = kLogBound;
      if (name == "k1_2") {  // a mode above Nyquist is not identifiable from the samples: keep it below 0.45 fs
        const double w_max = 2.0 * std::numbers::pi * 0.45 * fs_hz;
        pm.upper = std::min(pm.upper, std::log(w_max * w_max / v));
        if (pm.upper <= pm.lower) throw std::invalid_argument("waveform fit: the second mode starts above 0.45 fs");
      }
    } else if (name == "k3" || name == "b3") {
      const double rms = name == "k3" ? st.rms[0] : st.rms[1];
      const double lin = name == "k3" ? start.block.k1 : start.block.b1;
      pm.scale = lin / (rms * rms);
      pm.lower = 0.0;
      pm.upper = kCubicUpper;
      if (v < 0) throw std::invalid_argument("waveform fit: the start value of " + name + " must be >= 0");
    } else if (name == "c0" || name == "c1" || name == "c0_2" || name == "c1_2") {
      const std::size_t k = name == "c0" ? 0 : name == "c1" ? 1 : name == "c0_2" ? 2 : 3;
      pm.scale = y_rms / st.rms[k];
    } else if (name == "u_offset") {
      pm.scale = u_rms;
    } else {  // y_offset
      pm.scale = y_rms;
    }
    if (!(std::isfinite(pm.scale) && pm.scale > 0)) pm.scale = 1.0;
    maps.push_back(pm);
  }
  return maps;
}

double train_rms_of(const WaveformModel& m, double fs, const WaveformSimOptions& sim, int steps,
                    std::span<const double> u, std::span<const double> y, std::span<const SampleRange> ranges) {
  double sse = 0.0;
  std::size_t n = 0;
  for (const SampleRange& r : ranges) {
    const auto out = simulate_with_steps(m, fs, sim, steps, u, y, r);
    for (std::size_t j = sim.settle_samples; j < out.size(); ++j) {
      sse += (out[j] - y[r.begin + j]) * (out[j] - y[r.begin + j]);
      ++n;
    }
  }
  const double rms = std::sqrt(sse / static_cast<double>(std::max<std::size_t>(n, 1)));
  return std::isfinite(rms) ? rms : std::numeric_limits<double>::infinity();
}

}  // namespace

namespace {

// The start (see the header): the given model (its free gains refined by least squares where that lowers the
// training error), or the nearest of the presets whose resonance lies below Nyquist and the data's linear estimate.
void choose_start(std::span<const double> u, std::span<const double> y, const WaveformFitOptions& opt,
                  WaveformFitResult& res) {
  auto refine = [&](WaveformModel m) {
    if (opt.refine_start_gains)
      least_squares_gains(m, opt.fs_hz, opt.sim, steps_for(m, opt.fs_hz, opt.sim, u, opt.train), u, y, opt.train,
                          opt.free_params);
    return m;
  };
  auto rms_of = [&](const WaveformModel& m) {
    return train_rms_of(m, opt.fs_hz, opt.sim, steps_for(m, opt.fs_hz, opt.sim, u, opt.train), u, y, opt.train);
  };
  if (opt.start) {
    res.start = *opt.start;
    res.start_name = opt.start_name.empty() ? "given" : opt.start_name;
    res.start_train_rms = rms_of(res.start);
    const WaveformModel refined = refine(res.start);
    const double r = rms_of(refined);
    if (r < res.start_train_rms) {
      res.start = refined;
      res.start_train_rms = r;
    }
    return;
  }
  res.start_train_rms = std::numeric_limits<double>::infinity();
  for (const std::string& name : preset_names()) {
    WaveformModel m;
    m.block = preset(name);
    if (std::sqrt(m.block.k1 / m.block.m) / (2.0 * std::numbers::pi) >= 0.5 * opt.fs_hz) continue;
    m = refine(m);
    const double r = rms_of(m);
    if (r < res.start_train_rms) {
      res.start = m;
      res.start_name = name;
      res.start_train_rms = r;
    }
  }
  if (auto est = linear_estimate_from_data(u, y, opt.fs_hz, opt.train, opt.sim)) {
    const double r = rms_of(*est);
    if (r < res.start_train_rms) {
      res.start = *est;
      res.start_name = "data";
      res.start_train_rms = r;
    }
  }
  if (!std::isfinite(res.start_train_rms))
    throw std::runtime_error("waveform fit: no usable start (no preset below Nyquist and no stable linear estimate)");
}

// The solve from the start, repeated (at most three rounds) while the fitted model needs finer integration steps
// than it was fitted with. Leaves ctx at the last round's maps; steps and iterations: the last round's step, the
// iterations of all rounds.
CoreResult fit_rounds(FitContext& ctx, const WaveformFitOptions& opt, const WaveformModel& start,
                      std::chrono::steady_clock::time_point t0, int& steps, int& iterations) {
  const double u_rms = signal_rms(ctx.u, opt.train), y_rms = signal_rms(ctx.y, opt.train);
  WaveformModel current = start;
  CoreResult core;
  steps = 0;
  iterations = 0;
  for (int round = 0; round < 3; ++round) {
    const int steps_now = steps_for(current, opt.fs_hz, opt.sim, ctx.u, opt.train);
    if (round > 0 && steps_now <= steps) break;
    steps = steps_now;
    const StateRms st = state_rms(current, opt.fs_hz, opt.sim, steps, ctx.u, opt.train);
    ctx.steps = steps;
    ctx.base = current;
    ctx.maps = make_maps(current, opt.free_params, st, u_rms, y_rms, opt.fs_hz);
    core = solve(ctx, opt, t0);
    iterations += core.iterations;
    current = core.model;
    if (opt.sim.steps_per_sample > 0) break;
  }
  core.model = current;
  return core;
}

using RowMajorMap = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;

// The sandwich's meat: the scores J^T r summed over blocks of neighbouring samples (within each range).
Eigen::MatrixXd block_scores(const RowMajorMap& J, const Eigen::Map<Eigen::VectorXd>& R, const WaveformFitOptions& opt,
                             std::size_t n, std::size_t p) {
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(p), static_cast<Eigen::Index>(p));
  std::size_t at = 0;
  for (const SampleRange& seg : opt.train) {
    const std::size_t len = seg.size() - opt.sim.settle_samples;
    const std::size_t bl = block_length(n);
    for (std::size_t b0 = 0; b0 < len; b0 += bl) {
      const std::size_t b1 = std::min(len, b0 + bl);
      const auto rows = static_cast<Eigen::Index>(b1 - b0);
      const Eigen::VectorXd g = J.middleRows(static_cast<Eigen::Index>(at + b0), rows).transpose() *
                                R.segment(static_cast<Eigen::Index>(at + b0), rows);
      meat.noalias() += g * g.transpose();
    }
    at += len;
  }
  return meat;
}

// The training error and the uncertainty from the Jacobian at the optimum res.model (in data units).
void add_uncertainty(const FitContext& ctx, const WaveformFitOptions& opt, WaveformFitResult& res) {
  const std::size_t p = ctx.maps.size(), n = ctx.n_scored;
  std::vector<double> theta(p);
  for (std::size_t k = 0; k < p; ++k) theta[k] = ctx.maps[k].theta(get_parameter(res.model, ctx.maps[k].name));
  std::vector<double> r(n), jac(n * p);
  ctx.residuals(theta.data(), r.data());
  const bool jac_ok = ctx.jacobian(theta.data(), nullptr, jac.data());
  const double sqrt_n = std::sqrt(static_cast<double>(n));
  RowMajorMap J(jac.data(), static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(p));
  Eigen::Map<Eigen::VectorXd> R(r.data(), static_cast<Eigen::Index>(n));
  J *= sqrt_n;
  R *= sqrt_n;
  const double sse = R.squaredNorm();
  res.train_samples = n;
  res.train_rms = std::sqrt(sse / static_cast<double>(n));
  res.residual_sigma = std::sqrt(sse / static_cast<double>(n - p));
  res.sigma.assign(p, std::numeric_limits<double>::quiet_NaN());
  res.sigma_blocks.assign(p, std::numeric_limits<double>::quiet_NaN());
  res.at_bound.assign(p, false);
  for (std::size_t k = 0; k < p; ++k) {
    const double th = theta[k];
    const auto& m = ctx.maps[k];
    res.at_bound[k] =
        (std::isfinite(m.lower) && th <= m.lower + 1e-9) || (std::isfinite(m.upper) && th >= m.upper - 1e-9);
  }
  if (!jac_ok) return;
  const Eigen::MatrixXd jtj = J.transpose() * J;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(jtj);
  const Eigen::VectorXd& ev = es.eigenvalues();
  const double tol = ev.maxCoeff() * 1e-14;
  Eigen::VectorXd inv_ev(ev.size());
  for (Eigen::Index i = 0; i < ev.size(); ++i) inv_ev(i) = ev(i) > tol ? 1.0 / ev(i) : 0.0;
  const Eigen::MatrixXd jtj_inv = es.eigenvectors() * inv_ev.asDiagonal() * es.eigenvectors().transpose();
  const Eigen::MatrixXd cov = res.residual_sigma * res.residual_sigma * jtj_inv;
  const Eigen::MatrixXd meat = block_scores(J, R, opt, n, p);
  const Eigen::MatrixXd cov_b = jtj_inv * meat * jtj_inv * (static_cast<double>(n) / static_cast<double>(n - p));
  const bool singular = (ev.array() <= tol).any();
  for (std::size_t k = 0; k < p; ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    const double d = std::fabs(ctx.maps[k].derivative(theta[k]));
    res.sigma[k] = singular ? std::numeric_limits<double>::infinity() : d * std::sqrt(cov(i, i));
    res.sigma_blocks[k] = singular ? std::numeric_limits<double>::infinity() : d * std::sqrt(cov_b(i, i));
  }
}

}  // namespace

WaveformFitResult fit_waveform(std::span<const double> u, std::span<const double> y, const WaveformFitOptions& opt) {
  validate(u, y, opt);
  const auto t0 = std::chrono::steady_clock::now();
  const bool second_free = std::any_of(opt.free_params.begin(), opt.free_params.end(),
                                       [](const std::string& n) { return n.find("_2") != std::string::npos; });
  WaveformFitResult res;
  choose_start(u, y, opt, res);
  if (second_free && !res.start.has_second_mode)
    throw std::invalid_argument("waveform fit: second-mode parameters are free but the start has no second mode");

  FitContext ctx;
  ctx.u = u;
  ctx.y = y;
  ctx.fs = opt.fs_hz;
  ctx.sim = opt.sim;
  ctx.train = opt.train;
  ctx.n_scored = scored_count(opt.train, opt.sim.settle_samples);
  if (ctx.n_scored <= opt.free_params.size())
    throw std::invalid_argument("waveform fit: fewer scored samples than free parameters");
  int steps = 0, iterations = 0;
  const CoreResult core = fit_rounds(ctx, opt, res.start, t0, steps, iterations);
  res.model = core.model;
  res.free_params = opt.free_params;
  res.iterations = iterations;
  res.converged = core.converged;
  res.solver_message = core.message;
  res.steps_per_sample = steps;
  add_uncertainty(ctx, opt, res);

  WaveformSimOptions held_sim = opt.sim;
  held_sim.steps_per_sample = steps;
  const auto held = free_run_errors(res.model, opt.fs_hz, held_sim, u, y, opt.heldout);
  for (const auto& e : held) res.heldout_segment_rms.push_back(e.rms());
  const SegmentError hp = pooled(held);
  res.heldout_rms = hp.rms();
  res.heldout_samples = hp.count;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace noisemon::model::fit
