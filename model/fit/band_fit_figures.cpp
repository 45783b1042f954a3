// The measured side and the figures: gain-corrected measured band levels, the gap per band, its RMS.
#include <cmath>
#include <limits>

#include "model/fit/band_fit.hpp"

namespace noisemon::model::fit {

double measured_ms(const ConditionData& c, std::size_t cycle, std::size_t b, const ExtendedModel& model) {
  if (!model.on.mic_gain || model.ext.mic_gain_db.size() != c.mics) return c.mic_avg_ms(cycle, b);
  double s = 0.0;
  for (std::size_t m = 0; m < c.mics; ++m)
    s += c.mic_ms[(cycle * c.mics + m) * c.bands + b] * std::pow(10.0, -model.ext.mic_gain_db[m] / 10.0);
  return s / static_cast<double>(c.mics);
}

std::vector<double> condition_gaps(const ConditionData& cond, const std::vector<double>& pred_ms,
                                   const std::vector<char>& scored, const ExtendedModel& model) {
  const std::size_t nb = cond.bands, nc = cond.cycle_count();
  std::vector<double> gaps(nb, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t b = 0; b < nb; ++b) {
    if (!scored[b]) continue;
    double m = 0.0, p = 0.0;
    for (std::size_t c = 0; c < nc; ++c) {
      m += measured_ms(cond, c, b, model);
      p += pred_ms[c * nb + b];
    }
    if (m > 0 && p > 0) gaps[b] = 10.0 * std::log10(m / p);
  }
  return gaps;
}

double rms_db(const std::vector<double>& gaps) {
  double s = 0.0;
  int n = 0;
  for (double g : gaps)
    if (std::isfinite(g)) {
      s += g * g;
      ++n;
    }
  return n > 0 ? std::sqrt(s / n) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace noisemon::model::fit
