// One-third-octave bank, measured through the real multirate implementation with steady signals.
//
// References: IEC 61260-1:2014 (band layout, clause 5; class 1 acceptance limits of Table 1 scaled to
// one-third-octave bands with the clause 5.10 formula), analytic sinusoid levels, the Butterworth noise
// bandwidth for white noise, and single-channel / single-block runs of the same bank for the
// streaming and multichannel properties.
#include "dsp/math_constants.hpp"
#include "dsp/third_octave_bank.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace {

using noisemon::dsp::ThirdOctaveBand;
using noisemon::dsp::ThirdOctaveBank;

constexpr double kFs = 40000;
using noisemon::kInf;
using noisemon::kPi;
const double kG = std::pow(10.0, 3.0 / 10.0);  // base-10 octave ratio

double db(double power_ratio) { return 10.0 * std::log10(power_ratio); }

// IEC 61260-1:2014 Table 1, class 1: limits on relative attenuation (dB) at Omega = G^e for octave-band
// filters (the same limits hold at G^-e). At the band edge the table has two rows, the pass-band side
// (-0.4 .. +5.3) and the stop-band side (>= +1.2); a continuous response meets both at the edge itself.
struct Class1Limit {
  double e, min_db, max_db;
};
constexpr Class1Limit kClass1[] = {
    {0.0, -0.4, 0.4},  {1.0 / 8, -0.4, 0.5}, {1.0 / 4, -0.4, 0.7}, {3.0 / 8, -0.4, 1.4}, {1.0 / 2, 1.2, 5.3},
    {1.0, 16.6, kInf}, {2.0, 40.5, kInf},    {3.0, 60.0, kInf},    {4.0, 70.0, kInf},
};

// Clause 5.10: breakpoints of a 1/b-octave filter from the octave ones, above the mid-band frequency
// (below it: the reciprocal).
double third_octave_omega(double e) {
  const double b = 3;
  return 1.0 + (std::pow(kG, 1.0 / (2 * b)) - 1.0) / (std::pow(kG, 0.5) - 1.0) * (std::pow(kG, e) - 1.0);
}

double bandwidth(const ThirdOctaveBand& b) { return b.upper_edge_hz - b.lower_edge_hz; }

// Unit-amplitude cosine/sine pairs at freqs[i] in channels 2i, 2i+1, switched on at t = 0. In steady
// state the two band outputs of a pair are |H| cos and |H| sin of the same phase, so their mean squares
// sum to |H|^2 over any window, however short: no dependence on how many periods fit in it.
class QuadratureTones {
 public:
  QuadratureTones(const std::vector<double>& freqs, double fs)
      : fs_(fs),
        bank_(fs, 2 * freqs.size()),
        ph_(freqs.size(), 1.0),
        rot_(freqs.size()),
        buf_(kBlock * 2 * freqs.size()),
        ms_(2 * freqs.size() * bank_.band_count()) {
    for (std::size_t i = 0; i < freqs.size(); ++i) rot_[i] = std::polar(1.0, 2 * kPi * freqs[i] / fs);
  }
  const ThirdOctaveBank& bank() const { return bank_; }
  void run_for(double seconds) {
    auto frames = static_cast<std::size_t>(std::llround(seconds * fs_));
    const std::size_t ch = 2 * ph_.size();
    while (frames > 0) {
      const std::size_t n = std::min(frames, kBlock);
      for (std::size_t t = 0; t < n; ++t)
        for (std::size_t i = 0; i < ph_.size(); ++i) {
          buf_[t * ch + 2 * i] = ph_[i].real();
          buf_[t * ch + 2 * i + 1] = ph_[i].imag();
          ph_[i] *= rot_[i];
        }
      for (auto& p : ph_) p /= std::abs(p);  // keep the phasors on the unit circle
      bank_.process(buf_.data(), n);
      frames -= n;
    }
  }
  // Per tone and band: |H|^2 averaged since the previous take.
  std::vector<std::vector<double>> take_gain() {
    bank_.take_mean_square(ms_.data());
    const std::size_t nb = bank_.band_count();
    std::vector<std::vector<double>> gain(ph_.size(), std::vector<double>(nb));
    for (std::size_t i = 0; i < ph_.size(); ++i)
      for (std::size_t b = 0; b < nb; ++b) gain[i][b] = ms_[(2 * i) * nb + b] + ms_[(2 * i + 1) * nb + b];
    return gain;
  }

 private:
  static constexpr std::size_t kBlock = 2048;
  double fs_;
  ThirdOctaveBank bank_;
  std::vector<std::complex<double>> ph_, rot_;
  std::vector<double> buf_, ms_;
};

std::vector<double> white_noise(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> x(n);
  for (double& v : x) v = g(rng);
  return x;
}

}  // namespace

TEST(ThirdOctaveBank, BandLayoutFollowsIec61260Base10) {
  // Nominal mid-band frequencies, IEC 61260-1 annex E (one-third-octave, 20 Hz .. 20 kHz).
  const double nominal[] = {20,   25,   31.5, 40,   50,   63,    80,    100,   125,  160,  200,
                            250,  315,  400,  500,  630,  800,   1000,  1250,  1600, 2000, 2500,
                            3150, 4000, 5000, 6300, 8000, 10000, 12500, 16000, 20000};
  ThirdOctaveBank bank(kFs, 2);
  ASSERT_EQ(bank.band_count(), 31u);
  EXPECT_EQ(bank.channels(), 2u);
  EXPECT_EQ(bank.sample_rate_hz(), kFs);
  for (std::size_t i = 0; i < 31; ++i) {
    const ThirdOctaveBand& b = bank.bands()[i];
    const double fm = 1000.0 * std::pow(kG, (static_cast<double>(i) - 17.0) / 3.0);  // G^(x/b) * fr
    EXPECT_EQ(b.nominal_hz, nominal[i]);
    EXPECT_NEAR(b.exact_mid_hz, fm, 1e-9 * fm);
    EXPECT_NEAR(b.lower_edge_hz, fm * std::pow(kG, -1.0 / 6.0), 1e-9 * fm);
    EXPECT_NEAR(b.upper_edge_hz, fm * std::pow(kG, 1.0 / 6.0), 1e-9 * fm);
    // Only the 20 kHz band (17.8 .. 22.4 kHz) reaches Nyquist at 40 kHz.
    EXPECT_EQ(b.nyquist_cut, i == 30) << b.nominal_hz;
    EXPECT_GT(b.response_time_s, 0.0);
  }
  // Lower bands are narrower, hence slower.
  for (std::size_t i = 1; i < 30; ++i)
    EXPECT_LT(bank.bands()[i].response_time_s, bank.bands()[i - 1].response_time_s) << i;
}

TEST(ThirdOctaveBank, BandsAboveNyquistAreOmittedAndTruncatedOnesFlagged) {
  // 32 kHz: the 20 kHz band starts above 16 kHz (omitted); 16 kHz band (14.1 .. 17.8 kHz) is cut.
  ThirdOctaveBank b32(32000, 1);
  ASSERT_EQ(b32.band_count(), 30u);
  EXPECT_EQ(b32.bands().back().nominal_hz, 16000);
  EXPECT_TRUE(b32.bands().back().nyquist_cut);
  // 48 kHz: all 31 bands fit below 24 kHz.
  ThirdOctaveBank b48(48000, 1);
  ASSERT_EQ(b48.band_count(), 31u);
  for (const auto& b : b48.bands()) EXPECT_FALSE(b.nyquist_cut) << b.nominal_hz;
}

// Every band, every class 1 breakpoint below fs/2, measured with steady tones through process().
// Attenuation is taken relative to the input (the bank's reference attenuation is 0 dB by design).
class ThirdOctaveBankClass1 : public ::testing::TestWithParam<double> {};

TEST_P(ThirdOctaveBankClass1, EveryBandMeetsTheLimitsAtEveryBreakpoint) {
  const double fs = GetParam();
  const std::vector<ThirdOctaveBand> bands = ThirdOctaveBank(fs, 1).bands();
  // Smallest headroom to the limits: pass band and edges (to the lower and to the upper limit), stop band.
  double worst[3] = {kInf, kInf, kInf};
  std::string where[3];
  for (std::size_t b = 0; b < bands.size(); ++b) {
    struct Point {
      double f, lo, hi, e;
    };
    std::vector<Point> points;
    for (const Class1Limit& lim : kClass1)
      for (int side : {1, -1}) {
        if (lim.e == 0 && side < 0) continue;
        const double omega = side > 0 ? third_octave_omega(lim.e) : 1.0 / third_octave_omega(lim.e);
        const double f = bands[b].exact_mid_hz * omega;
        if (f < fs / 2) points.push_back({f, lim.min_db, lim.max_db, side * lim.e});
      }
    std::vector<double> freqs;
    for (const Point& p : points) freqs.push_back(p.f);
    // The slowest band-pass pole decays as exp(-pi B t / 2) or faster: 20 / B is far beyond any
    // start-up transient.
    const double bw = bandwidth(bands[b]);
    QuadratureTones tones(freqs, fs);
    tones.run_for(20.0 / bw + 0.05);
    tones.take_gain();
    tones.run_for(10.0 / bw + 0.02);
    const auto gain = tones.take_gain();
    for (std::size_t i = 0; i < points.size(); ++i) {
      const Point& p = points[i];
      const double att = -db(gain[i][b]);
      EXPECT_GE(att, p.lo) << bands[b].nominal_hz << " Hz band at G^" << p.e << " (" << p.f << " Hz)";
      EXPECT_LE(att, p.hi) << bands[b].nominal_hz << " Hz band at G^" << p.e << " (" << p.f << " Hz)";
      const bool pass = std::abs(p.e) < 0.5 + 1e-9;
      const double headroom[3] = {pass ? att - p.lo : kInf, pass ? p.hi - att : kInf, pass ? kInf : att - p.lo};
      for (int r = 0; r < 3; ++r)
        if (headroom[r] < worst[r]) {
          worst[r] = headroom[r];
          char text[80];
          std::snprintf(text, sizeof text, "%g Hz band at G^%+.3g: %.3f dB", bands[b].nominal_hz, p.e, att);
          where[r] = text;
        }
    }
  }
  std::printf(
      "fs %g Hz, class 1 headroom: pass band %.3f dB to the lower limit (%s), %.3f dB to the upper "
      "limit (%s); stop band %.3f dB (%s)\n",
      fs, worst[0], where[0].c_str(), worst[1], where[1].c_str(), worst[2], where[2].c_str());
}

INSTANTIATE_TEST_SUITE_P(SampleRates, ThirdOctaveBankClass1, ::testing::Values(40000.0, 44100.0, 48000.0));

TEST(ThirdOctaveBank, ToneAtBandCentreReadsTheToneLevelInItsBandOnly) {
  // One plain sine per channel, channel c at band c's exact mid-band frequency.
  ThirdOctaveBank bank(kFs, 31);
  const std::vector<ThirdOctaveBand> bands = bank.bands();
  const std::size_t nb = bands.size(), ch = nb;
  const double amp = 0.5, tone_ms = amp * amp / 2;
  const auto settle = static_cast<std::size_t>(20.0 / bandwidth(bands[0]) * kFs);
  const std::size_t total = settle + static_cast<std::size_t>(12.0 / bandwidth(bands[0]) * kFs);
  constexpr std::size_t kBlock = 1000;
  std::vector<double> x(kBlock * ch), ms(ch * nb);
  for (std::size_t t0 = 0; t0 < total; t0 += kBlock) {
    const std::size_t n = std::min(kBlock, total - t0);
    for (std::size_t t = 0; t < n; ++t)
      for (std::size_t c = 0; c < ch; ++c)
        x[t * ch + c] = amp * std::sin(2 * kPi * bands[c].exact_mid_hz * static_cast<double>(t0 + t) / kFs);
    bank.process(x.data(), n);
    if (t0 + n == settle / kBlock * kBlock) bank.take_mean_square(ms.data());
  }
  bank.take_mean_square(ms.data());
  double worst = 0;
  for (std::size_t c = 0; c < ch; ++c) {
    const double rel = db(ms[c * nb + c] / tone_ms);
    EXPECT_NEAR(rel, 0.0, 0.1) << bands[c].nominal_hz << " Hz";
    worst = std::max(worst, std::abs(rel));
    for (std::size_t adj : {c - 1, c + 1})
      if (adj < nb) {
        EXPECT_LE(db(ms[c * nb + adj] / tone_ms), -15.0)
            << bands[c].nominal_hz << " Hz in the " << bands[adj].nominal_hz << " Hz band";
      }
  }
  std::printf("tone at band centre: largest level error %.4f dB\n", worst);
}

TEST(ThirdOctaveBank, WhiteNoiseBandSumMatchesTheSignal) {
  const std::size_t settle = static_cast<std::size_t>(1.0 * kFs), n = static_cast<std::size_t>(4.0 * kFs);
  const std::vector<double> x = white_noise(settle + n, 7);
  ThirdOctaveBank bank(kFs, 1);
  const std::size_t nb = bank.band_count();
  std::vector<double> ms(nb);
  bank.process(x.data(), settle);
  bank.take_mean_square(ms.data());
  bank.process(x.data() + settle, n);
  bank.take_mean_square(ms.data());
  double sum = 0, ref = 0;
  for (double v : ms) sum += v;
  for (std::size_t i = settle; i < settle + n; ++i) ref += x[i] * x[i];
  ref /= static_cast<double>(n);
  // The bands tile 17.8 Hz .. fs/2, so the reference is the signal's mean square over that range: white
  // noise puts the fraction (fs/2 - 17.8 Hz) / (fs/2) there. The bank's 8th-order Butterworth band-pass
  // (4th-order prototype, n = 4) passes white noise like an ideal band (pi/2n)/sin(pi/2n) = 1.026 times as
  // wide (exactly, for the low-pass to band-pass transform), so the band sum exceeds the in-range power by
  // that factor; the 20 kHz band (a high-pass up to fs/2) and the bilinear warping of the top bands make
  // up the rest of the tolerance.
  const auto& bands = bank.bands();
  const double covered = (kFs / 2 - bands.front().lower_edge_hz) / (kFs / 2);
  const double order = 4;
  const double excess = (kPi / (2 * order)) / std::sin(kPi / (2 * order));
  std::printf("white noise: band sum / in-range mean square = %+.3f dB (Butterworth noise bandwidth: %+.3f dB)\n",
              db(sum / (ref * covered)), db(excess));
  EXPECT_NEAR(db(sum / (ref * covered)), db(excess), 0.05);
}

TEST(ThirdOctaveBank, ArbitraryBlockSizesAndTakesGiveIdenticalResults) {
  const std::size_t ch = 3, frames = static_cast<std::size_t>(1.5 * kFs);
  std::vector<double> x = white_noise(frames * ch, 11);
  for (std::size_t t = 0; t < frames; ++t) x[t * ch + 1] += std::sin(2 * kPi * 31.6 * static_cast<double>(t) / kFs);
  const std::vector<std::size_t> take_at = {1, 700, 1537, 4000, 9001, 9002, 20000, 33333, frames};

  auto run = [&](auto next_block) {
    ThirdOctaveBank bank(kFs, ch);
    std::vector<double> ms(ch * bank.band_count()), all;
    std::size_t pos = 0;
    for (std::size_t stop : take_at) {
      while (pos < stop) {
        const std::size_t n = std::min(next_block(), stop - pos);
        bank.process(x.data() + pos * ch, n);
        pos += n;
      }
      bank.take_mean_square(ms.data());
      all.insert(all.end(), ms.begin(), ms.end());
    }
    return all;
  };
  const auto whole = run([] { return std::size_t{1} << 30; });
  std::mt19937 rng(3);
  std::uniform_int_distribution<std::size_t> size(1, 3000);
  const auto pieces = run([&] { return size(rng); });
  const auto singles = run([] { return std::size_t{1}; });
  ASSERT_EQ(whole.size(), pieces.size());
  for (std::size_t i = 0; i < whole.size(); ++i) {
    EXPECT_EQ(whole[i], pieces[i]) << i;
    EXPECT_EQ(whole[i], singles[i]) << i;
  }
}

TEST(ThirdOctaveBank, ChannelsAreIndependent) {
  const std::size_t ch = 5, frames = static_cast<std::size_t>(1.2 * kFs);
  std::vector<double> x(frames * ch);
  for (std::size_t c = 0; c < ch; ++c) {
    const auto noise = white_noise(frames, 100 + c);
    for (std::size_t t = 0; t < frames; ++t)
      x[t * ch + c] = (0.1 + c) * noise[t] + std::sin(2 * kPi * (50.0 + 900.0 * c) * static_cast<double>(t) / kFs);
  }
  ThirdOctaveBank multi(kFs, ch);
  const std::size_t nb = multi.band_count();
  std::vector<double> ms_multi(ch * nb);
  multi.process(x.data(), frames);
  multi.take_mean_square(ms_multi.data());
  for (std::size_t c = 0; c < ch; ++c) {
    std::vector<double> mono(frames), ms(nb);
    for (std::size_t t = 0; t < frames; ++t) mono[t] = x[t * ch + c];
    ThirdOctaveBank single(kFs, 1);
    single.process(mono.data(), frames);
    single.take_mean_square(ms.data());
    for (std::size_t b = 0; b < nb; ++b) EXPECT_NEAR(ms_multi[c * nb + b], ms[b], 1e-12 * ms[b]) << c << " " << b;
  }
}

TEST(ThirdOctaveBank, TakesBetweenDecimatedSamplesRepeatTheLastValue) {
  ThirdOctaveBank bank(kFs, 1);
  const std::size_t nb = bank.band_count();
  std::vector<double> ms(nb, -1.0);
  bank.take_mean_square(ms.data());
  for (double v : ms) EXPECT_EQ(v, 0.0);  // nothing processed yet

  // A 20 Hz tone: its band runs at fs / 512, so most takes 100 frames apart see no new band sample.
  const double f = bank.bands()[0].exact_mid_hz, amp = 1.0;
  std::size_t t = 0;
  std::vector<double> block(100);
  auto feed = [&] {
    for (double& v : block) v = amp * std::sin(2 * kPi * f * static_cast<double>(t++) / kFs);
    bank.process(block.data(), block.size());
  };
  for (int i = 0; i < 1600; ++i) feed();  // 4 s to settle
  bank.take_mean_square(ms.data());
  double sum = 0;
  int takes = 0;
  for (int i = 0; i < 8000; ++i) {  // 20 s
    feed();
    bank.take_mean_square(ms.data());
    EXPECT_GT(ms[0], 0.0);
    sum += ms[0];
    ++takes;
  }
  // Each band sample is repeated for the takes until the next one, so the take average is the band's
  // mean square: the tone's.
  EXPECT_NEAR(db(sum / takes / (amp * amp / 2)), 0.0, 0.1);
  bank.take_mean_square(ms.data());
  for (double v : ms) EXPECT_EQ(v, 0.0);  // nothing processed since the last take

  bank.reset();
  feed();
  bank.take_mean_square(ms.data());
  EXPECT_LT(ms[0], 1e-3 * amp * amp);  // state cleared: the 20 Hz band has only just started
}

// response_time_s is the settling time: after a tone at mid-band is switched on, the band level stays
// within 0.5 dB of its steady value from response_time_s on, and is still far off at a third of it.
TEST(ThirdOctaveBank, ResponseTimeIsTheSettlingTime) {
  const std::vector<ThirdOctaveBand> bands = ThirdOctaveBank(kFs, 1).bands();
  for (std::size_t b : {0u, 5u, 12u, 17u, 22u, 26u, 29u}) {
    const double tr = bands[b].response_time_s;
    const double window = std::max(0.05 * tr, 1.0 / bands[b].exact_mid_hz);  // a few band samples
    QuadratureTones tone({bands[b].exact_mid_hz}, kFs);
    tone.run_for(tr / 3);
    tone.take_gain();
    tone.run_for(window);
    EXPECT_LT(db(tone.take_gain()[0][b]), -2.0) << bands[b].nominal_hz << " Hz at a third of " << tr << " s";
    tone.run_for(tr - tr / 3 - window);
    tone.take_gain();
    for (double t = tr; t < 3 * tr; t += window) {
      tone.run_for(window);
      EXPECT_NEAR(db(tone.take_gain()[0][b]), 0.0, 0.5) << bands[b].nominal_hz << " Hz at " << t << " s, tr " << tr;
    }
  }
}
