#include "dsp/resample.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include "dsp/fir_design.hpp"

namespace noisemon::dsp {
namespace {

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

double dot(const double* a, const double* b, std::size_t n) {
  // Eight independent partial sums: the compiler turns the lane loop into SIMD without reassociating.
  constexpr std::size_t kLanes = 8;
  double acc[kLanes] = {};
  std::size_t i = 0;
  for (; i + kLanes <= n; i += kLanes)
    for (std::size_t l = 0; l < kLanes; ++l) acc[l] += a[i + l] * b[i + l];
  double tail = 0.0;
  for (; i < n; ++i) tail += a[i] * b[i];
  return ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail;
}

// Delivers output frames into the caller's buffer; what does not fit is kept for the next call.
class OutputQueue {
 public:
  OutputQueue(std::size_t channels, std::size_t capacity_frames)
      : channels_(channels), capacity_(capacity_frames), ring_(channels * capacity_frames) {}

  // Starts a call: pending frames go out first.
  void begin(double* out, std::size_t max_out) {
    out_ = out;
    max_out_ = max_out;
    written_ = 0;
    while (count_ > 0 && written_ < max_out_) {
      std::memcpy(out_ + written_ * channels_, &ring_[head_ * channels_], channels_ * sizeof(double));
      head_ = (head_ + 1) % capacity_;
      --count_;
      ++written_;
    }
  }
  // Where the next frame goes (channels values).
  double* next_slot() {
    if (count_ == 0 && written_ < max_out_) return out_ + (written_++) * channels_;
    if (count_ == capacity_)
      throw std::length_error("resampler: more than " + std::to_string(capacity_) +
                              " output frames pending; call process() with more room in out");
    double* slot = &ring_[((head_ + count_) % capacity_) * channels_];
    ++count_;
    return slot;
  }
  std::size_t written() const { return written_; }
  std::size_t pending() const { return count_; }

 private:
  std::size_t channels_;
  std::size_t capacity_;
  std::vector<double> ring_;
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  double* out_ = nullptr;
  std::size_t max_out_ = 0;
  std::size_t written_ = 0;
};

// Streaming zero-delay polyphase FIR: upsample by `up`, filter with the centred prototype h[-J..J]
// (running at up * input rate), keep every `down`-th sample. Output k lands on tick k * down, input m on
// tick m * up, so y[k] = sum_m x[m] h[k down - m up]: no delay, output k waits for input floor((k down + J) / up).
// History is kept per channel (contiguous, for the dot products) with absolute input indices.
class PolyphaseFir {
 public:
  PolyphaseFir(const std::vector<double>& prototype, std::size_t up, std::size_t down, std::size_t channels)
      : up_(static_cast<std::int64_t>(up)),
        down_(static_cast<std::int64_t>(down)),
        half_(static_cast<std::int64_t>(prototype.size() / 2)),
        taps_((prototype.size() + up - 1) / up),
        channels_(channels),
        stride_(taps_ + kChunkFrames),
        coef_(up * taps_, 0.0),
        history_(channels * stride_, 0.0) {
    // Phase p holds h0[p + i up] for i = taps-1 .. 0 (oldest input first), h0[n] = h[n - J].
    for (std::size_t p = 0; p < up; ++p) {
      double* row = &coef_[p * taps_];
      for (std::size_t i = 0; i < taps_; ++i) {
        const std::size_t n = p + i * up;
        row[taps_ - 1 - i] = n < prototype.size() ? prototype[n] : 0.0;
      }
      // Every phase passes DC exactly (pressure rides on a large mean).
      const double sum = std::accumulate(row, row + taps_, 0.0);
      for (std::size_t i = 0; i < taps_; ++i) row[i] /= sum;
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
  double* channel_tail(std::size_t c) { return &history_[c * stride_ + len_]; }
  void commit(std::size_t frames) { len_ += frames; }
  std::int64_t next_output() const { return next_k_; }
  std::int64_t half_length() const { return half_; }
  std::size_t up() const { return static_cast<std::size_t>(up_); }
  std::size_t down() const { return static_cast<std::size_t>(down_); }

  // Computes every output whose input has arrived, then drops history no later output needs.
  void run(OutputQueue& queue) {
    const std::int64_t end = base_ + static_cast<std::int64_t>(len_);
    for (;;) {
      const std::int64_t tick = next_k_ * down_ + half_;
      const std::int64_t newest = tick / up_;
      if (newest >= end) break;
      const double* c = &coef_[static_cast<std::size_t>(tick - newest * up_) * taps_];
      const auto offset = static_cast<std::size_t>(newest - static_cast<std::int64_t>(taps_) + 1 - base_);
      double* frame = queue.next_slot();
      for (std::size_t ch = 0; ch < channels_; ++ch) frame[ch] = dot(c, &history_[ch * stride_ + offset], taps_);
      ++next_k_;
    }
    const std::int64_t keep_from = std::min(newest_needed(next_k_) - static_cast<std::int64_t>(taps_) + 1, end);
    const auto drop = static_cast<std::size_t>(keep_from - base_);
    if (drop > 0) {
      const std::size_t kept = len_ - drop;
      for (std::size_t ch = 0; ch < channels_; ++ch) {
        double* h = &history_[ch * stride_];
        std::memmove(h, h + drop, kept * sizeof(double));
      }
      len_ = kept;
      base_ = keep_from;
    }
  }

 private:
  std::int64_t newest_needed(std::int64_t k) const { return (k * down_ + half_) / up_; }

  std::int64_t up_, down_, half_;
  std::size_t taps_;      // per phase
  std::size_t channels_;
  std::size_t stride_;    // history capacity per channel
  std::vector<double> coef_;
  std::vector<double> history_;
  std::int64_t base_ = 0;  // absolute input index of history_[ch * stride_]
  std::size_t len_ = 0;
  std::int64_t next_k_ = 0;
};

// Low-pass for a resampler running at `filter_rate_hz`, passband edge kPassbandFraction * band_rate_hz.
std::vector<double> design_lowpass(double filter_rate_hz, double band_rate_hz) {
  const double pass = kPassbandFraction * band_rate_hz / filter_rate_hz;
  const double stop = kStopbandFraction * band_rate_hz / filter_rate_hz;
  const std::size_t half = fir::kaiser_half_length(kDesignAttenuationDb, stop - pass);
  return fir::kaiser_lowpass(half, 0.5 * (pass + stop), fir::kaiser_beta(kDesignAttenuationDb));
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
  static PolyphaseFir make_fir(double in_hz, double out_hz, std::size_t channels) {
    const std::int64_t in = integer_rate(in_hz, "input rate");
    const std::int64_t out = integer_rate(out_hz, "output rate");
    const std::int64_t g = std::gcd(in, out);
    const auto up = static_cast<std::size_t>(out / g);
    const auto down = static_cast<std::size_t>(in / g);
    // Both bound the filter: its length grows with up * max(1, down / up) taps.
    if (up > 4096) throw std::invalid_argument("RationalResampler: rate ratio needs more than 4096 filter phases");
    if (down > 4096) throw std::invalid_argument("RationalResampler: rate ratio decimates by more than 4096");
    return PolyphaseFir(design_lowpass(static_cast<double>(up) * in_hz, std::min(in_hz, out_hz)), up, down,
                        channels);
  }

  Impl(double in_hz, double out_hz, std::size_t ch)
      : channels(ch), passband_hz(converter_passband_hz(std::min(in_hz, out_hz))), fir(make_fir(in_hz, out_hz, ch)),
        queue(ch, kPendingFrames) {
    // Before input frame 0 the signal is zero.
    const std::int64_t first = fir.start(0);
    const auto zeros = static_cast<std::size_t>(-first);
    for (std::size_t c = 0; c < channels; ++c) std::fill_n(fir.channel_tail(c), zeros, 0.0);
    fir.commit(zeros);
  }

  std::size_t channels;
  double passband_hz;
  PolyphaseFir fir;
  OutputQueue queue;
};

RationalResampler::RationalResampler(double in_rate_hz, double out_rate_hz, std::size_t channels) {
  require_channels(channels, "RationalResampler");
  impl_ = std::make_unique<Impl>(in_rate_hz, out_rate_hz, channels);
}
RationalResampler::~RationalResampler() = default;
RationalResampler::RationalResampler(RationalResampler&&) noexcept = default;
RationalResampler& RationalResampler::operator=(RationalResampler&&) noexcept = default;

std::size_t RationalResampler::process(const double* in, std::size_t frames, double* out, std::size_t max_out) {
  Impl& s = *impl_;
  s.queue.begin(out, max_out);
  const std::size_t ch = s.channels;
  std::size_t done = 0;
  while (done < frames) {
    const std::size_t n = std::min(frames - done, s.fir.room());
    const double* src = in + done * ch;
    for (std::size_t c = 0; c < ch; ++c) {
      double* dst = s.fir.channel_tail(c);
      for (std::size_t i = 0; i < n; ++i) dst[i] = src[i * ch + c];
    }
    s.fir.commit(n);
    done += n;
    s.fir.run(s.queue);
  }
  return s.queue.written();
}

std::size_t RationalResampler::max_output_frames(std::size_t input_frames) const {
  // New input spans input_frames * up ticks; outputs fall every `down` ticks.
  const std::size_t up = impl_->fir.up();
  const std::size_t down = impl_->fir.down();
  return impl_->queue.pending() + (input_frames * up + down - 1) / down;
}

std::int64_t RationalResampler::next_output_index() const {
  return impl_->fir.next_output() - static_cast<std::int64_t>(impl_->queue.pending());
}
double RationalResampler::passband_edge_hz() const { return impl_->passband_hz; }
std::size_t RationalResampler::channels() const { return impl_->channels; }

// ---------------------------------------------------------------------------------------------------------
// NonuniformResampler
//
// Stage 1: band-limited interpolation onto a fine uniform grid at kFineFactor * out_rate. The samples are
// treated as uniform in their index (crank-angle clocking makes them uniform in angle): the fractional index
// u(t) of a grid instant comes from cubic interpolation of the index against the sample times, and the value
// from a Kaiser-windowed sinc in u (2 * kKernelHalfWidth taps from a table whose rows sum to 1, so DC is
// exact). This is band-limited to about kIndexPassband cycles per input sample, i.e. 0.41 * the local edge
// rate; when the edges are slower than the output the passband is therefore that, below the input's own
// Nyquist (passband_edge_hz() reports it from the edge rate of the latest call).
// Stage 2: the same zero-delay low-pass as the rational resampler (flat to 0.45 out_rate, >= 80 dB from
// 0.5 out_rate) decimating the fine grid by kFineFactor. Input content between the output Nyquist and half
// the edge rate is removed here; it stays out of the passband for edge rates up to about
// 2 * (kFineFactor - 0.5) * out_rate (600 kHz at a 40 kHz output).
// Before the first input the signal is held at the first sample's value (no step for a signal on a mean).

namespace {
constexpr std::int64_t kFineFactor = 8;
constexpr std::size_t kKernelHalfWidth = 16;  // taps each side of the interpolation instant
constexpr std::size_t kKernelPhases = 1024;   // kernel table resolution (linear interpolation between rows)
constexpr double kKernelAttenuationDb = 90.0;
// Transition of the windowed sinc is centred on 0.5 cycles/sample with width (A - 8) / (2.285 * 2 pi * 2W);
// the passband ends half a width below (0.41 for W = 16, A = 90 dB; the tests measure it).
constexpr double kIndexPassband =
    0.5 - 0.5 * (kKernelAttenuationDb - 8.0) / (2.285 * 2.0 * 3.141592653589793 * 2.0 * kKernelHalfWidth);
}  // namespace

struct NonuniformResampler::Impl {
  static PolyphaseFir make_decimator(double out_hz, std::size_t ch) {
    const double fine_hz = static_cast<double>(kFineFactor) * out_hz;
    return PolyphaseFir(design_lowpass(fine_hz, out_hz), 1, static_cast<std::size_t>(kFineFactor), ch);
  }

  Impl(double out_hz, std::size_t ch)
      : channels(ch),
        out_rate(out_hz),
        fine_rate(static_cast<double>(kFineFactor) * out_hz),
        table((kKernelPhases + 1) * 2 * kKernelHalfWidth),
        weights(2 * kKernelHalfWidth),
        stride(2 * kKernelHalfWidth + kChunkFrames),
        times(stride),
        values(ch * stride),
        first_values(ch),
        decimator(make_decimator(out_hz, ch)),
        queue(ch, kPendingFrames) {
    // Row r, tap k: kernel at offset r / R + W - 1 - k (tap k is sample cursor - W + 1 + k).
    const double beta = fir::kaiser_beta(kKernelAttenuationDb);
    const auto w = static_cast<double>(kKernelHalfWidth);
    for (std::size_t r = 0; r <= kKernelPhases; ++r) {
      for (std::size_t k = 0; k < 2 * kKernelHalfWidth; ++k) {
        const double d = static_cast<double>(r) / kKernelPhases + w - 1.0 - static_cast<double>(k);
        table[r * 2 * kKernelHalfWidth + k] = fir::sinc(d) * fir::kaiser_window(d / w, beta);
      }
      // Rows sum to 1, so do blends of neighbouring rows: DC passes exactly (pressure rides on a large mean).
      double* row = &table[r * 2 * kKernelHalfWidth];
      const double sum = std::accumulate(row, row + 2 * kKernelHalfWidth, 0.0);
      for (std::size_t k = 0; k < 2 * kKernelHalfWidth; ++k) row[k] /= sum;
    }
  }

  // First input: output starts at the first grid instant at or after it; earlier samples hold its value.
  void start(const double* x0, double t0) {
    t_first = t0;
    auto k0 = static_cast<std::int64_t>(std::ceil(t0 * out_rate));
    while (static_cast<double>(k0 - 1) / out_rate >= t0) --k0;
    while (static_cast<double>(k0) / out_rate < t0) ++k0;
    next_fine = decimator.start(k0);
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

  // Fills the fine grid as far as the input allows and runs the decimator.
  void produce() {
    const std::int64_t last = seen - 1;
    const auto w = static_cast<std::int64_t>(kKernelHalfWidth);
    const std::size_t n_taps = 2 * kKernelHalfWidth;
    std::size_t made = 0;
    for (;;) {
      if (made == decimator.room()) {
        decimator.commit(made);
        decimator.run(queue);
        made = 0;
      }
      const double tau = static_cast<double>(next_fine) / fine_rate;
      if (tau < t_first) {
        for (std::size_t c = 0; c < channels; ++c) decimator.channel_tail(c)[made] = first_values[c];
      } else {
        while (cursor < last && time_at(cursor + 1) <= tau) ++cursor;
        if (cursor + w > last) break;
        const double frac = std::clamp(fractional_index(tau) - static_cast<double>(cursor), 0.0, 1.0);
        const double pos = frac * kKernelPhases;
        const auto row = std::min(static_cast<std::size_t>(pos), kKernelPhases - 1);
        const double a = pos - static_cast<double>(row);
        const double* r0 = &table[row * n_taps];
        const double* r1 = r0 + n_taps;
        for (std::size_t k = 0; k < n_taps; ++k) weights[k] = r0[k] + a * (r1[k] - r0[k]);
        const auto offset = static_cast<std::size_t>(cursor - w + 1 - base);
        for (std::size_t c = 0; c < channels; ++c)
          decimator.channel_tail(c)[made] = dot(weights.data(), &values[c * stride + offset], n_taps);
      }
      ++made;
      ++next_fine;
    }
    decimator.commit(made);
    decimator.run(queue);
    // Keep the samples the next grid instant can reach.
    const std::int64_t keep_from = cursor - w + 1;
    const auto drop = static_cast<std::size_t>(keep_from - base);
    if (drop > 0) {
      const std::size_t kept = len - drop;
      std::memmove(times.data(), times.data() + drop, kept * sizeof(double));
      for (std::size_t c = 0; c < channels; ++c) {
        double* v = &values[c * stride];
        std::memmove(v, v + drop, kept * sizeof(double));
      }
      len = kept;
      base = keep_from;
    }
  }

  std::size_t channels;
  double out_rate;
  double fine_rate;
  std::vector<double> table;    // windowed-sinc kernel, (kKernelPhases + 1) rows of 2W taps
  std::vector<double> weights;  // scratch, 2W
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
  PolyphaseFir decimator;
  OutputQueue queue;
};

NonuniformResampler::NonuniformResampler(double out_rate_hz, std::size_t channels) {
  require_channels(channels, "NonuniformResampler");
  if (!(out_rate_hz > 0.0) || !std::isfinite(out_rate_hz))
    throw std::invalid_argument("NonuniformResampler: output rate must be positive");
  impl_ = std::make_unique<Impl>(out_rate_hz, channels);
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
  return impl_->decimator.next_output() - static_cast<std::int64_t>(impl_->queue.pending());
}

double crank_angle_passband_hz(double edge_rate_hz) { return kIndexPassband * edge_rate_hz; }

double converter_passband_hz(double rate_hz) { return kPassbandFraction * rate_hz; }

double NonuniformResampler::passband_edge_hz() const {
  const double out_limit = converter_passband_hz(impl_->out_rate);
  if (impl_->edge_rate_hz <= 0.0) return out_limit;
  return std::min(out_limit, crank_angle_passband_hz(impl_->edge_rate_hz));
}

std::size_t NonuniformResampler::channels() const { return impl_->channels; }

}  // namespace noisemon::dsp
