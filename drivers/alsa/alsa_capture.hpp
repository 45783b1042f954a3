// One ALSA capture PCM (an audio interface, an acoustics front-end with an ALSA driver, or a PCM an asoundrc
// defines), opened by name and read as interleaved frames of values in [-1, 1) (digital full scale).
//
// The PCM runs at the configured rate exactly (alsa-lib's own resampling is off: the converter's clock is the
// measurement's), in the configured sample format or the best the device offers. Reads never block for long:
// wait() returns after at most its timeout, so a driver thread can poll its stop request.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace noisemon::drivers::alsa {

// The sample formats read (alsa-lib names). S24_LE: 24 bits in the low three bytes of four; S24_3LE: three bytes.
enum class SampleFormat : std::uint8_t { kS16, kS24, kS24Packed, kS32, kFloat };
inline constexpr std::string_view kSampleFormatNames[] = {"S16_LE", "S24_LE", "S24_3LE", "S32_LE", "FLOAT_LE"};
std::string_view format_name(SampleFormat f);
// The format of an alsa-lib name; false when it is none of the above.
bool parse_format(std::string_view name, SampleFormat& out);
// Bytes of one sample of a format.
unsigned sample_bytes(SampleFormat f);
// Converts `samples` samples of raw little-endian data to values in [-1, 1).
void decode_samples(SampleFormat f, const std::uint8_t* raw, std::size_t samples, double* out);

struct CaptureConfig {
  std::string pcm = "default";  // hw:CARD=X,DEV=0, plughw:1, a name an asoundrc defines
  std::string config_file;      // an asoundrc whose definitions are added to the system's (empty: none)
  unsigned rate_hz = 48000;
  unsigned channels = 0;           // at least 1
  bool at_least_channels = false;  // take the fewest channels of `channels` or more the device offers
  std::string format;  // an alsa-lib name of kSampleFormatNames; empty: the first of S32_LE, S24_3LE, S24_LE,
                       // FLOAT_LE, S16_LE the device offers
  unsigned period_frames = 1024;  // frames per read
  unsigned periods = 8;           // the buffer holds this many periods
};

// The outcome of one read.
enum class ReadStatus : std::uint8_t { kFrames, kNothingYet, kOverrun };

class Capture {
 public:
  // Opens and configures the PCM. Throws std::runtime_error naming the PCM (and the config file) when it is
  // missing, busy, or cannot do the rate, channels or format asked for (saying what it can do).
  explicit Capture(const CaptureConfig& config);
  ~Capture();
  Capture(const Capture&) = delete;
  Capture& operator=(const Capture&) = delete;

  SampleFormat format() const { return format_; }
  unsigned channels() const { return channels_; }
  unsigned period_frames() const { return period_frames_; }
  unsigned buffer_frames() const { return buffer_frames_; }
  const std::string& name() const { return name_; }

  // Starts (again, after an overrun) capturing; returns the host time (wall clock, us) of the start.
  std::int64_t start();
  // Waits up to timeout_ms for a period of frames to be ready.
  void wait(int timeout_ms);
  // Reads up to one period into `values` (frames * channels, interleaved, in [-1, 1)). kOverrun: the device's
  // buffer overflowed (frames were lost) and capture has stopped until start(). Throws std::runtime_error naming
  // the PCM when the device has gone (unplugged) or fails otherwise.
  ReadStatus read(std::vector<double>& values, std::size_t& frames);

 private:
  struct Handle;
  std::unique_ptr<Handle> pcm_;
  std::string name_;
  unsigned channels_ = 0;
  SampleFormat format_ = SampleFormat::kS32;
  unsigned period_frames_ = 0, buffer_frames_ = 0;
  std::vector<std::uint8_t> raw_;
};

}  // namespace noisemon::drivers::alsa
