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

namespace noisemon::model {
namespace {

constexpr double kStepOmega = 0.3;  // h * omega of the fixed integration step
constexpr int kMaxStepsPerSample = 4096;
constexpr double kFiniteDifference = 1e-5;       // in the O(1) fitting coordinates
constexpr double kLogBound = 6.907755278982137;  // ln(1e3): log parameters move at most a factor 1e3
constexpr double kCubicUpper = 1e3;

using State = std::array<double, 4>;  // z, z', and the second mode's w, w'

// ------------------------------------------------------------------------------------------ simulation

BlockModelOptions block_options(const WaveformSimOptions& sim, double fs_hz, int steps) {
  BlockModelOptions o;
  o.input = sim.input;
  o.max_step_s = 1.0 / (fs_hz * steps);
  o.refine = false;  // fixed steps: the output is a smooth function of the parameters
  return o;
}

// BlockModel, or SecondModeModel when the model has a second mode.
class Simulator {
 public:
  Simulator(const WaveformModel& m, double fs_hz, const BlockModelOptions& o) {
    if (m.has_second_mode)
      two_.emplace(m.block, m.second, fs_hz, o);
    else
      one_.emplace(m.block, fs_hz, o);
  }
  std::size_t latency() const { return one_ ? one_->latency_samples() : two_->latency_samples(); }
  void reset() { one_ ? one_->reset() : two_->reset(); }
  void process(const double* u, double* y, std::size_t n) { one_ ? one_->process(u, y, n) : two_->process(u, y, n); }
  void set_state(const State& s) {
    if (one_)
      one_->set_state(s[0], s[1]);
    else
      two_->set_state(s[0], s[1], s[2], s[3]);
  }
  State state() const {
    if (one_) return {one_->position(), one_->velocity(), 0.0, 0.0};
    return {two_->primary().position(), two_->primary().velocity(), two_->second().position(),
            two_->second().velocity()};
  }

 private:
  std::optional<BlockModel> one_;
  std::optional<SecondModeModel> two_;
};

double output_of_state(const WaveformModel& m, const State& s) {
  double y = m.block.c0 * s[0] + m.block.c1 * s[1] + m.y_offset;
  if (m.has_second_mode) y += m.second.c0 * s[2] + m.second.c1 * s[3];
  return y;
}

// Runs the model over one range from a chosen initial state. The interpolator is primed with the range's
// first input held before it (the range alone is used, so ranges are independent); the state is set at the
// instant of the range's first sample.
class SegmentRunner {
 public:
  SegmentRunner(const WaveformModel& m, double fs_hz, const BlockModelOptions& o, std::span<const double> u,
                SampleRange r)
      : m_(m), u_(u), r_(r), sim_(m, fs_hz, o), lat_(sim_.latency()) {}

  double input(std::ptrdiff_t i) const {
    const auto lo = static_cast<std::ptrdiff_t>(r_.begin), hi = static_cast<std::ptrdiff_t>(r_.end) - 1;
    return u_[static_cast<std::size_t>(std::clamp(i, lo, hi))] - m_.u_offset;
  }

  double first_input() const { return input(static_cast<std::ptrdiff_t>(r_.begin)); }

  // Output of range samples [0, n) into out; with `states`, also the state after each sample.
  void run(const State& s0, std::size_t n, double* out, std::vector<State>* states = nullptr) {
    sim_.reset();
    const auto begin = static_cast<std::ptrdiff_t>(r_.begin);
    const auto lat = static_cast<std::ptrdiff_t>(lat_);
    // Input sample i of the stream is output at the instant i - latency: 2 lat + 1 samples bring the model
    // to the instant of the range's first sample.
    buf_in_.resize(std::max<std::size_t>(2 * lat_ + 1, kChunk));
    buf_out_.resize(buf_in_.size());
    for (std::ptrdiff_t i = 0; i <= 2 * lat; ++i) buf_in_[static_cast<std::size_t>(i)] = input(begin - lat + i);
    sim_.process(buf_in_.data(), buf_out_.data(), 2 * lat_ + 1);
    sim_.set_state(s0);
    if (n == 0) return;
    out[0] = output_of_state(m_, s0);
    if (states) {
      states->resize(n);
      (*states)[0] = s0;
    }
    for (std::size_t j = 1; j < n;) {
      const std::size_t k = states ? 1 : std::min(kChunk, n - j);
      for (std::size_t i = 0; i < k; ++i) buf_in_[i] = input(begin + lat + static_cast<std::ptrdiff_t>(j + i));
      sim_.process(buf_in_.data(), out + j, k);
      for (std::size_t i = 0; i < k; ++i) out[j + i] += m_.y_offset;
      if (states) (*states)[j] = sim_.state();
      j += k;
    }
  }

 private:
  static constexpr std::size_t kChunk = 1024;
  const WaveformModel& m_;
  std::span<const double> u_;
  SampleRange r_;
  Simulator sim_;
  std::size_t lat_;
  std::vector<double> buf_in_, buf_out_;
};

// Static equilibrium under a constant input: k1 z + k3 z^3 = u0 (Newton from the linear solution; the
// function is monotone for k3 >= 0).
State equilibrium(const WaveformModel& m, double u0) {
  State s{};
  const BlockParams& p = m.block;
  double z = u0 / p.k1;
  if (p.k3 != 0.0) {
    for (int it = 0; it < 50; ++it) {
      const double f = p.k1 * z + p.k3 * z * z * z - u0;
      const double df = p.k1 + 3.0 * p.k3 * z * z;
      if (!(df > 0)) break;
      const double dz = f / df;
      z -= dz;
      if (std::fabs(dz) <= 1e-14 * std::fabs(z)) break;
    }
  }
  s[0] = std::isfinite(z) ? z : 0.0;
  if (m.has_second_mode && m.second.k1 > 0) s[2] = u0 / m.second.k1;
  return s;
}

// Initial state that best explains the first w outputs (Gauss-Newton with finite differences; one step is
// exact for the linear model, whose step map is affine).
State estimate_initial_state(const WaveformModel& m, SegmentRunner& runner, const double* y, std::size_t w) {
  State s = equilibrium(m, runner.first_input());
  const int d = m.has_second_mode ? 4 : 2;
  if (w < static_cast<std::size_t>(d) + 1) return s;

  double y_rms = 0.0;
  for (std::size_t i = 0; i < w; ++i) y_rms += (y[i] - m.y_offset) * (y[i] - m.y_offset);
  y_rms = std::sqrt(y_rms / static_cast<double>(w)) + 1e-300;
  std::array<double, 4> scale{};
  const double om1 = std::sqrt(m.block.k1 / m.block.m);
  const double zs =
      std::max(y_rms / std::max(std::fabs(m.block.c0) + std::fabs(m.block.c1) * om1, 1e-300), std::fabs(s[0]));
  scale[0] = zs;
  scale[1] = om1 * zs;
  if (m.has_second_mode) {
    const double om2 = std::sqrt(std::max(m.second.k1, 1e-300));
    const double ws =
        std::max(y_rms / std::max(std::fabs(m.second.c0) + std::fabs(m.second.c1) * om2, 1e-300), std::fabs(s[2]));
    scale[2] = ws;
    scale[3] = om2 * ws;
  }

  std::vector<double> base(w), plus(w);
  auto cost_of = [&](const State& st, std::vector<double>& out) {
    runner.run(st, w, out.data());
    double c = 0.0;
    for (std::size_t i = 0; i < w; ++i) c += (out[i] - y[i]) * (out[i] - y[i]);
    return c;
  };
  double best_cost = cost_of(s, base);
  if (!std::isfinite(best_cost)) return s;
  const int iterations = m.block.is_linear() ? 1 : 4;
  Eigen::MatrixXd jac(static_cast<Eigen::Index>(w), d);
  for (int it = 0; it < iterations; ++it) {
    for (int k = 0; k < d; ++k) {
      State sp = s;
      const double h = 1e-4 * scale[static_cast<std::size_t>(k)];
      sp[static_cast<std::size_t>(k)] += h;
      runner.run(sp, w, plus.data());
      for (std::size_t i = 0; i < w; ++i) jac(static_cast<Eigen::Index>(i), k) = (plus[i] - base[i]) / h;
    }
    Eigen::VectorXd r(static_cast<Eigen::Index>(w));
    for (std::size_t i = 0; i < w; ++i) r(static_cast<Eigen::Index>(i)) = base[i] - y[i];
    if (!jac.allFinite() || !r.allFinite()) break;
    Eigen::MatrixXd jtj = jac.transpose() * jac;
    const double ridge = 1e-12 * std::max(jtj.diagonal().maxCoeff(), 1e-300);
    jtj.diagonal().array() += ridge;
    const Eigen::VectorXd delta = jtj.ldlt().solve(-jac.transpose() * r);
    State trial = s;
    for (int k = 0; k < d; ++k) trial[static_cast<std::size_t>(k)] += delta(k);
    const double c = cost_of(trial, plus);
    if (!(c < best_cost)) break;
    best_cost = c;
    s = trial;
    std::swap(base, plus);
    if (c <= 1e-24 * static_cast<double>(w) * y_rms * y_rms) break;
  }
  return s;
}

void check_range(SampleRange r, std::size_t n, std::size_t settle) {
  if (r.end > n || r.size() <= settle + 1)
    throw std::invalid_argument("sample range [" + std::to_string(r.begin) + ", " + std::to_string(r.end) +
                                ") does not fit the data (" + std::to_string(n) + " samples) with " +
                                std::to_string(settle) + " settling samples");
}

std::vector<double> simulate_with_steps(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, int steps,
                                        std::span<const double> u, std::span<const double> y, SampleRange r) {
  check_range(r, std::min(u.size(), y.size()), sim.settle_samples);
  SegmentRunner runner(m, fs_hz, block_options(sim, fs_hz, steps), u, r);
  const State s0 = estimate_initial_state(m, runner, y.data() + r.begin, sim.settle_samples);
  std::vector<double> out(r.size());
  runner.run(s0, r.size(), out.data());
  return out;
}

// States of a run from the held-first-input equilibrium (no estimation): for scales and gain estimates.
std::vector<State> record_states(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, int steps,
                                 std::span<const double> u, SampleRange r) {
  SegmentRunner runner(m, fs_hz, block_options(sim, fs_hz, steps), u, r);
  std::vector<double> out(r.size());
  std::vector<State> states;
  runner.run(equilibrium(m, runner.first_input()), r.size(), out.data(), &states);
  return states;
}

struct StateRms {
  std::array<double, 4> rms{};
  double z_peak = 0.0;
};

StateRms state_rms(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, int steps,
                   std::span<const double> u, std::span<const SampleRange> ranges) {
  StateRms out;
  std::size_t n = 0;
  for (const SampleRange& r : ranges) {
    const auto states = record_states(m, fs_hz, sim, steps, u, r);
    for (std::size_t j = sim.settle_samples; j < states.size(); ++j) {
      for (std::size_t k = 0; k < 4; ++k) out.rms[k] += states[j][k] * states[j][k];
      out.z_peak = std::max(out.z_peak, std::fabs(states[j][0]));
      ++n;
    }
  }
  for (double& v : out.rms) v = std::sqrt(v / static_cast<double>(std::max<std::size_t>(n, 1)));
  return out;
}

// The fixed step of a simulation: given, or chosen from the model and (for a cubic spring) the peak
// displacement it reaches on the ranges.
int steps_for(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, std::span<const double> u,
              std::span<const SampleRange> ranges) {
  if (sim.steps_per_sample > 0) return sim.steps_per_sample;
  const int linear_steps = choose_steps_per_sample(m, fs_hz);
  if (m.block.k3 == 0.0) return linear_steps;
  return choose_steps_per_sample(m, fs_hz, state_rms(m, fs_hz, sim, linear_steps, u, ranges).z_peak);
}

double signal_rms(std::span<const double> x, std::span<const SampleRange> ranges) {
  double s = 0.0;
  std::size_t n = 0;
  for (const SampleRange& r : ranges)
    for (std::size_t i = r.begin; i < r.end; ++i) {
      s += x[i] * x[i];
      ++n;
    }
  return std::sqrt(s / static_cast<double>(std::max<std::size_t>(n, 1)));
}

// Free output gains (c0, c1, c0_2, c1_2, y_offset among `free`) by linear least squares on the recorded states.
void least_squares_gains(WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, int steps,
                         std::span<const double> u, std::span<const double> y, std::span<const SampleRange> ranges,
                         const std::vector<std::string>& free) {
  std::vector<std::string> gains;
  for (const char* g : {"c0", "c1", "c0_2", "c1_2", "y_offset"})
    if (std::find(free.begin(), free.end(), g) != free.end() &&
        (m.has_second_mode || std::string(g).find("_2") == std::string::npos))
      gains.emplace_back(g);
  if (gains.empty()) return;
  const auto g = static_cast<Eigen::Index>(gains.size());
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(g, g);
  Eigen::VectorXd atb = Eigen::VectorXd::Zero(g);
  Eigen::VectorXd row(g);
  for (const SampleRange& r : ranges) {
    const auto states = record_states(m, fs_hz, sim, steps, u, r);
    // Skip the start transient: the estimate ignores the unknown initial state.
    const std::size_t skip = std::max(sim.settle_samples, r.size() / 10);
    for (std::size_t j = skip; j < states.size(); ++j) {
      const State& s = states[j];
      double fixed = 0.0;
      for (Eigen::Index k = 0; k < g; ++k) {
        const std::string& name = gains[static_cast<std::size_t>(k)];
        row(k) = name == "c0" ? s[0] : name == "c1" ? s[1] : name == "c0_2" ? s[2] : name == "c1_2" ? s[3] : 1.0;
      }
      auto add_fixed = [&](const char* name, double value) {
        if (std::find(gains.begin(), gains.end(), name) == gains.end()) fixed += value;
      };
      add_fixed("c0", m.block.c0 * s[0]);
      add_fixed("c1", m.block.c1 * s[1]);
      if (m.has_second_mode) {
        add_fixed("c0_2", m.second.c0 * s[2]);
        add_fixed("c1_2", m.second.c1 * s[3]);
      }
      add_fixed("y_offset", m.y_offset);
      ata.noalias() += row * row.transpose();
      atb.noalias() += row * (y[r.begin + j] - fixed);
    }
  }
  ata.diagonal().array() += 1e-12 * std::max(ata.diagonal().maxCoeff(), 1e-300);
  const Eigen::VectorXd x = ata.ldlt().solve(atb);
  if (!x.allFinite()) return;
  for (Eigen::Index k = 0; k < g; ++k) set_parameter(m, gains[static_cast<std::size_t>(k)], x(k));
}

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

// ------------------------------------------------------------------------------------------ public API

const std::vector<std::string>& waveform_parameter_names() {
  static const std::vector<std::string> names{"k1",   "b1",   "k3",   "b3",   "c0",       "c1",
                                              "k1_2", "b1_2", "c0_2", "c1_2", "u_offset", "y_offset"};
  return names;
}

namespace {
double* parameter_slot(WaveformModel& m, std::string_view name) {
  if (name == "k1") return &m.block.k1;
  if (name == "b1") return &m.block.b1;
  if (name == "k3") return &m.block.k3;
  if (name == "b3") return &m.block.b3;
  if (name == "c0") return &m.block.c0;
  if (name == "c1") return &m.block.c1;
  if (name == "k1_2") return &m.second.k1;
  if (name == "b1_2") return &m.second.b1;
  if (name == "c0_2") return &m.second.c0;
  if (name == "c1_2") return &m.second.c1;
  if (name == "u_offset") return &m.u_offset;
  if (name == "y_offset") return &m.y_offset;
  std::string list;
  for (const auto& n : waveform_parameter_names()) list += " " + n;
  throw std::invalid_argument("unknown waveform-model parameter '" + std::string(name) + "'; known:" + list);
}
}  // namespace

double get_parameter(const WaveformModel& m, std::string_view name) {
  return *parameter_slot(const_cast<WaveformModel&>(m), name);
}
void set_parameter(WaveformModel& m, std::string_view name, double value) { *parameter_slot(m, name) = value; }

double SegmentError::rms() const {
  return count ? std::sqrt(sse / static_cast<double>(count)) : std::numeric_limits<double>::quiet_NaN();
}

SegmentError pooled(std::span<const SegmentError> errors) {
  SegmentError p;
  for (const auto& e : errors) {
    p.sse += e.sse;
    p.count += e.count;
  }
  return p;
}

int choose_steps_per_sample(const WaveformModel& m, double fs_hz, double z_peak) {
  const BlockParams& p = m.block;
  double w2 = std::max(p.k1, p.k1 + 3.0 * p.k3 * z_peak * z_peak) / p.m;
  if (m.has_second_mode) w2 = std::max(w2, m.second.k1);
  const double steps = std::ceil(std::sqrt(std::max(w2, 0.0)) / (kStepOmega * fs_hz));
  if (!std::isfinite(steps)) return kMaxStepsPerSample;
  return static_cast<int>(std::clamp(steps, 1.0, static_cast<double>(kMaxStepsPerSample)));
}

std::vector<double> simulate_waveform(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim,
                                      std::span<const double> u, std::span<const double> y, SampleRange r) {
  check_range(r, std::min(u.size(), y.size()), sim.settle_samples);
  const SampleRange one[1] = {r};
  return simulate_with_steps(m, fs_hz, sim, steps_for(m, fs_hz, sim, u, one), u, y, r);
}

WaveformTrace simulate_waveform_trace(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim,
                                      std::span<const double> u, std::span<const double> y, SampleRange r) {
  check_range(r, std::min(u.size(), y.size()), sim.settle_samples);
  const SampleRange one[1] = {r};
  const int steps = steps_for(m, fs_hz, sim, u, one);
  SegmentRunner runner(m, fs_hz, block_options(sim, fs_hz, steps), u, r);
  const State s0 = estimate_initial_state(m, runner, y.data() + r.begin, sim.settle_samples);
  WaveformTrace t;
  t.y.resize(r.size());
  std::vector<State> states;
  runner.run(s0, r.size(), t.y.data(), &states);
  t.z.resize(states.size());
  t.v.resize(states.size());
  for (std::size_t i = 0; i < states.size(); ++i) {
    t.z[i] = states[i][0];
    t.v[i] = states[i][1];
  }
  return t;
}

std::vector<SegmentError> free_run_errors(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim,
                                          std::span<const double> u, std::span<const double> y,
                                          std::span<const SampleRange> ranges) {
  std::vector<SegmentError> out;
  for (const SampleRange& r : ranges) check_range(r, std::min(u.size(), y.size()), sim.settle_samples);
  const int steps = steps_for(m, fs_hz, sim, u, ranges);
  for (const SampleRange& r : ranges) {
    const auto sim_y = simulate_with_steps(m, fs_hz, sim, steps, u, y, r);
    SegmentError e;
    for (std::size_t j = sim.settle_samples; j < sim_y.size(); ++j) {
      const double d = sim_y[j] - y[r.begin + j];
      e.sse += d * d;
      ++e.count;
    }
    out.push_back(e);
  }
  return out;
}

std::optional<WaveformModel> linear_estimate_from_data(std::span<const double> u, std::span<const double> y,
                                                       double fs_hz, std::span<const SampleRange> train,
                                                       const WaveformSimOptions& sim) {
  // y[n] = a1 y[n-1] + a2 y[n-2] + b0 u[n] + b1 u[n-1] + b2 u[n-2] + c
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> atb = Eigen::Matrix<double, 6, 1>::Zero();
  for (const SampleRange& r : train)
    for (std::size_t n = r.begin + 2; n < r.end; ++n) {
      Eigen::Matrix<double, 6, 1> row;
      row << y[n - 1], y[n - 2], u[n], u[n - 1], u[n - 2], 1.0;
      ata.noalias() += row * row.transpose();
      atb.noalias() += row * y[n];
    }
  const Eigen::Matrix<double, 6, 1> x = ata.ldlt().solve(atb);
  if (!x.allFinite()) return std::nullopt;
  const double a1 = x(0), a2 = x(1);
  const double disc = a1 * a1 + 4.0 * a2;
  double k1 = 0.0, b1 = 0.0;
  if (disc < 0) {
    const std::complex<double> z(a1 / 2.0, std::sqrt(-disc) / 2.0);
    if (!(std::abs(z) < 1.0)) return std::nullopt;
    const std::complex<double> s = std::log(z) * fs_hz;
    k1 = std::norm(s);
    b1 = -2.0 * s.real();
  } else {
    const double z1 = (a1 + std::sqrt(disc)) / 2.0, z2 = (a1 - std::sqrt(disc)) / 2.0;
    if (!(z1 > 0 && z1 < 1 && z2 > 0 && z2 < 1)) return std::nullopt;
    const double s1 = std::log(z1) * fs_hz, s2 = std::log(z2) * fs_hz;
    k1 = s1 * s2;
    b1 = -(s1 + s2);
  }
  WaveformModel m;
  m.block.m = 1.0;
  m.block.k1 = k1;
  m.block.b1 = b1;
  m.block.k3 = m.block.b3 = 0.0;
  m.block.c0 = 1.0;
  m.block.c1 = 0.0;
  if (!(k1 > 0 && b1 > 0 && std::isfinite(k1) && std::isfinite(b1))) return std::nullopt;
  least_squares_gains(m, fs_hz, sim, choose_steps_per_sample(m, fs_hz), u, y, train, {"c0", "c1", "y_offset"});
  return m;
}

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
  const Eigen::VectorXd ev = es.eigenvalues();
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

}  // namespace noisemon::model
