#include "dsp/resample.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "dsp/fir_design.hpp"
#include "dsp/kernel_clones.hpp"
#include "dsp/output_queue.hpp"
#include "dsp/simd_vectors.hpp"
#include "dsp/sinc_kernel.hpp"

namespace noisemon::dsp {
namespace {

using simd::dot;
using simd::dot4;
using simd::kVd;
using simd::load;
using simd::Vd;

// Anti-alias / anti-image low-pass of both resamplers: flat to 0.45 * rate, >= 80 dB from 0.5 * rate
// (designed for 85 dB so Kaiser's length estimate has margin; the tests measure it).
constexpr double kPassbandFraction = 0.45;
constexpr double kStopbandFraction = 0.5;
constexpr double kDesignAttenuationDb = 85.0;

// Frames a call could not hand out (max_out too small) wait here for the next call. Fixed size, so no
// allocation after construction; overflowing it means the caller never drains and is a usage error.
constexpr std::size_t kPendingFrames = 8192;

// Input frames copied into a FIR's history per pass.
constexpr std::size_t kChunkFrames = 1024;

// Where a FIR's outputs go: channel c of output j lands at base[c * channel_stride + j * frame_stride] (frames
// interleaved: 1, channels; channel-major rows: row length, 1).
struct FirOutput {
  double* base;
  std::size_t channel_stride;
  std::size_t frame_stride;
};

// A polyphase FIR's state as its hot loop reads it (see PolyphaseFir).
template <class T>
struct FirView {
  const T* coef;
  std::size_t taps;
  std::int64_t up, down, half;
  const T* history;
  std::size_t history_stride;
  std::int64_t base;  // absolute input index of history[0]
  std::size_t channels;
};

// Outputs k .. k + count - 1 of a polyphase FIR, all channels: one dot product of a phase's taps with each
// channel's history per output.
template <class T>
NOISEMON_INLINE void fir_outputs_body(const FirView<T>& f, std::int64_t k, std::size_t count, FirOutput out) {
  for (std::size_t j = 0; j < count; ++j, ++k) {
    const std::int64_t tick = k * f.down + f.half;
    const std::int64_t newest = tick / f.up;
    const T* c = &f.coef[static_cast<std::size_t>(tick - newest * f.up) * f.taps];
    const auto offset = static_cast<std::size_t>(newest - static_cast<std::int64_t>(f.taps) + 1 - f.base);
    double* frame = out.base + j * out.frame_stride;
    std::size_t ch = 0;
    for (; ch + 4 <= f.channels; ch += 4) {
      const T* rows[4];
      for (std::size_t q = 0; q < 4; ++q) rows[q] = &f.history[(ch + q) * f.history_stride + offset];
      T sums[4];
      dot4(c, rows, f.taps, sums);
      for (std::size_t q = 0; q < 4; ++q) frame[(ch + q) * out.channel_stride] = sums[q];
    }
    for (; ch < f.channels; ++ch)
      frame[ch * out.channel_stride] = dot(c, &f.history[ch * f.history_stride + offset], f.taps);
  }
}
// The hot loop of both resamplers, in double (pressure: a small signal on a large mean) and in float
// (microphones: float WAVs and ADC words, twice the lanes per vector).
NOISEMON_KERNEL_CLONES void fir_outputs(const FirView<double>& f, std::int64_t k, std::size_t count, FirOutput out) {
  fir_outputs_body(f, k, count, out);
}
NOISEMON_KERNEL_CLONES void fir_outputs(const FirView<float>& f, std::int64_t k, std::size_t count, FirOutput out) {
  fir_outputs_body(f, k, count, out);
}

// Streaming zero-delay polyphase FIR: upsample by `up`, filter with the centred prototype h[-J..J]
// (running at up * input rate), keep every `down`-th sample. Output k lands on tick k * down, input m on
// tick m * up, so y[k] = sum_m x[m] h[k down - m up]: no delay, output k waits for input floor((k down + J) / up).
// History is kept per channel (contiguous, for the dot products) with absolute input indices, in T.
// Taps per phase padded with zeros (at the oldest end) to whole vectors: the dot products need no scalar tail.
constexpr std::size_t padded_taps(std::size_t taps) { return (taps + 7) / 8 * 8; }

template <class T>
class PolyphaseFir {
 public:
  PolyphaseFir(const std::vector<double>& prototype, std::size_t up, std::size_t down, std::size_t channels)
      : up_(static_cast<std::int64_t>(up)),
        down_(static_cast<std::int64_t>(down)),
        half_(static_cast<std::int64_t>(prototype.size() / 2)),
        taps_(padded_taps((prototype.size() + up - 1) / up)),
        channels_(channels),
        stride_(taps_ + kChunkFrames),
        coef_(up * taps_, T{0}),
        history_(channels * stride_, T{0}) {
    // Phase p holds h0[p + i up] for i = taps-1 .. 0 (oldest input first), h0[n] = h[n - J].
    std::vector<double> row(taps_);
    for (std::size_t p = 0; p < up; ++p) {
      for (std::size_t i = 0; i < taps_; ++i) {
        const std::size_t n = p + i * up;
        row[taps_ - 1 - i] = n < prototype.size() ? prototype[n] : 0.0;
      }
      // Every phase passes DC exactly in double (pressure rides on a large mean).
      const double sum = std::accumulate(row.begin(), row.end(), 0.0);
      for (std::size_t i = 0; i < taps_; ++i) coef_[p * taps_ + i] = static_cast<T>(row[i] / sum);
    }
  }

  // Positions the stream so that the first output is k_first; returns the absolute index of the first
  // input frame the caller must supply (earlier ones are never needed).
  std::int64_t start(std::int64_t k_first) {
    next_k_ = k_first;
    base_ = newest_needed(k_first) - static_cast<std::int64_t>(taps_) + 1;
    len_ = 0;
    return base_;
  }

  std::size_t room() const { return stride_ - len_; }
  std::size_t history_stride() const { return stride_; }
  T* channel_tail(std::size_t c) { return &history_[c * stride_ + len_]; }
  void commit(std::size_t frames) { len_ += frames; }
  std::int64_t next_output() const { return next_k_; }
  std::size_t up() const { return static_cast<std::size_t>(up_); }
  std::size_t down() const { return static_cast<std::size_t>(down_); }
  // Most outputs one run() can have ready (a full history).
  std::size_t max_ready() const { return (stride_ * up()) / down() + 2; }

  // Computes up to max_out of the outputs whose input has arrived, then drops history no later output needs.
  // Returns the count written.
  std::size_t run(FirOutput out, std::size_t max_out) {
    const std::int64_t end = base_ + static_cast<std::int64_t>(len_);
    std::size_t count = 0;
    while (count < max_out && newest_needed(next_k_ + static_cast<std::int64_t>(count)) < end) ++count;
    fir_outputs(FirView<T>{coef_.data(), taps_, up_, down_, half_, history_.data(), stride_, base_, channels_}, next_k_,
                count, out);
    next_k_ += static_cast<std::int64_t>(count);
    drop_history(end);
    return count;
  }
  // Runs into a queue of interleaved frames through `scratch` (max_ready() frames).
  void run(OutputQueue& queue, double* scratch) {
    queue.push(scratch, run(FirOutput{scratch, 1, channels_}, max_ready()));
  }

 private:
  std::int64_t newest_needed(std::int64_t k) const { return (k * down_ + half_) / up_; }

  void drop_history(std::int64_t end) {
    const std::int64_t keep_from = std::min(newest_needed(next_k_) - static_cast<std::int64_t>(taps_) + 1, end);
    const auto drop = static_cast<std::size_t>(keep_from - base_);
    if (drop == 0) return;
    const std::size_t kept = len_ - drop;
    for (std::size_t ch = 0; ch < channels_; ++ch) {
      T* h = &history_[ch * stride_];
      std::memmove(h, h + drop, kept * sizeof(T));
    }
    len_ = kept;
    base_ = keep_from;
  }

  std::int64_t up_, down_, half_;
  std::size_t taps_;  // per phase
  std::size_t channels_;
  std::size_t stride_;  // history capacity per channel
  std::vector<T> coef_;
  std::vector<T> history_;
  std::int64_t base_ = 0;  // absolute input index of history_[ch * stride_]
  std::size_t len_ = 0;
  std::int64_t next_k_ = 0;
};

// Low-pass running at filter_rate_hz, flat to pass_hz, >= kDesignAttenuationDb from stop_hz.
std::vector<double> kaiser_design(double filter_rate_hz, double pass_hz, double stop_hz,
                                  double attenuation_db = kDesignAttenuationDb) {
  const double pass = pass_hz / filter_rate_hz;
  const double stop = stop_hz / filter_rate_hz;
  const std::size_t half = fir::kaiser_half_length(attenuation_db, stop - pass);
  return fir::kaiser_lowpass(half, 0.5 * (pass + stop), fir::kaiser_beta(attenuation_db));
}

// Low-pass for a resampler running at `filter_rate_hz`, passband edge kPassbandFraction * band_rate_hz.
std::vector<double> design_lowpass(double filter_rate_hz, double band_rate_hz) {
  return kaiser_design(filter_rate_hz, kPassbandFraction * band_rate_hz, kStopbandFraction * band_rate_hz);
}

std::int64_t integer_rate(double rate_hz, const char* what) {
  const double r = std::round(rate_hz);
  if (!(rate_hz > 0.0) || r > 1e12 || std::abs(rate_hz - r) > 1e-9 * r)
    throw std::invalid_argument(std::string("RationalResampler: ") + what + " must be a positive whole number of Hz");
  return static_cast<std::int64_t>(r);
}

void require_channels(std::size_t channels, const char* who) {
  if (channels == 0) throw std::invalid_argument(std::string(who) + ": channels must be positive");
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// RationalResampler

struct RationalResampler::Impl {
  using Fir = std::variant<PolyphaseFir<double>, PolyphaseFir<float>>;

  static Fir make_fir(double in_hz, double out_hz, std::size_t channels, SamplePrecision precision) {
    const std::int64_t in = integer_rate(in_hz, "input rate");
    const std::int64_t out = integer_rate(out_hz, "output rate");
    const std::int64_t g = std::gcd(in, out);
    const auto up = static_cast<std::size_t>(out / g);
    const auto down = static_cast<std::size_t>(in / g);
    // Both bound the filter: its length grows with up * max(1, down / up) taps.
    if (up > 4096) throw std::invalid_argument("RationalResampler: rate ratio needs more than 4096 filter phases");
    if (down > 4096) throw std::invalid_argument("RationalResampler: rate ratio decimates by more than 4096");
    const std::vector<double> prototype = design_lowpass(static_cast<double>(up) * in_hz, std::min(in_hz, out_hz));
    if (precision == SamplePrecision::kSingle) return PolyphaseFir<float>(prototype, up, down, channels);
    return PolyphaseFir<double>(prototype, up, down, channels);
  }

  Impl(double in_hz, double out_hz, std::size_t ch, SamplePrecision precision)
      : channels(ch),
        passband_hz(converter_passband_hz(std::min(in_hz, out_hz))),
        fir(make_fir(in_hz, out_hz, ch, precision)),
        queue(ch, kPendingFrames) {
    std::visit(
        [&](auto& f) {
          scratch.resize(f.max_ready() * ch);
          // Before input frame 0 the signal is zero.
          const auto zeros = static_cast<std::size_t>(-f.start(0));
          for (std::size_t c = 0; c < channels; ++c) std::fill_n(f.channel_tail(c), zeros, 0);
          f.commit(zeros);
        },
        fir);
  }

  // Copies interleaved input into the FIR's channel rows (in its precision) and runs it, as far as it goes.
  template <class T>
  void feed(PolyphaseFir<T>& f, const double* in, std::size_t frames) {
    std::size_t done = 0;
    while (done < frames) {
      const std::size_t n = std::min(frames - done, f.room());
      const double* src = in + done * channels;
      for (std::size_t c = 0; c < channels; ++c) {
        T* dst = f.channel_tail(c);
        for (std::size_t i = 0; i < n; ++i) dst[i] = static_cast<T>(src[i * channels + c]);
      }
      f.commit(n);
      done += n;
      f.run(queue, scratch.data());
    }
  }

  std::size_t channels;
  double passband_hz;
  Fir fir;
  OutputQueue queue;
  std::vector<double> scratch;  // one run's outputs, interleaved
};

RationalResampler::RationalResampler(double in_rate_hz, double out_rate_hz, std::size_t channels,
                                     SamplePrecision precision) {
  require_channels(channels, "RationalResampler");
  impl_ = std::make_unique<Impl>(in_rate_hz, out_rate_hz, channels, precision);
}
RationalResampler::~RationalResampler() = default;
RationalResampler::RationalResampler(RationalResampler&&) noexcept = default;
RationalResampler& RationalResampler::operator=(RationalResampler&&) noexcept = default;

std::size_t RationalResampler::process(const double* in, std::size_t frames, double* out, std::size_t max_out) {
  Impl& s = *impl_;
  s.queue.begin(out, max_out);
  std::visit([&](auto& f) { s.feed(f, in, frames); }, s.fir);
  return s.queue.written();
}

std::size_t RationalResampler::max_output_frames(std::size_t input_frames) const {
  // New input spans input_frames * up ticks; outputs fall every `down` ticks.
  const std::size_t up = std::visit([](const auto& f) { return f.up(); }, impl_->fir);
  const std::size_t down = std::visit([](const auto& f) { return f.down(); }, impl_->fir);
  return impl_->queue.pending() + (input_frames * up + down - 1) / down;
}

std::int64_t RationalResampler::next_output_index() const {
  const std::int64_t next = std::visit([](const auto& f) { return f.next_output(); }, impl_->fir);
  return next - static_cast<std::int64_t>(impl_->queue.pending());
}
double RationalResampler::passband_edge_hz() const { return impl_->passband_hz; }
std::size_t RationalResampler::channels() const { return impl_->channels; }

// ---------------------------------------------------------------------------------------------------------
// NonuniformResampler
//
// Stage 1: band-limited interpolation onto a fine uniform grid at fine_factor * out_rate (the smallest power of
// two from 4 that keeps the highest expected edge rate's content out of the band, see below). The samples are
// treated as uniform in their index (crank-angle clocking makes them uniform in angle): the fractional index
// u(t) of a grid instant comes from cubic interpolation of the index against the sample times, and the value
// from a Kaiser-windowed sinc in u (2 * kKernelHalfWidth taps from a table whose rows sum to 1, so DC is
// exact). This is band-limited to about kIndexPassband cycles per input sample, i.e. 0.41 * the local edge
// rate; when the edges are slower than the output the passband is therefore that, below the input's own
// Nyquist (passband_edge_hz() reports it from the edge rate of the latest call).
// Stage 2: decimation to out_rate in two zero-delay low-pass steps: the fine grid to 2 * out_rate (flat to
// 0.5 out_rate, >= 80 dB from 1.5 out_rate: what would fold into the band; a short filter), then the same
// low-pass as the rational resampler (flat to 0.45 out_rate, >= 80 dB from 0.5 out_rate) at 2 * out_rate,
// where it needs a quarter of the taps it needs on the fine grid. Input content between the output Nyquist
// and half the edge rate is removed here; it stays out of the passband for edge rates up to
// 2 * (fine_factor - 0.5) * out_rate (280 kHz at a 4 x 40 kHz fine grid, 600 kHz at 8 x).
// Before the first input the signal is held at the first sample's value (no step for a signal on a mean).

namespace {
constexpr std::int64_t kMidFactor = 2;  // the decimation's intermediate rate, in output rates
// The first decimation step is short (about 30 taps), so it is designed far below the second's ripple: the
// pair then passes tones as flat as the single filter did.
constexpr double kFirstStepAttenuationDb = 110.0;
using namespace sinc_kernel;
constexpr std::size_t kPlanFrames = 256;  // fine-grid instants planned per pass

// Where each planned fine-grid instant reads: the first of its kKernelTaps samples in the history, and its
// position between kernel rows (row + fraction); a negative position holds the first sample's value.
struct FinePlan {
  std::size_t offset[kPlanFrames];
  double position[kPlanFrames];
};

// The fine-grid values of a plan, channel c of instant j to out[c * out_stride + j]. The hot loop of the
// crank-angle resampler: a blend of two kernel rows, then one dot product per channel. (A template, like the
// FIR's body, so that clang compiles its 32-byte vectors inside each clone instead of refusing them in the
// default one; T is double.)
template <class T>
NOISEMON_INLINE void interpolate_fine_body(const T* table, const FinePlan& plan, std::size_t count, const T* values,
                                           std::size_t values_stride, std::size_t channels, const T* hold, T* out,
                                           std::size_t out_stride) {
  constexpr std::size_t kWeightVectors = kKernelTaps / kVd;
  static_assert(kKernelTaps % (2 * kVd) == 0, "the kernel is a whole number of vector pairs");
  for (std::size_t j = 0; j < count; ++j) {
    const double pos = plan.position[j];
    if (pos < 0.0) {
      for (std::size_t c = 0; c < channels; ++c) out[c * out_stride + j] = hold[c];
      continue;
    }
    const auto row = std::min(static_cast<std::size_t>(pos), kKernelPhases - 1);
    const double a = pos - static_cast<double>(row);
    const double* r0 = &table[row * kKernelTaps];
    const double* r1 = r0 + kKernelTaps;
    Vd weights[kWeightVectors];
    for (std::size_t v = 0; v < kWeightVectors; ++v) {
      const Vd w0 = load(r0 + v * kVd);
      weights[v] = w0 + a * (load(r1 + v * kVd) - w0);
    }
    for (std::size_t c = 0; c < channels; ++c) {
      const double* x = &values[c * values_stride + plan.offset[j]];
      Vd acc0 = {}, acc1 = {};
      for (std::size_t v = 0; v < kWeightVectors; v += 2) {
        acc0 += weights[v] * load(x + v * kVd);
        acc1 += weights[v + 1] * load(x + (v + 1) * kVd);
      }
      const Vd acc = acc0 + acc1;
      out[c * out_stride + j] = (acc[0] + acc[2]) + (acc[1] + acc[3]);
    }
  }
}
NOISEMON_KERNEL_CLONES void interpolate_fine(const double* table, const FinePlan& plan, std::size_t count,
                                             const double* values, std::size_t values_stride, std::size_t channels,
                                             const double* hold, double* out, std::size_t out_stride) {
  interpolate_fine_body(table, plan, count, values, values_stride, channels, hold, out, out_stride);
}
}  // namespace

struct NonuniformResampler::Impl {
  // Content up to half the edge rate must stay above fine_rate - 0.5 out_rate (it would fold into the band).
  static std::int64_t fine_factor_for(double out_hz, double max_edge_rate_hz) {
    std::int64_t factor = 2 * kMidFactor;
    while (static_cast<double>(factor) * out_hz < 0.5 * (max_edge_rate_hz + out_hz)) factor *= 2;
    return factor;
  }
  static PolyphaseFir<double> make_fine_to_mid(double out_hz, std::int64_t fine_factor, std::size_t ch) {
    const double fine_hz = static_cast<double>(fine_factor) * out_hz;
    const double mid_hz = static_cast<double>(kMidFactor) * out_hz;
    return PolyphaseFir<double>(kaiser_design(fine_hz, 0.5 * out_hz, mid_hz - 0.5 * out_hz, kFirstStepAttenuationDb), 1,
                                static_cast<std::size_t>(fine_factor / kMidFactor), ch);
  }
  static PolyphaseFir<double> make_mid_to_out(double out_hz, std::size_t ch) {
    return PolyphaseFir<double>(design_lowpass(static_cast<double>(kMidFactor) * out_hz, out_hz), 1,
                                static_cast<std::size_t>(kMidFactor), ch);
  }

  Impl(double out_hz, std::size_t ch, double max_edge_rate_hz)
      : channels(ch),
        out_rate(out_hz),
        fine_factor(fine_factor_for(out_hz, max_edge_rate_hz)),
        fine_rate(static_cast<double>(fine_factor) * out_hz),
        table(shared_interpolation_table()),
        stride(kKernelTaps + kChunkFrames),
        times(stride),
        values(ch * stride),
        first_values(ch),
        fine_to_mid(make_fine_to_mid(out_hz, fine_factor, ch)),
        mid_to_out(make_mid_to_out(out_hz, ch)),
        queue(ch, kPendingFrames),
        scratch(mid_to_out.max_ready() * ch) {}

  // First input: output starts at the first grid instant at or after it; earlier samples hold its value.
  void start(const double* x0, double t0) {
    t_first = t0;
    auto k0 = static_cast<std::int64_t>(std::ceil(t0 * out_rate));
    while (static_cast<double>(k0 - 1) / out_rate >= t0) --k0;
    while (static_cast<double>(k0) / out_rate < t0) ++k0;
    next_fine = fine_to_mid.start(mid_to_out.start(k0));
    const auto w = static_cast<std::int64_t>(kKernelHalfWidth);
    base = -w;
    len = kKernelHalfWidth;
    for (std::size_t c = 0; c < channels; ++c) {
      first_values[c] = x0[c];
      std::fill_n(&values[c * stride], kKernelHalfWidth, x0[c]);
    }
    std::fill_n(times.begin(), kKernelHalfWidth, t0);  // never read: the cubic map uses indices >= 0
    cursor = 0;
    started = true;
  }

  double time_at(std::int64_t i) const { return times[static_cast<std::size_t>(i - base)]; }

  // Fractional sample index at time tau, tau in [t_cursor, t_cursor+1): cubic Lagrange through the 4 samples
  // from p0 = max(cursor - 1, 0); the basis denominators are kept while p0 stays.
  double fractional_index(double tau) {
    const std::int64_t p0 = std::max<std::int64_t>(cursor - 1, 0);
    if (p0 != map_p0) {
      map_p0 = p0;
      for (int j = 0; j < 4; ++j) map_t[j] = time_at(p0 + j);
      const double* t = map_t;
      map_c[0] = 1.0 / ((t[1] - t[0]) * (t[1] - t[2]) * (t[1] - t[3]));
      map_c[1] = 2.0 / ((t[2] - t[0]) * (t[2] - t[1]) * (t[2] - t[3]));
      map_c[2] = 3.0 / ((t[3] - t[0]) * (t[3] - t[1]) * (t[3] - t[2]));
    }
    const double d0 = tau - map_t[0], d1 = tau - map_t[1], d2 = tau - map_t[2], d3 = tau - map_t[3];
    return static_cast<double>(p0) + d0 * (d2 * d3 * map_c[0] + d1 * (d3 * map_c[1] + d2 * map_c[2]));
  }

  // Plans up to `limit` fine-grid instants from next_fine on, as far as the input allows; returns the count.
  std::size_t plan_fine(std::size_t limit) {
    const std::int64_t last = seen - 1;
    const auto w = static_cast<std::int64_t>(kKernelHalfWidth);
    std::size_t n = 0;
    for (; n < limit; ++n) {
      const double tau = static_cast<double>(next_fine + static_cast<std::int64_t>(n)) / fine_rate;
      if (tau < t_first) {
        plan.position[n] = -1.0;
        plan.offset[n] = 0;
        continue;
      }
      while (cursor < last && time_at(cursor + 1) <= tau) ++cursor;
      if (cursor + w > last) break;
      const double frac = std::clamp(fractional_index(tau) - static_cast<double>(cursor), 0.0, 1.0);
      plan.position[n] = frac * kKernelPhases;
      plan.offset[n] = static_cast<std::size_t>(cursor - w + 1 - base);
    }
    return n;
  }

  // Decimates what the fine grid holds as far as it goes, into the output queue.
  void decimate() {
    for (;;) {
      const std::size_t n =
          fine_to_mid.run(FirOutput{mid_to_out.channel_tail(0), mid_to_out.history_stride(), 1}, mid_to_out.room());
      mid_to_out.commit(n);
      mid_to_out.run(queue, scratch.data());
      if (n == 0) return;
    }
  }

  // Fills the fine grid as far as the input allows and decimates it.
  void produce() {
    for (;;) {
      if (fine_to_mid.room() == 0) decimate();
      const std::size_t wanted = std::min(kPlanFrames, fine_to_mid.room());
      const std::size_t n = plan_fine(wanted);
      interpolate_fine(table.data(), plan, n, values.data(), stride, channels, first_values.data(),
                       fine_to_mid.channel_tail(0), fine_to_mid.history_stride());
      fine_to_mid.commit(n);
      next_fine += static_cast<std::int64_t>(n);
      if (n < wanted) break;
    }
    decimate();
    drop_samples();
  }

  // Keeps the samples the next grid instant can reach.
  void drop_samples() {
    const std::int64_t keep_from = cursor - static_cast<std::int64_t>(kKernelHalfWidth) + 1;
    const auto drop = static_cast<std::size_t>(keep_from - base);
    if (drop == 0) return;
    const std::size_t kept = len - drop;
    std::memmove(times.data(), times.data() + drop, kept * sizeof(double));
    for (std::size_t c = 0; c < channels; ++c) {
      double* v = &values[c * stride];
      std::memmove(v, v + drop, kept * sizeof(double));
    }
    len = kept;
    base = keep_from;
  }

  std::size_t channels;
  double out_rate;
  std::int64_t fine_factor;
  double fine_rate;
  const std::vector<double>& table;  // windowed-sinc kernel, (kKernelPhases + 1) rows of kKernelTaps
  FinePlan plan;
  // Input history: samples base .. base + len - 1 (absolute indices; -W..-1 hold the first value).
  std::size_t stride;
  std::vector<double> times;
  std::vector<double> values;  // per channel, stride apart
  std::int64_t base = 0;
  std::size_t len = 0;
  std::int64_t seen = 0;       // input samples received
  std::int64_t cursor = 0;     // sample at or before the next fine-grid instant
  std::int64_t next_fine = 0;  // next fine-grid index (time next_fine / fine_rate)
  std::int64_t map_p0 = -1;    // first sample of the cached inverse-map window
  double map_t[4] = {};        // its times
  double map_c[3] = {};        // j / prod_{m != j}(t_j - t_m) for j = 1..3 (j = 0 contributes 0)
  double t_first = 0.0;
  double t_last = 0.0;
  double edge_rate_hz = 0.0;  // over the latest call
  std::vector<double> first_values;
  bool started = false;
  PolyphaseFir<double> fine_to_mid;  // fine grid -> kMidFactor * out_rate
  PolyphaseFir<double> mid_to_out;   // -> out_rate
  OutputQueue queue;
  std::vector<double> scratch;  // one run's outputs, interleaved
};

NonuniformResampler::NonuniformResampler(double out_rate_hz, std::size_t channels, double max_edge_rate_hz) {
  require_channels(channels, "NonuniformResampler");
  if (!(out_rate_hz > 0.0) || !std::isfinite(out_rate_hz))
    throw std::invalid_argument("NonuniformResampler: output rate must be positive");
  if (!(max_edge_rate_hz > 0.0) || !std::isfinite(max_edge_rate_hz))
    throw std::invalid_argument("NonuniformResampler: the highest edge rate must be positive");
  impl_ = std::make_unique<Impl>(out_rate_hz, channels, max_edge_rate_hz);
}
NonuniformResampler::~NonuniformResampler() = default;
NonuniformResampler::NonuniformResampler(NonuniformResampler&&) noexcept = default;
NonuniformResampler& NonuniformResampler::operator=(NonuniformResampler&&) noexcept = default;

std::size_t NonuniformResampler::process(const double* t, const double* x, std::size_t n, double* out,
                                         std::size_t max_out) {
  Impl& s = *impl_;
  s.queue.begin(out, max_out);
  if (n == 0) return s.queue.written();
  const std::size_t ch = s.channels;
  const double t_before = s.t_last;
  const bool had_input = s.started;
  // Check the whole call first so a rejected call changes nothing.
  double previous = had_input ? s.t_last : -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i) {
    if (!(t[i] > previous) || !std::isfinite(t[i]))
      throw std::invalid_argument("NonuniformResampler: sample times must be finite and strictly increasing");
    previous = t[i];
  }
  if (!s.started) s.start(x, t[0]);
  s.t_last = t[n - 1];
  std::size_t done = 0;
  while (done < n) {
    const std::size_t take = std::min(n - done, s.stride - s.len);
    for (std::size_t i = 0; i < take; ++i) {
      s.times[s.len + i] = t[done + i];
      const double* xi = x + (done + i) * ch;
      for (std::size_t c = 0; c < ch; ++c) s.values[c * s.stride + s.len + i] = xi[c];
    }
    s.len += take;
    s.seen += static_cast<std::int64_t>(take);
    done += take;
    s.produce();
  }
  const double span = had_input ? s.t_last - t_before : s.t_last - t[0];
  const std::size_t intervals = had_input ? n : n - 1;
  if (intervals > 0 && span > 0.0) s.edge_rate_hz = static_cast<double>(intervals) / span;
  return s.queue.written();
}

std::int64_t NonuniformResampler::next_output_index() const {
  return impl_->mid_to_out.next_output() - static_cast<std::int64_t>(impl_->queue.pending());
}

double crank_angle_passband_hz(double edge_rate_hz) { return kIndexPassband * edge_rate_hz; }

double converter_passband_hz(double rate_hz) { return kPassbandFraction * rate_hz; }

double NonuniformResampler::passband_edge_hz() const {
  const double out_limit = converter_passband_hz(impl_->out_rate);
  if (impl_->edge_rate_hz <= 0.0) return out_limit;
  return std::min(out_limit, crank_angle_passband_hz(impl_->edge_rate_hz));
}

std::size_t NonuniformResampler::channels() const { return impl_->channels; }

double NonuniformResampler::max_edge_rate_hz() const { return 2.0 * (impl_->fine_rate - 0.5 * impl_->out_rate); }

}  // namespace noisemon::dsp
