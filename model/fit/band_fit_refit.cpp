// One surrogate solve on given anchors (no re-simulation): the training conditions' residuals on the shortcut, the
// parameters' bounds, the solve, the block parameters' uncertainty and the training figures.
#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit {
namespace {

using namespace band_fit_internal;

constexpr double kLogBound = 3.0 * std::numbers::ln10;  // +-3 decades around the start

// Pointers into Values in the order of the cost function's parameter blocks.
struct BlockRefs {
  std::vector<double*> ptr;
  std::vector<int> size;
  // What each block is: -1 lin, -2 mode, -3 speed, -4 tn, -5 lexp, >= 0: stationary of add slot s (2s) or
  // locked of add slot s (2s + 1).
  std::vector<int> kind;
};

BlockRefs block_refs(const Layout& L, Values& v) {
  BlockRefs b;
  auto add = [&](double* p, int size, int kind) {
    b.ptr.push_back(p);
    b.size.push_back(size);
    b.kind.push_back(kind);
  };
  if (!v.lin.empty()) add(v.lin.data(), static_cast<int>(v.lin.size()), -1);
  if (L.on.second_mode) add(v.mode.data(), 4, -2);
  if (L.on.speed) add(v.speed.data(), 2, -3);
  if (L.on.transducer) add(v.tn.data(), 2, -4);
  if (L.on.locked) add(v.lexp.data(), 1, -5);
  for (std::size_t s = 0; s < L.add_bands.size(); ++s) {
    if (L.on.stationary) add(&v.stat[s], 1, static_cast<int>(2 * s));
    if (L.on.locked) add(v.locked[s].data(), static_cast<int>(v.locked[s].size()), static_cast<int>(2 * s + 1));
  }
  return b;
}

// Struct indices of a block's entries.
std::vector<int> struct_indices(const Layout& L, int kind) {
  switch (kind) {
    case -1:
      return L.lin_free;
    case -2:
      return {kSModeDb, kSModeLogF, kSModeLogQ, kSModePhase};
    case -3:
      return {kSSpeedGain, kSSpeedShift};
    case -4:
      return {kSTnLogD, kSTnSlope};
    case -5:
      return {kSLockExp};
    default:
      return {};
  }
}

class ConditionCost final : public ceres::CostFunction {
 public:
  ConditionCost(const Layout& L, const CondSetup& c, const BlockRefs& refs, Values& shadow)
      : L_(L), c_(c), refs_(refs), shadow_(shadow) {
    set_num_residuals(static_cast<int>(c.bands.size() + c.wbands.size() * kW));
    for (int s : refs.size) mutable_parameter_block_sizes()->push_back(s);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    CondResiduals out;
    condition_residuals(L_, values_at(parameters), c_, jacobians != nullptr, out);
    const std::size_t nres = out.r.size();
    for (std::size_t r = 0; r < nres; ++r) {
      residuals[r] = out.r[r].a;
      if (!std::isfinite(residuals[r])) return false;
    }
    if (!jacobians) return true;
    for (std::size_t i = 0; i < refs_.kind.size(); ++i)
      if (jacobians[i]) fill_jacobian(i, out, jacobians[i]);
    return true;
  }

 private:
  // The parameter values in a private Values (Ceres may evaluate at trial points).
  Values values_at(double const* const* parameters) const {
    Values v = shadow_;
    for (std::size_t i = 0; i < refs_.kind.size(); ++i) {
      const int kind = refs_.kind[i];
      const double* p = parameters[i];
      switch (kind) {
        case -1:
          std::copy(p, p + refs_.size[i], v.lin.begin());
          break;
        case -2:
          std::copy(p, p + 4, v.mode.begin());
          break;
        case -3:
          std::copy(p, p + 2, v.speed.begin());
          break;
        case -4:
          std::copy(p, p + 2, v.tn.begin());
          break;
        case -5:
          v.lexp[0] = p[0];
          break;
        default: {
          const std::size_t slot = static_cast<std::size_t>(kind / 2);
          if (kind % 2 == 0)
            v.stat[slot] = p[0];
          else
            std::copy(p, p + refs_.size[i], v.locked[slot].begin());
        }
      }
    }
    return v;
  }

  // Jacobian of parameter block i: structural blocks from the Jets, additive ones from the prediction's derivatives.
  void fill_jacobian(std::size_t i, const CondResiduals& out, double* J) const {
    const std::size_t nres = out.r.size();
    const int kind = refs_.kind[i];
    const std::size_t width = static_cast<std::size_t>(refs_.size[i]);
    std::fill(J, J + nres * width, 0.0);
    if (kind < 0) {
      const std::vector<int> idx = struct_indices(L_, kind);
      for (std::size_t r = 0; r < nres; ++r)
        for (std::size_t j = 0; j < width; ++j) J[r * width + j] = out.r[r].v[idx[j]];
      return;
    }
    const std::size_t slot = static_cast<std::size_t>(kind / 2);
    for (std::size_t r = 0; r < nres; ++r) {
      if (out.add_index[r] != slot) continue;
      const double weight = out.window[r] < 0 ? c_.weight : c_.wweight;
      const double scale = -weight * kDbPerNeper / out.pred[r];
      if (kind % 2 == 0) {
        J[r] = scale * out.dpred_add[r];
      } else {
        const std::vector<double>& d = out.dpred_locked[r];
        for (std::size_t j = 0; j < width; ++j) J[r * width + j] = scale * d[j];
      }
    }
  }

  const Layout& L_;
  const CondSetup& c_;
  const BlockRefs& refs_;
  const Values& shadow_;
};

class ProgressCallback final : public ceres::IterationCallback {
 public:
  ProgressCallback(const FitSetup& setup, int anchor, double conditions)
      : setup_(setup), anchor_(anchor), k_(conditions) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (setup_.progress) {
      FitProgress p;
      p.anchor = anchor_;
      p.iteration = s.iteration;
      p.rms_db = std::sqrt(2.0 * s.cost / std::max(1.0, k_));
      p.note = "solver";
      setup_.progress(p);
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitSetup& setup_;
  int anchor_;
  double k_;
};

// The reference speed of the speed extension: the mean speed of the fired conditions (of all when none is fired).
double fired_mean_speed(const BandDataset& data, const std::vector<std::size_t>& conds) {
  double s = 0.0;
  int n = 0;
  for (std::size_t k : conds)
    if (!data.conditions[k].info.motored && !data.conditions[k].info.background) {
      s += data.conditions[k].mean_speed_rpm();
      ++n;
    }
  if (n == 0)
    for (std::size_t k : conds) {
      s += data.conditions[k].mean_speed_rpm();
      ++n;
    }
  return n > 0 ? s / n : 3050.0;
}

// One surrogate problem: the start model, the layout, the training conditions' views and the values Ceres moves.
struct Surrogate {
  ExtendedModel start;
  Layout L;
  std::vector<CondSetup> conds;
  Values v;
  bool taylor = false;  // the block moves on the anchor's exact Jacobian
};

void prepare_surrogate(const FitSetup& setup, const Anchor& anchor, const ExtendedModel& start, Surrogate& sg) {
  const BandDataset& data = *setup.data;
  sg.taylor = !anchor.jac_params.empty();
  std::vector<BlockParam> lin;
  if (sg.taylor) {
    lin = anchor.jac_params;
  } else {
    for (BlockParam p : setup.free)
      if (!is_cubic(p)) lin.push_back(p);
  }
  ExtendedModel& st = sg.start;
  st = start;
  st.on = setup.extensions;
  st.on.mic_gain = start.on.mic_gain;  // fixed gains come with the start model
  st.ext.speed_ref_rpm = fired_mean_speed(data, setup.train);
  sg.L = make_layout(data, anchor.block, st.block, lin, sg.taylor, setup.extensions, setup.train, setup.scored);
  for (std::size_t i = 0; i < anchor.conditions.size(); ++i) {
    if (std::find(setup.train.begin(), setup.train.end(), anchor.conditions[i]) == setup.train.end()) continue;
    CondSetup c = make_cond_setup(data, anchor, i, sg.L, setup, st, st.ext.speed_ref_rpm);
    if (!c.bands.empty()) sg.conds.push_back(std::move(c));
  }
  if (sg.conds.empty()) throw std::invalid_argument("fit: no training condition has a band to score");
  sg.v = initial_values(sg.L, st, sg.conds);
}

void set_bounds(ceres::Problem& problem, const BlockRefs& refs, const Surrogate& sg) {
  const Layout& L = sg.L;
  for (std::size_t i = 0; i < refs.ptr.size(); ++i) {
    double* p = refs.ptr[i];
    switch (refs.kind[i]) {
      case -1:
        for (int j = 0; j < refs.size[i]; ++j) {
          const BlockParam param = param_of_struct(L.lin_free[static_cast<std::size_t>(j)]);
          const double x0 = std::log(param_value(sg.start.block, param) / param_value(L.anchor, param));
          // The Taylor model is trusted within a factor of two around the anchor.
          const double bound = sg.taylor ? std::log(is_cubic(param) ? 4.0 : 2.0) : kLogBound;
          problem.SetParameterLowerBound(p, j, std::min(x0, 0.0) - bound);
          problem.SetParameterUpperBound(p, j, std::max(x0, 0.0) + bound);
        }
        break;
      case -2:
        // a = 10^(dB/20) - 1 >= 0: a dip is a mode in anti-phase (the phase is free), one spelling per model.
        problem.SetParameterLowerBound(p, 0, 0.0);
        problem.SetParameterUpperBound(p, 0, 30.0);
        problem.SetParameterLowerBound(p, 1, std::log(0.05));
        problem.SetParameterUpperBound(p, 1, std::log(18.0));
        problem.SetParameterLowerBound(p, 2, std::log(0.5));
        problem.SetParameterUpperBound(p, 2, std::log(50.0));
        // The phase is periodic: room for a full turn either way from a start at +-180 deg (reported in (-180, 180]).
        problem.SetParameterLowerBound(p, 3, -2.0 * kPi);
        problem.SetParameterUpperBound(p, 3, 2.0 * kPi);
        break;
      case -3:
        problem.SetParameterLowerBound(p, 0, -40.0);
        problem.SetParameterUpperBound(p, 0, 40.0);
        problem.SetParameterLowerBound(p, 1, -0.3);
        problem.SetParameterUpperBound(p, 1, 0.3);
        break;
      case -4:
        problem.SetParameterLowerBound(p, 0, sg.v.tn[0] - 8.0);
        problem.SetParameterUpperBound(p, 0, sg.v.tn[0] + 4.0);
        problem.SetParameterLowerBound(p, 1, -2.0);
        problem.SetParameterUpperBound(p, 1, 2.0);
        break;
      case -5:
        problem.SetParameterLowerBound(p, 0, -4.0);
        problem.SetParameterUpperBound(p, 0, 8.0);
        break;
      default:
        for (int j = 0; j < refs.size[i]; ++j) {
          problem.SetParameterLowerBound(p, j, std::log(kAdditiveFloor));
          problem.SetParameterUpperBound(p, j, std::log(kAdditiveCeil));
        }
    }
  }
}

// Uncertainty of the free linear block parameters: covariance of the log parameters scaled by the residual
// variance (delta method to the parameters themselves).
void block_sigma(const FitSetup& setup, ceres::Problem& problem, const ceres::Solver::Summary& summary, Surrogate& sg,
                 FitOutcome& out) {
  out.sigma.assign(setup.free.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<double>& lin = sg.v.lin;
  if (lin.empty()) return;
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> blocks{{lin.data(), lin.data()}};
  if (!cov.Compute(blocks, &problem)) return;
  std::vector<double> C(lin.size() * lin.size());
  cov.GetCovarianceBlock(lin.data(), lin.data(), C.data());
  const double nres = static_cast<double>(summary.num_residuals);
  const double dof = std::max(1.0, nres - static_cast<double>(summary.num_effective_parameters));
  // Residuals are weighted by 1/sqrt(bands) per condition: the variance of one band's gap is 2 cost
  // * (bands per condition) / dof; the covariance from the weighted problem is scaled to match.
  const double s2 = 2.0 * summary.final_cost / dof;
  ExtendedModel m = model_from_values(sg.L, sg.v, sg.start);
  for (std::size_t i = 0; i < lin.size(); ++i) {
    const BlockParam p = param_of_struct(sg.L.lin_free[i]);
    const auto it = std::find(setup.free.begin(), setup.free.end(), p);
    out.sigma[static_cast<std::size_t>(it - setup.free.begin())] =
        param_value(m.block, p) * std::sqrt(std::max(0.0, C[i * lin.size() + i] * s2));
  }
}

void solve_surrogate(const FitSetup& setup, Surrogate& sg, const BlockRefs& refs, FitOutcome& out) {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (std::size_t i = 0; i < refs.ptr.size(); ++i) problem.AddParameterBlock(refs.ptr[i], refs.size[i]);
  for (const CondSetup& c : sg.conds) {
    ceres::LossFunction* loss = setup.robust ? new ceres::SoftLOneLoss(3.0 * c.weight) : nullptr;
    problem.AddResidualBlock(new ConditionCost(sg.L, c, refs, sg.v), loss, refs.ptr);
  }
  set_bounds(problem, refs, sg);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 60;
  so.function_tolerance = 1e-8;
  so.parameter_tolerance = 1e-8;
  so.logging_type = ceres::SILENT;
  ProgressCallback cb(setup, 0, static_cast<double>(sg.conds.size()));
  if (setup.progress) {
    so.callbacks.push_back(&cb);
    so.update_state_every_iteration = false;
  }
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  out.iterations = static_cast<int>(summary.iterations.size());
  out.converged = summary.termination_type == ceres::CONVERGENCE;
  block_sigma(setup, problem, summary, sg, out);
}

// Training figures at the values (surrogate; exact when the anchor is at the result).
void training_figures(const Surrogate& sg, FitOutcome& out) {
  double sum = 0.0, obj = 0.0;
  for (const CondSetup& c : sg.conds) {
    CondResiduals r;
    condition_residuals(sg.L, sg.v, c, false, r);
    double ms = 0.0;
    for (std::size_t i = 0; i < c.bands.size(); ++i) ms += std::pow(r.r[i].a / c.weight, 2);
    for (const Jet& x : r.r) obj += x.a * x.a;
    sum += std::sqrt(ms / static_cast<double>(c.bands.size()));
  }
  out.train_rms_db = sum / static_cast<double>(sg.conds.size());
  out.objective = obj;
}

}  // namespace

FitOutcome refit_on_anchor(const FitSetup& setup, const Anchor& anchor, const ExtendedModel& start) {
  Surrogate sg;
  prepare_surrogate(setup, anchor, start, sg);
  const BlockRefs refs = block_refs(sg.L, sg.v);
  FitOutcome out;
  out.free = setup.free;
  for (int sz : refs.size) out.parameters += sz;
  if (!refs.ptr.empty() && !setup.evaluate_only) solve_surrogate(setup, sg, refs, out);
  out.model = model_from_values(sg.L, sg.v, sg.start);
  training_figures(sg, out);
  return out;
}

}  // namespace noisemon::model::fit
