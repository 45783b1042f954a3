#include "model/fit/pressure_floor.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit {
namespace {

constexpr double kEstimateFromHz = 1000.0;  // the quiet windows' true pressure is far below any floor up here
constexpr double kGridMaxHz = 0.5 * kDatasetRateHz;

double median(std::vector<double> v) {
  if (v.empty()) return PressureFloor::kNaN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The floor's upper frequency on the 40 kHz grid for an encoder rate (NaN: unknown, the whole grid).
double floor_upper_hz(double encoder_rate_hz) {
  return std::isfinite(encoder_rate_hz) && encoder_rate_hz > 0 ? std::min(0.5 * encoder_rate_hz, kGridMaxHz)
                                                               : kGridMaxHz;
}

// Per band: the quiet-window pressure over the band's noise bandwidth (see the header); empty when no band is fast
// enough for a crank window.
std::vector<double> estimate_floor(const BandDataset& data, std::size_t k, double upper_hz, double& white) {
  const ConditionData& d = data.conditions[k];
  const std::vector<char> fast = window_capable_bands(data, {k});
  const std::vector<double> win = mean_window_cpl(d);
  const std::size_t nb = d.bands;
  std::vector<double> out(nb, PressureFloor::kNaN), used;
  for (std::size_t b = 0; b < nb; ++b) {
    const dsp::ThirdOctaveBand& band = data.bands[b];
    if (!fast[b] || band.exact_mid_hz < kEstimateFromHz) continue;
    const double bw = band_noise_bandwidth(band, kGridMaxHz);
    double quiet = win[b * kW];
    for (std::size_t w = 1; w < kW; ++w) quiet = std::min(quiet, win[b * kW + w]);
    if (!(bw > 0) || !(quiet >= 0)) continue;
    out[b] = quiet / bw;
    if (band.upper_edge_hz <= upper_hz) used.push_back(out[b]);
  }
  white = median(used);
  // Bands without an estimate: the nearest estimated band's density (the slow low bands; the Nyquist-cut band).
  std::size_t first = nb;
  for (std::size_t b = 0; b < nb && first == nb; ++b)
    if (std::isfinite(out[b])) first = b;
  if (first == nb) return {};
  for (std::size_t b = 0; b < first; ++b) out[b] = out[first];
  for (std::size_t b = first + 1; b < nb; ++b)
    if (!std::isfinite(out[b])) out[b] = out[b - 1];
  return out;
}

// The stated floor: white, 2 sigma^2 / f_encoder, in the bands below the encoder's Nyquist frequency.
std::vector<double> stated_floor(const BandDataset& data, double sigma_pa, double encoder_rate_hz) {
  const double upper = floor_upper_hz(encoder_rate_hz), density = 2.0 * sigma_pa * sigma_pa / encoder_rate_hz;
  std::vector<double> out;
  for (const dsp::ThirdOctaveBand& band : data.bands) {
    const double share = std::clamp((upper - band.lower_edge_hz) / (band.upper_edge_hz - band.lower_edge_hz), 0.0, 1.0);
    out.push_back(density * share);
  }
  return out;
}

// Per band: the mean square a floor of these per-band densities leaves through each band's filter on the grid.
std::vector<double> floor_band_ms(const BandDataset& data, const std::vector<double>& density) {
  std::vector<double> out(data.band_count(), 0.0);
  for (std::size_t b = 0; b < density.size() && b < data.band_count(); ++b)
    out[b] = density[b] * band_noise_bandwidth(data.bands[b], kGridMaxHz);
  return out;
}

}  // namespace

double PressureFloor::estimated_rms_per_sample_pa(double encoder_rate_hz) const {
  return std::isfinite(encoder_rate_hz) && encoder_rate_hz > 0 ? std::sqrt(0.5 * estimated_white * encoder_rate_hz)
                                                               : kNaN;
}

double PressureFloor::estimated_rms_on_grid_pa(const BandDataset& data) const {
  if (estimated.empty()) return kNaN;
  const std::vector<double> ms = floor_band_ms(data, estimated);
  return std::sqrt(std::accumulate(ms.begin(), ms.end(), 0.0));
}

double band_noise_bandwidth(const dsp::ThirdOctaveBand& band, double f_max_hz) {
  // Trapezoid rule on a grid fine against the band's width (the response is smooth on it).
  const double lo = std::max(1.0, band.lower_edge_hz / 4.0), hi = std::min(f_max_hz, band.upper_edge_hz * 4.0);
  if (!(hi > lo)) return 0.0;
  const std::size_t n = 4000;
  const double step = std::log(hi / lo) / static_cast<double>(n);  // log grid: df = f d(ln f)
  double sum = 0.0;
  for (std::size_t i = 0; i <= n; ++i) {
    const double f = lo * std::exp(step * static_cast<double>(i));
    sum += (i == 0 || i == n ? 0.5 : 1.0) * band_fit_internal::band_power_response(band, f) * f;
  }
  return sum * step;
}

std::vector<double> mean_window_cpl(const ConditionData& d) {
  const std::size_t nb = d.bands, nc = d.cycle_count();
  std::vector<double> out(nb * kW, 0.0);
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t w = 0; w < kW; ++w)
      for (std::size_t b = 0; b < nb; ++b)
        out[b * kW + w] += d.cpl_win_ms[(c * kW + w) * nb + b] / static_cast<double>(nc);
  return out;
}

std::vector<double> mean_band_cpl(const ConditionData& d) {
  const std::size_t nb = d.bands, nc = d.cycle_count();
  std::vector<double> out(nb, 0.0);
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t b = 0; b < nb; ++b) out[b] += d.cpl_ms[c * nb + b] / static_cast<double>(nc);
  return out;
}

std::vector<double> quiet_window_mic_ms(const BandDataset& data, std::size_t k) {
  const ConditionData& d = data.conditions[k];
  const std::size_t nb = d.bands, nc = d.cycle_count();
  const std::vector<char> fast = window_capable_bands(data, {k});
  std::vector<double> out(nb, PressureFloor::kNaN);
  for (std::size_t b = 0; b < nb; ++b) {
    if (!fast[b]) continue;
    for (std::size_t w = 0; w < kW; ++w) {
      double s = 0.0;
      for (std::size_t c = 0; c < nc; ++c) s += d.win_ms[(c * kW + w) * nb + b] / static_cast<double>(nc);
      if (!(out[b] <= s)) out[b] = s;
    }
  }
  return out;
}

std::vector<char> window_capable_bands(const BandDataset& data, const std::vector<std::size_t>& conditions) {
  double shortest = std::numeric_limits<double>::infinity();
  for (std::size_t k : conditions)
    for (const CycleInfo& c : data.conditions[k].cycles) shortest = std::min(shortest, c.duration_s / kW);
  std::vector<char> out(data.band_count(), 0);
  for (std::size_t b = 0; b < data.band_count(); ++b)
    out[b] = data.bands[b].response_time_s <= shortest && !data.bands[b].nyquist_cut;
  return out;
}

PressureFloor pressure_floor(const BandDataset& data, std::size_t k) {
  const ConditionInfo& info = data.conditions[k].info;
  PressureFloor f;
  const double upper = floor_upper_hz(info.encoder_rate_hz);
  f.estimated = estimate_floor(data, k, upper, f.estimated_white);
  f.stated = std::isfinite(info.pressure_floor_pa) && info.pressure_floor_pa >= 0 &&
             std::isfinite(info.encoder_rate_hz) && info.encoder_rate_hz > 0;
  f.density = f.stated ? stated_floor(data, info.pressure_floor_pa, info.encoder_rate_hz) : f.estimated;
  f.band_ms = floor_band_ms(data, f.density);
  return f;
}

void judge_pressure_floors(BandDataset& data) {
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    ConditionInfo& info = data.conditions[k].info;
    const PressureFloor f = pressure_floor(data, k);
    const bool any = std::any_of(f.density.begin(), f.density.end(), [](double x) { return x > 0; });
    info.floor_density = !info.background && any ? f.density : std::vector<double>{};
    info.floor_limited_band = floor_limited_cells(data, k, &info.floor_limited_window);
  }
}

std::vector<char> floor_limited_cells(const BandDataset& data, std::size_t k, std::vector<char>* windows) {
  const std::size_t nb = data.band_count();
  const double margin = std::pow(10.0, kFloorMarginDb / 10.0);
  std::vector<char> bands(nb, 0);
  if (windows) windows->assign(nb * kW, 0);
  const ConditionData& d = data.conditions[k];
  const std::vector<double>& density = d.info.floor_density;
  if (density.empty()) return bands;
  const std::vector<double> band = mean_band_cpl(d), win = mean_window_cpl(d), floor = floor_band_ms(data, density);
  for (std::size_t b = 0; b < nb && b < density.size(); ++b) {
    const double limit = margin * floor[b];
    bands[b] = band[b] < limit;
    if (windows)
      for (std::size_t w = 0; w < kW; ++w) (*windows)[b * kW + w] = bands[b] || win[b * kW + w] < limit;
  }
  return bands;
}

std::vector<std::vector<char>> floor_limited_bands(const BandDataset& data, std::vector<std::vector<char>>* windows) {
  const std::size_t nb = data.band_count();
  std::vector<std::vector<char>> bands;
  if (windows) windows->clear();
  for (const ConditionData& d : data.conditions) {
    const ConditionInfo& info = d.info;
    bands.push_back(info.floor_limited_band.empty() ? std::vector<char>(nb, 0) : info.floor_limited_band);
    if (windows)
      windows->push_back(info.floor_limited_window.empty() ? std::vector<char>(nb * kW, 0) : info.floor_limited_window);
  }
  return bands;
}

}  // namespace noisemon::model::fit
