// IEC 61260-1 base-10 one-third-octave filter bank, nominal 20 Hz ... 20 kHz, class 1 (8th-order
// Butterworth band-passes, multirate: lower octaves run decimated by powers of two).
//
// Streaming, multichannel: process() takes interleaved frames and accumulates, per channel and band, the
// sum of squared band outputs; take_mean_square() returns the mean square since the previous call and
// restarts the accumulation. Filter state is kept across calls (a band's output never restarts at a cycle
// boundary). No allocation after construction.
//
// A decimated band (1 sample per 2^k frames) averages its own samples since the last take; if takes come
// closer together than its sample spacing and none arrived, the band repeats its previous value.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <vector>

namespace noisemon::dsp {

// IEC 61260-1 nominal mid-band frequencies of the bank's bands, 20 Hz ... 20 kHz, in order.
inline constexpr std::array<double, 31> kThirdOctaveNominalHz{
    20,  25,   31.5, 40,   50,   63,   80,   100,  125,  160,  200,  250,   315,   400,   500,  630,
    800, 1000, 1250, 1600, 2000, 2500, 3150, 4000, 5000, 6300, 8000, 10000, 12500, 16000, 20000};
// The exact mid-band frequency 1000 * 10^(x/10) of the band whose nominal frequency is nominal_hz.
double third_octave_exact_mid_hz(double nominal_hz);

struct ThirdOctaveBand {
  double nominal_hz = 0;       // IEC 61260-1 nominal mid-band frequency (20, 25, 31.5, ... 20000)
  double exact_mid_hz = 0;     // 1000 * 10^(x/10)
  double lower_edge_hz = 0;    // exact_mid * 10^(-1/20)
  double upper_edge_hz = 0;    // exact_mid * 10^(+1/20)
  bool nyquist_cut = false;    // the upper edge lies at or above fs/2: the band is truncated (measured as a
                               // high-pass from the lower edge up to fs/2)
  double response_time_s = 0;  // settling time: after a step in the input the band level stays within 0.5 dB
                               // of its final value from here on (3.5 group delays at mid-band)
};

class ThirdOctaveBank {
 public:
  // fs_hz: input sample rate (the pipeline uses 40 kHz); channels: interleaved channel count.
  ThirdOctaveBank(double fs_hz, std::size_t channels);
  ~ThirdOctaveBank();
  ThirdOctaveBank(ThirdOctaveBank&&) noexcept;
  ThirdOctaveBank& operator=(ThirdOctaveBank&&) noexcept;

  const std::vector<ThirdOctaveBand>& bands() const;
  std::size_t band_count() const;
  std::size_t channels() const;
  double sample_rate_hz() const;

  // in: frames * channels() values, interleaved.
  void process(const double* in, std::size_t frames);
  // out: channels() * band_count() values, out[channel * band_count() + band] = mean square of the band
  // output since the last take (0 when nothing was processed since then). Restarts the accumulation.
  void take_mean_square(double* out);
  // Clears filter state and accumulators.
  void reset();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace noisemon::dsp
