#include "model/motored_tdc.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace noisemon::model {
namespace {

constexpr double kPeakSearchDeg = 60.0;      // the peak is looked for within +-this of the nominal TDC ...
constexpr double kMaxPeakOffsetDeg = 10.0;   // ... and must lie within +-this of it
constexpr double kVertexHalfWidthDeg = 3.0;  // the parabola through the top
constexpr double kFitHalfWidthDeg = 30.0;    // the polytropic fit's window about the peak
constexpr double kScanBeforeDeg = 3.0, kScanAfterDeg = 5.0, kScanStepDeg = 0.02;  // its TDC scan about the peak
constexpr double kPeggingSpanBar = 0.5, kPeggingStepBar = 0.05;
// A motored cycle's fit: an exponent a gas can have and a curve it follows within 2 % (the real Yanmar record: n 1.23,
// 0.7 %; its fired record: n 0.92, 4.3 %).
constexpr double kMinExponent = 1.05, kMaxExponent = 1.45, kMaxFitRms = 0.02;

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

std::vector<double> mean_cycle(std::span<const std::vector<double>> cycles) {
  if (cycles.empty()) throw std::invalid_argument("no motored cycles to find TDC from");
  std::vector<double> m(cycles.front().size(), 0.0);
  for (const std::vector<double>& c : cycles) {
    if (c.size() != m.size())
      throw std::invalid_argument("motored cycles of different lengths (" + std::to_string(c.size()) + " and " +
                                  std::to_string(m.size()) + " samples)");
    for (std::size_t i = 0; i < m.size(); ++i) m[i] += c[i] / static_cast<double>(cycles.size());
  }
  return m;
}

// The vertex of the least-squares parabola through the samples within half_width of index top.
double parabola_vertex(const std::vector<double>& m, std::size_t top, double first_deg, double step_deg,
                       double half_width, double* peak) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  const double at = first_deg + step_deg * static_cast<double>(top);
  for (std::size_t i = 0; i < m.size(); ++i) {
    const double x = first_deg + step_deg * static_cast<double>(i) - at;
    if (std::abs(x) > half_width) continue;
    const Eigen::Vector3d row(1.0, x, x * x);
    A += row * row.transpose();
    b += row * m[i];
  }
  const Eigen::Vector3d c = A.ldlt().solve(b);
  if (!(c[2] < 0)) throw std::invalid_argument("the motored pressure has no maximum near TDC");
  const double x = -c[1] / (2.0 * c[2]);
  *peak = c[0] + c[1] * x + c[2] * x * x;
  return at + x;
}

struct PolytropicFit {
  double tdc_deg = 0.0, exponent = 0.0, rms = std::numeric_limits<double>::infinity();
};

// ln(p - p0) = a - n ln V(theta - tdc) - c (theta - peak) over the window, by linear least squares at one tdc, p0.
PolytropicFit fit_at(const std::vector<double>& m, double first_deg, double step_deg, const EngineGeometry& engine,
                     double peak_deg, double tdc_deg, double p0) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double yy = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    const double theta = first_deg + step_deg * static_cast<double>(i);
    if (std::abs(theta - peak_deg) > kFitHalfWidthDeg) continue;
    if (!(m[i] - p0 > 0)) return {};
    const double y = std::log(m[i] - p0);
    const Eigen::Vector3d row(1.0, -std::log(engine.volume_m3(theta - tdc_deg)), -(theta - peak_deg));
    A += row * row.transpose();
    b += row * y;
    yy += y * y;
    ++n;
  }
  const Eigen::Vector3d c = A.ldlt().solve(b);
  const double sse = std::max(0.0, yy - 2.0 * c.dot(b) + c.dot(A * c));
  return {tdc_deg, c[1], std::sqrt(sse / n)};
}

PolytropicFit polytropic_tdc(const std::vector<double>& m, double first_deg, double step_deg,
                             const EngineGeometry& engine, double peak_deg) {
  PolytropicFit best;
  for (double tdc = peak_deg - kScanBeforeDeg; tdc <= peak_deg + kScanAfterDeg + 1e-9; tdc += kScanStepDeg)
    for (double p0 = -kPeggingSpanBar; p0 <= kPeggingSpanBar + 1e-9; p0 += kPeggingStepBar) {
      const PolytropicFit f = fit_at(m, first_deg, step_deg, engine, peak_deg, tdc, p0);
      if (f.rms < best.rms) best = f;
    }
  return best;
}

}  // namespace

MotoredTdc motored_tdc(std::span<const std::vector<double>> cycles_bar, double first_deg, double step_deg,
                       const EngineGeometry& engine, double loss_angle_deg) {
  if (!(loss_angle_deg >= 0.0 && loss_angle_deg <= kMaxLossAngleDeg))
    throw std::invalid_argument("loss angle " + num(loss_angle_deg) + " deg: expected 0 ... " + num(kMaxLossAngleDeg) +
                                " deg (measured loss angles are 0.4 ... 1.3 deg)");
  if (!(step_deg > 0)) throw std::invalid_argument("the crank-angle step must be positive");
  const std::vector<double> m = mean_cycle(cycles_bar);
  std::size_t top = m.size();
  for (std::size_t i = 0; i < m.size(); ++i) {
    const double theta = first_deg + step_deg * static_cast<double>(i);
    if (std::abs(theta) <= kPeakSearchDeg && (top == m.size() || m[i] > m[top])) top = i;
  }
  if (top == m.size()) throw std::invalid_argument("the motored cycles do not cover TDC (+-60 deg)");
  const double top_deg = first_deg + step_deg * static_cast<double>(top);
  const double last_deg = first_deg + step_deg * static_cast<double>(m.size() - 1);
  if (std::abs(top_deg) > kMaxPeakOffsetDeg)
    throw std::invalid_argument("the motored pressure peaks at " + num(top_deg) +
                                " deg, more than 10 deg from TDC: not a motored cycle (a fired one peaks after TDC), "
                                "or a crank-angle scale not about firing TDC");
  if (top_deg - kFitHalfWidthDeg < first_deg || top_deg + kFitHalfWidthDeg > last_deg)
    throw std::invalid_argument("the motored cycles must cover +-30 deg about their peak");
  MotoredTdc r;
  r.cycles = static_cast<int>(cycles_bar.size());
  r.loss_angle_deg = loss_angle_deg;
  r.peak_deg = parabola_vertex(m, top, first_deg, step_deg, kVertexHalfWidthDeg, &r.peak_bar);
  r.tdc_by_loss_angle_deg = r.peak_deg + loss_angle_deg;
  const PolytropicFit fit = polytropic_tdc(m, first_deg, step_deg, engine, r.peak_deg);
  r.tdc_by_polytropic_deg = fit.tdc_deg;
  r.polytropic_exponent = fit.exponent;
  r.fit_rms = fit.rms;
  if (!(fit.exponent >= kMinExponent && fit.exponent <= kMaxExponent && fit.rms <= kMaxFitRms))
    throw std::invalid_argument(
        "the cycles do not follow a polytropic compression and expansion about their peak "
        "(exponent " +
        num(fit.exponent) + ", rms " + num(100 * fit.rms) +
        " % of the pressure): not a motored cycle (a fired one burns there)");
  return r;
}

}  // namespace noisemon::model
