// Resamplers against analytic signals.
//
// Every check compares the output frame k with the analytic signal evaluated at t = k / out_rate (sums of
// sinusoids with known frequency, amplitude and phase), so accuracy, flatness, alias rejection and time
// alignment are measured against the truth, not against an earlier run. The uneven time base is a crank
// angle with a 1 % sinusoidal speed ripple once per engine cycle; edge times are its exact inverse
// (Newton iteration to machine precision).
//
// Measured (RelWithDebInfo; printed by the tests; the assertions are looser: relative rms error < 1e-3,
// gain within 0.01 dB, phase within 1e-4 rad, alias level < -80 dB):
//   RationalResampler 51.2 kHz -> 40 kHz (passband 18 kHz, stopband from 20 kHz), double / single precision:
//     10 channels of tone mixes 20 Hz..17.5 kHz, relative rms error   3.1e-5 (worst channel)
//     gain, 31 tones 20 Hz..18 kHz                                     within 4.9e-4 dB
//     phase error, same tones (time alignment)                        within 1.6e-8 rad (< 0.2 ps)
//     alias level, 20.05 / 20.2 / 21 / 24 / 25.5 kHz input            <= -85.7 dB (worst at 20.05 kHz)
//   RationalResampler 102.4 -> 51.2 kHz, 44.1 -> 40 kHz, 16 -> 40 kHz:
//     tones 0.2 %..97 % of the passband, relative rms error          1.6e-5 (worst ratio)
//   NonuniformResampler -> 40 kHz, 183 kHz edges (0.1 deg at 3050 rpm, 1 % speed ripple), on the any-encoder
//   fine grid (8 x 40 kHz) / sized for 229 kHz edges (4 x):
//     tone mixes 20 Hz..16 kHz, relative rms error                    4.6e-6 / 3.7e-6; 2.8e-6 / 2.1e-6 on a 1e5 mean
//     gain, 25 tones 20 Hz..18 kHz                                     within 1.8e-4 / 1.5e-4 dB
//     phase error, same tones                                          within 6.1e-9 / 9.7e-9 rad
//     alias level, 20.05 / 21 / 24 / 40 / 70 / 90 kHz input           <= -84.6 / -84.5 dB (worst at 20.05 kHz)
//     the same 5 hours into the stream (t ~ 18000 s)                  3.4e-6
//     constant 1.234e6 input                                           exact to 1e-7 absolute
//   NonuniformResampler -> 40 kHz, 6 kHz edges (1 deg at 1000 rpm, 1 % ripple), slower than the output:
//     reported passband 0.41 * edge rate = 2478 Hz; tones 20 Hz..2.4 kHz, relative rms error 1.1e-5
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include "dsp/resample.hpp"

namespace noisemon::dsp {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

struct Tone {
  double freq_hz;
  double amplitude;
  double phase_rad;
};

double tones_at(const std::vector<Tone>& tones, double t) {
  double v = 0.0;
  for (const Tone& tone : tones) {
    // Reduce the cycle count first so late instants (hours) keep their phase accuracy.
    const double cycles = tone.freq_hz * t;
    v += tone.amplitude * std::sin(kTwoPi * (cycles - std::floor(cycles)) + tone.phase_rad);
  }
  return v;
}

// Least-squares amplitude and phase of a tone of known frequency in y[i] at times t[i]:
// y ~ a cos(w t) + b sin(w t) = A sin(w t + phi), A sin(phi) = a, A cos(phi) = b.
struct ToneFit {
  double amplitude;
  double phase_rad;
};
ToneFit fit_tone(const std::vector<double>& y, const std::vector<double>& t, double freq_hz) {
  double cc = 0, ss = 0, cs = 0, yc = 0, ys = 0;
  for (std::size_t i = 0; i < y.size(); ++i) {
    const double cycles = freq_hz * t[i];
    const double w = kTwoPi * (cycles - std::floor(cycles));
    const double c = std::cos(w), s = std::sin(w);
    cc += c * c;
    ss += s * s;
    cs += c * s;
    yc += y[i] * c;
    ys += y[i] * s;
  }
  const double det = cc * ss - cs * cs;
  const double a = (yc * ss - ys * cs) / det;
  const double b = (ys * cc - yc * cs) / det;
  return {std::hypot(a, b), std::atan2(a, b)};
}

double wrap_phase(double p) { return std::remainder(p, kTwoPi); }

double rms(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x * x;
  return std::sqrt(s / static_cast<double>(v.size()));
}

// ---- Rational ------------------------------------------------------------------------------------------

// Input frames i at t = i / in_rate, channel c carries tones[c]; interleaved.
std::vector<double> uniform_input(const std::vector<std::vector<Tone>>& tones, double in_rate, std::size_t frames) {
  const std::size_t ch = tones.size();
  std::vector<double> x(frames * ch);
  for (std::size_t i = 0; i < frames; ++i)
    for (std::size_t c = 0; c < ch; ++c) x[i * ch + c] = tones_at(tones[c], static_cast<double>(i) / in_rate);
  return x;
}

// Runs the whole input through in blocks with ample output room; returns all output frames (index 0 first).
std::vector<double> run_rational(RationalResampler& r, const std::vector<double>& x, std::size_t block) {
  const std::size_t ch = r.channels();
  const std::size_t frames = x.size() / ch;
  std::vector<double> out;
  std::vector<double> buf(r.max_output_frames(block) * ch);
  for (std::size_t i = 0; i < frames; i += block) {
    const std::size_t n = std::min(block, frames - i);
    const std::size_t w = r.process(&x[i * ch], n, buf.data(), r.max_output_frames(n));
    out.insert(out.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(w * ch));
  }
  return out;
}

// Relative rms error of channel c against the analytic tones, over output frames from skip_s on.
double rational_error(const std::vector<double>& out, std::size_t ch, std::size_t c, const std::vector<Tone>& tones,
                      double out_rate, double skip_s) {
  std::vector<double> err, ref;
  for (std::size_t k = static_cast<std::size_t>(skip_s * out_rate); k < out.size() / ch; ++k) {
    const double truth = tones_at(tones, static_cast<double>(k) / out_rate);
    ref.push_back(truth);
    err.push_back(out[k * ch + c] - truth);
  }
  return rms(err) / rms(ref);
}

// Every accuracy check runs in both precisions (double: the default; single: float WAVs and ADC words).
const SamplePrecision kPrecisions[] = {SamplePrecision::kDouble, SamplePrecision::kSingle};
const char* name(SamplePrecision p) { return p == SamplePrecision::kSingle ? "single" : "double"; }

// The first 10 ms see the zero signal before t = 0 through the filter; steady state is judged after it.
constexpr double kRationalSkipS = 0.01;

// Fits a tone of frequency f to samples y at instants t and expects unit gain and the original phase: within
// 0.01 dB and 1e-4 rad (1e-4 rad at 18 kHz is a 0.9 ns time shift: output k sits at k / out_rate).
void expect_unit_gain_and_phase(const std::vector<double>& y, const std::vector<double>& t, double f, double phase0,
                                double& worst_db, double& worst_phase) {
  const ToneFit fit = fit_tone(y, t, f);
  const double gain_db = 20.0 * std::log10(fit.amplitude);
  const double phase = wrap_phase(fit.phase_rad - phase0);
  worst_db = std::max(worst_db, std::abs(gain_db));
  worst_phase = std::max(worst_phase, std::abs(phase));
  EXPECT_LT(std::abs(gain_db), 0.01) << f << " Hz";
  EXPECT_LT(std::abs(phase), 1e-4) << f << " Hz";
}

TEST(RationalResampler, ReducesTheRateRatio) {
  // 51200 / 40000 = 32 / 25: 32 input frames make exactly 25 output frames.
  RationalResampler r(51200.0, 40000.0, 1);
  EXPECT_EQ(r.max_output_frames(32), 25u);
  EXPECT_EQ(r.max_output_frames(64), 50u);
  EXPECT_DOUBLE_EQ(r.passband_edge_hz(), 18000.0);
  std::vector<double> x(32 * 1000, 0.0), out(r.max_output_frames(x.size()));
  std::size_t total = 0;
  for (std::size_t i = 0; i < 1000; ++i) total += r.process(&x[i * 32], 32, out.data(), out.size());
  // 1000 * 25 outputs for 1000 * 32 inputs, less the few held back for the filter's look-ahead.
  EXPECT_LE(total, 25000u);
  EXPECT_GE(total, 25000u - 100u);
  EXPECT_EQ(r.next_output_index(), static_cast<std::int64_t>(total));

  RationalResampler half(102400.0, 51200.0, 2);
  EXPECT_EQ(half.max_output_frames(2), 1u);
  EXPECT_EQ(half.max_output_frames(3), 2u);
  EXPECT_DOUBLE_EQ(half.passband_edge_hz(), 0.45 * 51200.0);
}

TEST(RationalResampler, RejectsBadArguments) {
  EXPECT_THROW(RationalResampler(51200.5, 40000.0, 1), std::invalid_argument);
  EXPECT_THROW(RationalResampler(51200.0, 0.0, 1), std::invalid_argument);
  EXPECT_THROW(RationalResampler(51200.0, 40000.0, 0), std::invalid_argument);
  // The filter's length grows with the decimation factor too: 1 GHz -> 40 kHz (down 25000) is refused.
  EXPECT_THROW(RationalResampler(1e9, 40000.0, 1), std::invalid_argument);
}

TEST(RationalResampler, TenChannelToneMixesMatchTheAnalyticSignal) {
  const double in_rate = 51200.0, out_rate = 40000.0;
  std::vector<std::vector<Tone>> tones;
  const double freqs[] = {20.0, 63.0, 250.0, 1000.0, 3150.0, 6300.0, 10000.0, 12500.0, 16000.0, 17500.0};
  for (std::size_t c = 0; c < 10; ++c) {
    // Each channel: its own loud tone plus a shared low-level mix, all inside the passband.
    tones.push_back({{freqs[c], 1.0, 0.3 * static_cast<double>(c)},
                     {20.0 + 37.0 * static_cast<double>(c), 0.3, 1.0},
                     {16000.0 - 611.0 * static_cast<double>(c), 0.1, 2.0}});
  }
  for (const SamplePrecision precision : kPrecisions) {
    RationalResampler r(in_rate, out_rate, 10, precision);
    const auto out = run_rational(r, uniform_input(tones, in_rate, 25600), 512);
    double worst = 0.0;
    for (std::size_t c = 0; c < 10; ++c) {
      const double e = rational_error(out, 10, c, tones[c], out_rate, kRationalSkipS);
      worst = std::max(worst, e);
      EXPECT_LT(e, 1e-3) << "channel " << c << ", " << name(precision);
    }
    std::printf("rational 51.2k->40k tone mixes (%s): worst relative rms error %.2e\n", name(precision), worst);
  }
}

TEST(RationalResampler, FlatWithExactPhaseUpToThePassbandEdge) {
  const double in_rate = 51200.0, out_rate = 40000.0;
  for (const SamplePrecision precision : kPrecisions) {
    double worst_db = 0.0, worst_phase = 0.0;
    for (int i = 0; i <= 30; ++i) {
      const double f = 20.0 * std::pow(18000.0 / 20.0, i / 30.0);
      const Tone tone{f, 1.0, 0.7};
      RationalResampler r(in_rate, out_rate, 1, precision);
      const auto out = run_rational(r, uniform_input({{tone}}, in_rate, 10240), 1000);
      std::vector<double> y, t;
      for (std::size_t k = static_cast<std::size_t>(kRationalSkipS * out_rate); k < out.size(); ++k) {
        y.push_back(out[k]);
        t.push_back(static_cast<double>(k) / out_rate);
      }
      expect_unit_gain_and_phase(y, t, f, tone.phase_rad, worst_db, worst_phase);
    }
    std::printf("rational 51.2k->40k 20 Hz..18 kHz (%s): gain within %.1e dB, phase within %.1e rad\n", name(precision),
                worst_db, worst_phase);
  }
}

TEST(RationalResampler, RejectsTonesAboveTheOutputNyquist) {
  const double in_rate = 51200.0, out_rate = 40000.0;
  for (const SamplePrecision precision : kPrecisions) {
    double worst_db = -1000.0;
    for (double f : {20050.0, 20200.0, 21000.0, 24000.0, 25500.0}) {
      RationalResampler r(in_rate, out_rate, 1, precision);
      const auto out = run_rational(r, uniform_input({{{f, 1.0, 0.0}}}, in_rate, 20480), 256);
      const std::vector<double> steady(out.begin() + static_cast<std::ptrdiff_t>(kRationalSkipS * out_rate), out.end());
      const double level_db = 20.0 * std::log10(rms(steady) / std::sqrt(0.5));
      worst_db = std::max(worst_db, level_db);
      EXPECT_LT(level_db, -80.0) << f << " Hz, " << name(precision);
    }
    std::printf("rational 51.2k->40k alias rejection (%s): worst %.1f dB\n", name(precision), worst_db);
  }
}

TEST(RationalResampler, OtherRatiosMatchTheAnalyticSignal) {
  struct Case {
    double in_rate, out_rate;
  };
  double worst = 0.0;
  for (const Case cs : {Case{102400.0, 51200.0}, Case{44100.0, 40000.0}, Case{16000.0, 40000.0}}) {
    const double edge = 0.45 * std::min(cs.in_rate, cs.out_rate);
    std::vector<Tone> tones;
    for (double frac : {0.002, 0.05, 0.3, 0.7, 0.97}) tones.push_back({frac * edge, 0.5, frac * 10.0});
    RationalResampler r(cs.in_rate, cs.out_rate, 1);
    ASSERT_DOUBLE_EQ(r.passband_edge_hz(), edge);
    const auto frames = static_cast<std::size_t>(0.2 * cs.in_rate);
    const auto out = run_rational(r, uniform_input({tones}, cs.in_rate, frames), 333);
    const double e = rational_error(out, 1, 0, tones, cs.out_rate, kRationalSkipS);
    worst = std::max(worst, e);
    EXPECT_LT(e, 1e-3) << cs.in_rate << " -> " << cs.out_rate;
  }
  std::printf("rational other ratios: worst relative rms error %.2e\n", worst);
}

TEST(RationalResampler, RandomBlocksAndShortOutputBuffersEqualOnePiece) {
  const double in_rate = 51200.0, out_rate = 40000.0;
  const std::size_t ch = 3, frames = 40000;
  std::vector<std::vector<Tone>> tones = {{{440.0, 1.0, 0.0}}, {{5000.0, 1.0, 1.0}}, {{15000.0, 1.0, 2.0}}};
  const auto x = uniform_input(tones, in_rate, frames);

  RationalResampler whole(in_rate, out_rate, ch);
  std::vector<double> reference(whole.max_output_frames(frames) * ch);
  reference.resize(whole.process(x.data(), frames, reference.data(), whole.max_output_frames(frames)) * ch);

  RationalResampler pieces(in_rate, out_rate, ch);
  std::mt19937 rng(7);
  std::vector<double> got, buf(4096 * ch);
  std::size_t i = 0;
  while (i < frames) {
    const std::size_t n = std::min<std::size_t>(std::uniform_int_distribution<std::size_t>(0, 700)(rng), frames - i);
    // Sometimes less room than the call produces: the rest must come out of later calls, in order.
    const std::size_t room = std::uniform_int_distribution<std::size_t>(0, pieces.max_output_frames(n) + 40)(rng);
    const std::int64_t first = pieces.next_output_index();
    ASSERT_EQ(first, static_cast<std::int64_t>(got.size() / ch));
    const std::size_t w = pieces.process(&x[i * ch], n, buf.data(), room);
    ASSERT_LE(w, room);
    got.insert(got.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(w * ch));
    i += n;
  }
  for (std::size_t w; (w = pieces.process(nullptr, 0, buf.data(), 100)) > 0;)
    got.insert(got.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(w * ch));
  ASSERT_EQ(got.size(), reference.size());
  for (std::size_t j = 0; j < got.size(); ++j) ASSERT_EQ(got[j], reference[j]) << "sample " << j;
}

// ---- Nonuniform ----------------------------------------------------------------------------------------

// Crank angle with a sinusoidal speed ripple once per 720 deg cycle:
// w(t) = w0 (1 + eps sin(W t)), theta(t) = theta0 + w0 t + eps w0 (1 - cos(W t)) / W (degrees, seconds).
struct Crank {
  double rpm;
  double ripple;
  double t_start = 0.0;                                     // time origin of the rotation (theta = 0 there)
  double w0() const { return rpm * 6.0; }                   // deg/s
  double ripple_w() const { return kTwoPi * rpm / 120.0; }  // rad/s, once per cycle
  double angle(double t) const {
    const double s = t - t_start;
    return w0() * s + ripple * w0() * (1.0 - std::cos(ripple_w() * s)) / ripple_w();
  }
  double speed(double t) const { return w0() * (1.0 + ripple * std::sin(ripple_w() * (t - t_start))); }
  // Exact inverse by Newton's method (theta is smooth and strictly increasing).
  double time_of(double theta) const {
    double t = t_start + theta / w0();
    for (int it = 0; it < 50; ++it) {
      const double dt = (angle(t) - theta) / speed(t);
      t -= dt;
      if (std::abs(dt) <= 1e-17 * std::max(1.0, std::abs(t))) break;
    }
    return t;
  }
};

// Edge times for angles (first_edge + i) * resolution, i = 0..n-1.
std::vector<double> edge_times(const Crank& crank, double resolution_deg, double first_edge, std::size_t n) {
  std::vector<double> t(n);
  for (std::size_t i = 0; i < n; ++i) t[i] = crank.time_of((first_edge + static_cast<double>(i)) * resolution_deg);
  return t;
}

struct NuResult {
  std::int64_t first_index = 0;
  std::vector<double> out;  // interleaved
};

// Feeds the samples in blocks with generous output room.
NuResult run_nonuniform(NonuniformResampler& r, const std::vector<double>& t, const std::vector<double>& x,
                        std::size_t block) {
  const std::size_t ch = r.channels();
  NuResult res;
  std::vector<double> buf(8192 * ch);
  bool first = true;
  for (std::size_t i = 0; i < t.size(); i += block) {
    const std::size_t n = std::min(block, t.size() - i);
    const std::size_t w = r.process(&t[i], &x[i * ch], n, buf.data(), 8192);
    if (first) res.first_index = r.next_output_index() - static_cast<std::int64_t>(w);
    first = false;
    res.out.insert(res.out.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(w * ch));
  }
  for (std::size_t w; (w = r.process(nullptr, nullptr, 0, buf.data(), 8192)) > 0;)
    res.out.insert(res.out.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(w * ch));
  return res;
}

std::vector<double> sample_tones(const std::vector<std::vector<Tone>>& tones, const std::vector<double>& t,
                                 const std::vector<double>& offsets = {}) {
  const std::size_t ch = tones.size();
  std::vector<double> x(t.size() * ch);
  for (std::size_t i = 0; i < t.size(); ++i)
    for (std::size_t c = 0; c < ch; ++c)
      x[i * ch + c] = (offsets.empty() ? 0.0 : offsets[c]) + tones_at(tones[c], t[i]);
  return x;
}

// The first output frames see the held first value through the decimation filter (1.3 ms at 40 kHz).
constexpr double kNonuniformSkipS = 0.005;
constexpr double kOutRate = 40000.0;

// Relative rms error (of the AC part) of channel c from skip_s after the first output on.
double nonuniform_error(const NuResult& res, std::size_t ch, std::size_t c, const std::vector<Tone>& tones,
                        double offset = 0.0) {
  std::vector<double> err, ref;
  const std::size_t skip = static_cast<std::size_t>(kNonuniformSkipS * kOutRate);
  for (std::size_t j = skip; j < res.out.size() / ch; ++j) {
    const double t = static_cast<double>(res.first_index + static_cast<std::int64_t>(j)) / kOutRate;
    const double truth = tones_at(tones, t);
    ref.push_back(truth);
    err.push_back(res.out[j * ch + c] - offset - truth);
  }
  return rms(err) / rms(ref);
}

const Crank kIdle{3050.0, 0.01, -3.7e-6};  // 183 kHz edge rate at 0.1 deg; first edge 3.7 us after t = 0

// The fast-edge checks run on both fine grids: the any-encoder default (8 x the output rate) and the one a
// resampler told the highest edge rate picks (4 x for 183 kHz edges: content to 91.5 kHz must not fold into
// the band, which a 160 kHz grid just allows).
constexpr double kSizedMaxEdgeRateHz = 1.25 * 183000.0;
const double kFineGrids[] = {NonuniformResampler::kAnyEncoderEdgeRateHz, kSizedMaxEdgeRateHz};

TEST(NonuniformResampler, TheFineGridFollowsTheHighestEdgeRate) {
  EXPECT_DOUBLE_EQ(NonuniformResampler(kOutRate, 1).max_edge_rate_hz(), 600000.0);
  EXPECT_DOUBLE_EQ(NonuniformResampler(kOutRate, 1, kSizedMaxEdgeRateHz).max_edge_rate_hz(), 280000.0);
  EXPECT_DOUBLE_EQ(NonuniformResampler(kOutRate, 1, 1.2e6).max_edge_rate_hz(), 1240000.0);
  EXPECT_THROW(NonuniformResampler(kOutRate, 1, 0.0), std::invalid_argument);
}

TEST(NonuniformResampler, FastEdgesMatchTheAnalyticSignal) {
  const auto t = edge_times(kIdle, 0.1, 0.0, 183000 * 3 / 10);  // 0.3 s
  // Channel 1 rides on a large mean like absolute cylinder pressure (Pa).
  const std::vector<std::vector<Tone>> tones = {
      {{20.0, 1.0, 0.1},
       {315.0, 0.5, 0.2},
       {1000.0, 0.5, 0.3},
       {4000.0, 0.3, 0.4},
       {10000.0, 0.2, 0.5},
       {16000.0, 0.2, 0.6}},
      {{50.0, 2000.0, 1.0}, {2500.0, 500.0, 2.0}, {8000.0, 300.0, 3.0}, {12500.0, 200.0, 4.0}, {15000.0, 100.0, 5.0}}};
  const std::vector<double> offsets = {0.0, 1.0e5};
  for (const double max_edge_rate : kFineGrids) {
    NonuniformResampler r(kOutRate, 2, max_edge_rate);
    const NuResult res = run_nonuniform(r, t, sample_tones(tones, t, offsets), 256);
    const double e0 = nonuniform_error(res, 2, 0, tones[0]);
    const double e1 = nonuniform_error(res, 2, 1, tones[1], offsets[1]);
    EXPECT_LT(e0, 1e-3);
    EXPECT_LT(e1, 1e-3);
    EXPECT_DOUBLE_EQ(r.passband_edge_hz(), 18000.0);
    std::printf(
        "nonuniform 183k edges tone mixes (sized for %.0f kHz edges): relative rms error %.2e, %.2e "
        "(on a 1e5 mean)\n",
        1e-3 * max_edge_rate, e0, e1);
  }
}

TEST(NonuniformResampler, FlatWithExactPhaseUpToThePassbandEdge) {
  const auto t = edge_times(kIdle, 0.1, 0.0, 183000 / 20);  // 50 ms per tone
  for (const double max_edge_rate : kFineGrids) {
    double worst_db = 0.0, worst_phase = 0.0;
    for (int i = 0; i <= 24; ++i) {
      const double f = 20.0 * std::pow(18000.0 / 20.0, i / 24.0);
      const Tone tone{f, 1.0, -0.4};
      NonuniformResampler r(kOutRate, 1, max_edge_rate);
      const NuResult res = run_nonuniform(r, t, sample_tones({{tone}}, t), 300);
      std::vector<double> y, tk;
      for (std::size_t j = static_cast<std::size_t>(kNonuniformSkipS * kOutRate); j < res.out.size(); ++j) {
        y.push_back(res.out[j]);
        tk.push_back(static_cast<double>(res.first_index + static_cast<std::int64_t>(j)) / kOutRate);
      }
      expect_unit_gain_and_phase(y, tk, f, tone.phase_rad, worst_db, worst_phase);
    }
    std::printf(
        "nonuniform 183k edges 20 Hz..18 kHz (sized for %.0f kHz edges): gain within %.1e dB, phase "
        "within %.1e rad\n",
        1e-3 * max_edge_rate, worst_db, worst_phase);
  }
}

TEST(NonuniformResampler, RejectsContentAboveTheOutputNyquist) {
  const auto t = edge_times(kIdle, 0.1, 0.0, 183000 / 10);
  for (const double max_edge_rate : kFineGrids) {
    double worst_db = -1000.0;
    for (double f : {20050.0, 21000.0, 24000.0, 40000.0, 70000.0, 90000.0}) {
      NonuniformResampler r(kOutRate, 1, max_edge_rate);
      const NuResult res = run_nonuniform(r, t, sample_tones({{{f, 1.0, 0.0}}}, t), 256);
      const std::vector<double> steady(res.out.begin() + static_cast<std::ptrdiff_t>(kNonuniformSkipS * kOutRate),
                                       res.out.end());
      const double level_db = 20.0 * std::log10(rms(steady) / std::sqrt(0.5));
      worst_db = std::max(worst_db, level_db);
      EXPECT_LT(level_db, -80.0) << f << " Hz";
    }
    std::printf("nonuniform 183k edges alias rejection (sized for %.0f kHz edges): worst %.1f dB\n",
                1e-3 * max_edge_rate, worst_db);
  }
}

TEST(NonuniformResampler, SlowEdgesAreAccurateUpToTheirOwnPassband) {
  // 1 deg at 1000 rpm: 6 kHz edges, slower than the 40 kHz output.
  const Crank slow{1000.0, 0.01, -50e-6};
  const auto t = edge_times(slow, 1.0, 0.0, 6000 / 2);  // 0.5 s
  const std::vector<Tone> tones = {
      {20.0, 1.0, 0.0}, {200.0, 0.7, 1.0}, {1000.0, 0.5, 2.0}, {2000.0, 0.3, 3.0}, {2400.0, 0.3, 4.0}};
  NonuniformResampler r(kOutRate, 1);
  const NuResult res = run_nonuniform(r, t, sample_tones({tones}, t), 100);
  // The reported passband follows the edge rate: inside the input's own Nyquist (3 kHz), above 2.4 kHz.
  EXPECT_GT(r.passband_edge_hz(), 2400.0);
  EXPECT_LT(r.passband_edge_hz(), 3000.0);
  const double e = nonuniform_error(res, 1, 0, tones);
  EXPECT_LT(e, 1e-3);
  std::printf("nonuniform 6k edges tones to 2.4 kHz: relative rms error %.2e, passband %.0f Hz\n", e,
              r.passband_edge_hz());
}

TEST(NonuniformResampler, ConstantInputComesOutExactly) {
  const auto t = edge_times(kIdle, 0.1, 0.0, 20000);
  NonuniformResampler r(kOutRate, 1);
  const NuResult res = run_nonuniform(r, t, std::vector<double>(t.size(), 1.234e6), 1000);
  ASSERT_GT(res.out.size(), 3000u);
  for (double v : res.out) ASSERT_NEAR(v, 1.234e6, 1e-7);
}

TEST(NonuniformResampler, OutputStartsAtTheFirstGridInstantAtOrAfterTheFirstInput) {
  struct Case {
    double t0;
    std::int64_t first;
  };
  // Grid instants are k / 40000 s = k * 25 us.
  for (const Case cs : {Case{0.0, 0}, Case{125e-6, 5}, Case{125e-6 + 1e-9, 6}, Case{124e-6, 5}, Case{1.0, 40000}}) {
    std::vector<double> t(2000), x(2000, 1.0);
    for (std::size_t i = 0; i < t.size(); ++i) t[i] = cs.t0 + static_cast<double>(i) * 5e-6;
    NonuniformResampler r(kOutRate, 1);
    std::vector<double> out(1000);
    const std::size_t w = r.process(t.data(), x.data(), t.size(), out.data(), out.size());
    ASSERT_GT(w, 0u);
    EXPECT_EQ(r.next_output_index() - static_cast<std::int64_t>(w), cs.first) << "t0 = " << cs.t0;
    // Emitted only once the input reaches past the frame: the last frame is not after the last input.
    EXPECT_LE(static_cast<double>(r.next_output_index() - 1) / kOutRate, t.back());
  }
}

TEST(NonuniformResampler, HoursIntoTheStreamIsAsAccurate) {
  // The engine has been running for 5 hours: times near 18000 s, grid indices near 7.2e8.
  Crank late = kIdle;
  late.t_start = 0.0;
  const double first_edge = std::ceil(late.angle(5 * 3600.0) / 0.1);
  const auto t = edge_times(late, 0.1, first_edge, 183000 / 5);
  const std::vector<Tone> tones = {{31.5, 1.0, 0.0}, {1000.0, 0.5, 1.0}, {8000.0, 0.3, 2.0}, {16000.0, 0.2, 3.0}};
  NonuniformResampler r(kOutRate, 1);
  const NuResult res = run_nonuniform(r, t, sample_tones({tones}, t), 256);
  EXPECT_GT(res.first_index, static_cast<std::int64_t>(5 * 3600 * kOutRate) - 1);
  const double e = nonuniform_error(res, 1, 0, tones);
  EXPECT_LT(e, 1e-3);
  std::printf("nonuniform 183k edges at t = 5 h: relative rms error %.2e\n", e);
}

TEST(NonuniformResampler, RandomBlocksAndShortOutputBuffersEqualOnePiece) {
  const auto t = edge_times(kIdle, 0.1, 0.0, 60000);
  const std::vector<std::vector<Tone>> tones = {{{440.0, 1.0, 0.0}, {9000.0, 0.5, 0.0}}, {{3000.0, 1.0, 1.0}}};
  const auto x = sample_tones(tones, t, {0.0, 5e5});
  NonuniformResampler whole(kOutRate, 2);
  const NuResult reference = run_nonuniform(whole, t, x, t.size());

  NonuniformResampler pieces(kOutRate, 2);
  std::mt19937 rng(11);
  std::vector<double> got, buf(4096 * 2);
  std::int64_t first_index = -1;
  std::size_t i = 0;
  while (i < t.size()) {
    const std::size_t n = std::min<std::size_t>(std::uniform_int_distribution<std::size_t>(0, 900)(rng), t.size() - i);
    const std::size_t room = std::uniform_int_distribution<std::size_t>(0, 300)(rng);
    if (first_index >= 0) {
      ASSERT_EQ(pieces.next_output_index(), first_index + static_cast<std::int64_t>(got.size() / 2));
    }
    const std::size_t w = pieces.process(&t[i], &x[i * 2], n, buf.data(), room);
    ASSERT_LE(w, room);
    if (first_index < 0 && n > 0) first_index = pieces.next_output_index() - static_cast<std::int64_t>(w);
    got.insert(got.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(w * 2));
    i += n;
  }
  for (std::size_t w; (w = pieces.process(nullptr, nullptr, 0, buf.data(), 100)) > 0;)
    got.insert(got.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(w * 2));
  EXPECT_EQ(first_index, reference.first_index);
  ASSERT_EQ(got.size(), reference.out.size());
  for (std::size_t j = 0; j < got.size(); ++j) ASSERT_EQ(got[j], reference.out[j]) << "sample " << j;
}

TEST(NonuniformResampler, RejectsTimesThatDoNotIncrease) {
  NonuniformResampler r(kOutRate, 1);
  std::vector<double> out(100);
  const double t1[] = {0.0, 1e-5, 2e-5}, x1[] = {0.0, 0.0, 0.0};
  r.process(t1, x1, 3, out.data(), out.size());
  const double t2[] = {2e-5}, x2[] = {0.0};
  EXPECT_THROW(r.process(t2, x2, 1, out.data(), out.size()), std::invalid_argument);
  // A rejected call changes nothing: the stream goes on from the last good sample.
  const double t3[] = {2.5e-5, 3e-5}, x3[] = {0.0, 0.0};
  EXPECT_NO_THROW(r.process(t3, x3, 2, out.data(), out.size()));
  EXPECT_THROW(NonuniformResampler(kOutRate, 0), std::invalid_argument);
}

}  // namespace
}  // namespace noisemon::dsp
