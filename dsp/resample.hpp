// Band-limited resampling onto a uniform grid.
//
// Both resamplers are streaming and time-exact: output frame k of a resampler is the signal's value at
// t = k / out_rate_hz on the caller's clock (the filter delay is compensated inside), so two streams
// resampled onto the same grid stay aligned by index. Outputs are emitted only once the input needed to
// compute them has arrived. The measured error on analytic signals is documented in the test file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

namespace noisemon::dsp {

// Output frames (40 kHz) dropped after a resampler starts from silence, either kind: its filter's warm-up (10 ms,
// longer than both kernels reach).
inline constexpr std::int64_t kResamplerSettleFrames = 400;

// The arithmetic of a resampler's filter. kSingle suits samples that are single precision already (float WAVs,
// ADC words: 24 bits hold them) at twice the speed; its rounding, ~1e-7 of the signal, is not a pure gain.
enum class SamplePrecision { kDouble, kSingle };

// Rational-rate polyphase FIR resampler, e.g. 51.2 kHz -> 40 kHz (up 25, down 32).
// Input frame 0 is at t = 0; output frame k at t = k / out_rate.
class RationalResampler {
 public:
  RationalResampler(double in_rate_hz, double out_rate_hz, std::size_t channels,
                    SamplePrecision precision = SamplePrecision::kDouble);
  ~RationalResampler();
  RationalResampler(RationalResampler&&) noexcept;
  RationalResampler& operator=(RationalResampler&&) noexcept;

  // in: frames * channels interleaved; out: room for max_out frames. Returns frames written.
  // Call with max_out >= max_output_frames(frames) to never leave produced output behind.
  std::size_t process(const double* in, std::size_t frames, double* out, std::size_t max_out);
  std::size_t max_output_frames(std::size_t input_frames) const;
  std::int64_t next_output_index() const;  // index of the next frame process() will emit
  double passband_edge_hz() const;         // response is flat (see tests) up to here
  std::size_t channels() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// What a signal sampled once per encoder edge keeps, at edge_rate_hz edges per second: the NonuniformResampler
// is flat up to this frequency (a fraction of the edge rate, below its Nyquist); above it the content is lost.
double crank_angle_passband_hz(double edge_rate_hz);

// The passband a converter sampling at rate_hz keeps (its anti-alias filter, as the RationalResampler's).
double converter_passband_hz(double rate_hz);

// Resampler for samples taken at uneven instants (crank-angle-clocked: one sample per encoder edge, with
// the edge time). Output frame k is the band-limited signal at t = k / out_rate_hz (t in seconds on the
// caller's clock; frame 0 is at t = 0, so times before the first input are never requested: output starts
// at the first grid instant at or after the first input time).
class NonuniformResampler {
 public:
  // max_edge_rate_hz: the highest edge rate the stream will reach (edges per revolution times the highest
  // speed). It sets the internal fine grid (4, 8, 16 ... times out_rate_hz): content up to half the edge rate
  // stays out of the band up to max_edge_rate_hz() (>= the value given; 280 kHz at 4 x 40 kHz, which covers a
  // 0.1 deg encoder to 4666 rpm). The default suits any encoder to 600 kHz, at twice the cost of a 4 x grid.
  static constexpr double kAnyEncoderEdgeRateHz = 600e3;
  NonuniformResampler(double out_rate_hz, std::size_t channels, double max_edge_rate_hz = kAnyEncoderEdgeRateHz);
  ~NonuniformResampler();
  NonuniformResampler(NonuniformResampler&&) noexcept;
  NonuniformResampler& operator=(NonuniformResampler&&) noexcept;

  // t: n strictly increasing sample times (s); x: n * channels interleaved values.
  // Writes at most max_out frames to out, returns frames written. The index of the first frame written is
  // next_output_index() after the call minus the count returned (before the first call the start is unknown).
  // Output that does not fit is kept (up to 8192 frames) and emitted by later calls, which may pass n = 0.
  std::size_t process(const double* t, const double* x, std::size_t n, double* out, std::size_t max_out);
  std::int64_t next_output_index() const;
  double passband_edge_hz() const;
  std::size_t channels() const;
  double max_edge_rate_hz() const;  // the edge rate up to which out-of-band content cannot fold into the band

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace noisemon::dsp
