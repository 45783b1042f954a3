#include "daemon/crank_grid.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace noisemon::daemon {
namespace {
constexpr double kOnPoint = 1e-6;  // of a step: a sample this close to a point is on it
}  // namespace

CrankGrid::CrankGrid(double step_deg) : step_deg_(step_deg) {
  if (!(step_deg >= 0.01 && step_deg <= 6.0))
    throw std::invalid_argument("crank-angle grid step " + std::to_string(step_deg) + " deg (0.01 ... 6 expected)");
  values_.assign(static_cast<std::size_t>(std::lround(720.0 / step_deg)) + 1, kNaN);
}

void CrankGrid::clear(double origin_deg) {
  std::fill(values_.begin(), values_.end(), kNaN);
  origin_deg_ = origin_deg;
  has_last_ = false;
}

void CrankGrid::add(double crank_deg, double pressure_pa) {
  if (has_last_ && crank_deg > last_deg_) {
    // Grid points in (last, this]: linear between the two samples (a sample on a point gives it exactly).
    const double from = (last_deg_ - origin_deg_) / step_deg_, to = (crank_deg - origin_deg_) / step_deg_;
    const auto n = static_cast<std::int64_t>(values_.size());
    // A sample on a point (an edge on its own grid) is that point, whatever the rounding of the division.
    const auto first = static_cast<std::int64_t>(std::floor(from + kOnPoint)) + 1;
    const auto last = static_cast<std::int64_t>(std::floor(to + kOnPoint));
    for (std::int64_t k = std::max<std::int64_t>(first, 0); k <= std::min<std::int64_t>(last, n - 1); ++k) {
      const double x = std::min(1.0, (static_cast<double>(k) - from) / (to - from));
      values_[static_cast<std::size_t>(k)] = last_pa_ + x * (pressure_pa - last_pa_);
    }
  }
  last_deg_ = crank_deg;
  last_pa_ = pressure_pa;
  has_last_ = true;
}

void CrankGrid::close(double crank_deg, double pressure_pa) {
  has_carry_ = has_last_;
  carry_deg_ = last_deg_ - 720.0;
  carry_pa_ = last_pa_;
  add(crank_deg + 720.0, pressure_pa);
}

void CrankGrid::reopen(double origin_deg) {
  clear(origin_deg);
  has_last_ = has_carry_;
  last_deg_ = carry_deg_;
  last_pa_ = carry_pa_;
}

bool CrankGrid::complete() const {
  return std::none_of(values_.begin(), values_.end(), [](double v) { return std::isnan(v); });
}

model::CombustionMetrics CrankGrid::metrics(const model::EngineGeometry& engine, double speed_rpm,
                                            const model::MetricsOptions& options, model::MetricsWorkspace& scratch) {
  // The points but the last are one period; the last (+360) is then the period's first again.
  const auto n = static_cast<long>(values_.size()) - 1, k = std::lround(options.tdc_deg / step_deg_);
  if (k % n != 0) {
    std::rotate(values_.begin(), values_.begin() + ((k % n) + n) % n, values_.end() - 1);
    values_.back() = values_.front();
  }
  const double first = origin_deg_ + static_cast<double>(k) * step_deg_ - options.tdc_deg;
  return model::combustion_metrics(values_, first, step_deg_, engine, speed_rpm, options, scratch);
}

}  // namespace noisemon::daemon
