#include "daemon/crank_windows.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "dsp/weighting.hpp"

namespace noisemon::daemon {

namespace {

// A-weighting above kWindowHighPassHz: a window of 90 deg lasts 4.9 ms at 3050 rpm, slower content is not located in
// it (and the prediction's quasi-static response to the compression would swamp the rest).
constexpr double kWindowHighPassHz = 200.0;

std::vector<dsp::Biquad> window_filter(double fs_hz) {
  std::vector<dsp::Biquad> s = dsp::a_weighting_sections(fs_hz);
  for (const dsp::Biquad& q : dsp::butterworth_highpass(4, kWindowHighPassHz, fs_hz)) s.push_back(q);
  return s;
}

}  // namespace

CrankWindows::CrankWindows(std::size_t channels, double fs_hz)
    : channels_(channels),
      sections_(window_filter(fs_hz)),
      z0_(channels * sections_.size(), 0.0),
      z1_(channels * sections_.size(), 0.0),
      x_(channels, 0.0),
      sum_(kCrankWindows * channels, 0.0),
      closed_(sum_) {}

std::size_t CrankWindows::window_of(double crank_deg) {
  const double w = std::floor((crank_deg + 360.0) / (720.0 / kCrankWindows));
  return static_cast<std::size_t>(std::clamp(w, 0.0, static_cast<double>(kCrankWindows - 1)));
}

void CrankWindows::add(std::size_t w, const double* frame) {
  const std::size_t n = channels_;
  double* __restrict x = x_.data();
  for (std::size_t c = 0; c < n; ++c) x[c] = frame[c];
  for (std::size_t s = 0; s < sections_.size(); ++s) {
    const dsp::Biquad q = sections_[s];
    double* __restrict z0 = &z0_[s * n];
    double* __restrict z1 = &z1_[s * n];
    for (std::size_t c = 0; c < n; ++c) {
      const double in = x[c], y = q.b0 * in + z0[c];
      z0[c] = q.b1 * in - q.a1 * y + z1[c];
      z1[c] = q.b2 * in - q.a2 * y;
      x[c] = y;
    }
  }
  double* __restrict sum = &sum_[w * n];
  for (std::size_t c = 0; c < n; ++c) sum[c] += x[c] * x[c];
  ++frames_[w];
}

void CrankWindows::close() {
  for (std::size_t w = 0; w < kCrankWindows; ++w) {
    for (std::size_t c = 0; c < channels_; ++c)
      closed_[w * channels_ + c] = frames_[w] > 0 ? sum_[w * channels_ + c] / static_cast<double>(frames_[w]) : 0.0;
    closed_frames_[w] = frames_[w];
    frames_[w] = 0;
  }
  std::fill(sum_.begin(), sum_.end(), 0.0);
}

double CrankWindows::mean_square(std::size_t w, std::size_t channel) const {
  return closed_frames_[w] > 0 ? closed_[w * channels_ + channel] : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace noisemon::daemon
