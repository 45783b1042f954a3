#include "model/fit/waveform_sim.hpp"

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

namespace noisemon::model::fit {
namespace {

constexpr double kStepOmega = 0.3;  // h * omega of the fixed integration step
constexpr int kMaxStepsPerSample = 4096;

using detail::State;

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

}  // namespace

namespace detail {

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

}  // namespace detail

using detail::check_range;
using detail::least_squares_gains;
using detail::simulate_with_steps;
using detail::steps_for;

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

}  // namespace noisemon::model::fit
