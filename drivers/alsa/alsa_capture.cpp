#include "drivers/alsa/alsa_capture.hpp"

#include <alsa/asoundlib.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "drivers/source.hpp"

namespace noisemon::drivers::alsa {
namespace {

constexpr std::array<snd_pcm_format_t, 5> kAlsaFormats = {SND_PCM_FORMAT_S16_LE, SND_PCM_FORMAT_S24_LE,
                                                          SND_PCM_FORMAT_S24_3LE, SND_PCM_FORMAT_S32_LE,
                                                          SND_PCM_FORMAT_FLOAT_LE};
// The automatic choice: the widest integer format first (what interfaces convert natively), float, then 16 bits.
constexpr std::array<SampleFormat, 5> kPreference = {SampleFormat::kS32, SampleFormat::kS24Packed, SampleFormat::kS24,
                                                     SampleFormat::kFloat, SampleFormat::kS16};

snd_pcm_format_t alsa_format(SampleFormat f) { return kAlsaFormats[static_cast<std::size_t>(f)]; }

std::string errtext(int err) { return snd_strerror(err); }

// The system's configuration with config_file's definitions added (alsa-lib reads ~/.asoundrc the same way).
snd_config_t* local_config(const std::string& config_file) {
  snd_config_t* top = nullptr;
  if (int err = snd_config_update_ref(&top); err < 0)
    throw std::runtime_error("alsa: cannot read the system's ALSA configuration (" + errtext(err) + ")");
  snd_config_t* local = nullptr;
  const int copied = snd_config_copy(&local, top);
  snd_config_unref(top);
  if (copied < 0) throw std::runtime_error("alsa: cannot copy the ALSA configuration (" + errtext(copied) + ")");
  snd_input_t* in = nullptr;
  if (int err = snd_input_stdio_open(&in, config_file.c_str(), "r"); err < 0) {
    snd_config_delete(local);
    throw std::runtime_error("alsa: cannot read the ALSA configuration file " + config_file + " (" + errtext(err) +
                             ")");
  }
  const int loaded = snd_config_load(local, in);
  snd_input_close(in);
  if (loaded < 0) {
    snd_config_delete(local);
    throw std::runtime_error("alsa: " + config_file + " is not an ALSA configuration (" + errtext(loaded) + ")");
  }
  return local;
}

std::string open_error(const CaptureConfig& c, int err) {
  std::string what = "alsa: cannot open capture PCM '" + c.pcm + "'";
  if (!c.config_file.empty()) what += " (with " + c.config_file + ")";
  what += ": " + errtext(err);
  if (err == -EBUSY) what += " (another program is capturing from it; `fuser -v /dev/snd/*` shows which)";
  if (err == -ENOENT || err == -ENODEV)
    what += " (no such device or PCM name; `arecord -L` lists the names, `arecord -l` the cards)";
  return what;
}

}  // namespace

std::string_view format_name(SampleFormat f) { return kSampleFormatNames[static_cast<std::size_t>(f)]; }

bool parse_format(std::string_view name, SampleFormat& out) {
  for (std::size_t i = 0; i < std::size(kSampleFormatNames); ++i)
    if (name == kSampleFormatNames[i]) {
      out = static_cast<SampleFormat>(i);
      return true;
    }
  return false;
}

unsigned sample_bytes(SampleFormat f) {
  switch (f) {
    case SampleFormat::kS16:
      return 2;
    case SampleFormat::kS24Packed:
      return 3;
    default:
      return 4;
  }
}

void decode_samples(SampleFormat f, const std::uint8_t* raw, std::size_t samples, double* out) {
  const unsigned width = sample_bytes(f);
  for (std::size_t i = 0; i < samples; ++i, raw += width) {
    const std::uint32_t b = raw[0] | (raw[1] << 8) | (width > 2 ? raw[2] << 16 : 0u) |
                            (width > 3 ? static_cast<std::uint32_t>(raw[3]) << 24 : 0u);
    switch (f) {
      case SampleFormat::kS16:
        out[i] = static_cast<std::int16_t>(b) / 32768.0;
        break;
      case SampleFormat::kS24:
      case SampleFormat::kS24Packed:
        out[i] = static_cast<std::int32_t>((b & 0xFFFFFFu) << 8) / 2147483648.0;  // sign from bit 23
        break;
      case SampleFormat::kS32:
        out[i] = static_cast<std::int32_t>(b) / 2147483648.0;
        break;
      case SampleFormat::kFloat: {
        float v;
        std::memcpy(&v, &b, sizeof v);
        out[i] = v;
        break;
      }
    }
  }
}

struct Capture::Handle {
  snd_pcm_t* pcm = nullptr;
  snd_config_t* config = nullptr;  // the local configuration the PCM was opened with (kept while it is open)
  ~Handle() {
    if (pcm) snd_pcm_close(pcm);
    if (config) snd_config_delete(config);
  }
};

namespace {

struct HwParams {
  snd_pcm_hw_params_t* p = nullptr;
  HwParams() { snd_pcm_hw_params_malloc(&p); }
  ~HwParams() { snd_pcm_hw_params_free(p); }
};

SampleFormat choose_format(snd_pcm_t* pcm, snd_pcm_hw_params_t* hw, const CaptureConfig& c) {
  if (!c.format.empty()) {
    SampleFormat f;
    if (!parse_format(c.format, f)) throw std::invalid_argument("alsa: unknown sample format '" + c.format + "'");
    if (snd_pcm_hw_params_test_format(pcm, hw, alsa_format(f)) < 0)
      throw std::runtime_error("alsa: PCM '" + c.pcm + "' cannot capture " + c.format);
    return f;
  }
  for (SampleFormat f : kPreference)
    if (snd_pcm_hw_params_test_format(pcm, hw, alsa_format(f)) == 0) return f;
  throw std::runtime_error("alsa: PCM '" + c.pcm + "' offers none of S32_LE, S24_3LE, S24_LE, FLOAT_LE, S16_LE");
}

// Sets the channels (returns how many) and the rate; throws saying what the device offers when it cannot.
unsigned set_channels_and_rate(snd_pcm_t* pcm, snd_pcm_hw_params_t* hw, const CaptureConfig& c) {
  unsigned channels = c.channels;
  const bool set = c.at_least_channels ? snd_pcm_hw_params_set_channels_min(pcm, hw, &channels) >= 0 &&
                                             snd_pcm_hw_params_set_channels_first(pcm, hw, &channels) >= 0
                                       : snd_pcm_hw_params_set_channels(pcm, hw, c.channels) >= 0;
  if (!set) {
    unsigned lo = 0, hi = 0;
    snd_pcm_hw_params_get_channels_min(hw, &lo);
    snd_pcm_hw_params_get_channels_max(hw, &hi);
    throw std::runtime_error("alsa: PCM '" + c.pcm + "' cannot capture " + std::to_string(c.channels) +
                             (c.at_least_channels ? " or more" : "") + " channels (it offers " + std::to_string(lo) +
                             ".." + std::to_string(hi) + ")");
  }
  if (snd_pcm_hw_params_set_rate(pcm, hw, c.rate_hz, 0) < 0) {
    unsigned lo = 0, hi = 0;
    int lo_dir = 0, hi_dir = 0;  // an open end of the interval: the rate beside it is the last one offered
    snd_pcm_hw_params_get_rate_min(hw, &lo, &lo_dir);
    snd_pcm_hw_params_get_rate_max(hw, &hi, &hi_dir);
    lo += lo_dir > 0 ? 1 : 0;
    hi -= hi_dir < 0 ? 1 : 0;
    throw std::runtime_error("alsa: PCM '" + c.pcm + "' cannot run at " + std::to_string(c.rate_hz) +
                             " Hz without resampling (it offers " + std::to_string(lo) + ".." + std::to_string(hi) +
                             " Hz)");
  }
  return channels;
}

}  // namespace

Capture::Capture(const CaptureConfig& c) : pcm_(std::make_unique<Handle>()), name_(c.pcm), channels_(c.channels) {
  if (c.channels == 0) throw std::invalid_argument("alsa: no channels to capture");
  int err = 0;
  if (c.config_file.empty()) {
    err = snd_pcm_open(&pcm_->pcm, c.pcm.c_str(), SND_PCM_STREAM_CAPTURE, SND_PCM_NONBLOCK);
  } else {
    pcm_->config = local_config(c.config_file);
    err = snd_pcm_open_lconf(&pcm_->pcm, c.pcm.c_str(), SND_PCM_STREAM_CAPTURE, SND_PCM_NONBLOCK, pcm_->config);
  }
  if (err < 0) {
    pcm_->pcm = nullptr;
    throw std::runtime_error(open_error(c, err));
  }
  HwParams hw;
  snd_pcm_t* pcm = pcm_->pcm;
  if ((err = snd_pcm_hw_params_any(pcm, hw.p)) < 0)
    throw std::runtime_error("alsa: PCM '" + c.pcm + "' has no configuration (" + errtext(err) + ")");
  snd_pcm_hw_params_set_rate_resample(pcm, hw.p, 0);
  if (snd_pcm_hw_params_set_access(pcm, hw.p, SND_PCM_ACCESS_RW_INTERLEAVED) < 0)
    throw std::runtime_error("alsa: PCM '" + c.pcm + "' cannot be read interleaved (try plughw: instead of hw:)");
  format_ = choose_format(pcm, hw.p, c);
  snd_pcm_hw_params_set_format(pcm, hw.p, alsa_format(format_));
  channels_ = set_channels_and_rate(pcm, hw.p, c);
  snd_pcm_uframes_t period = c.period_frames;
  int dir = 0;
  snd_pcm_hw_params_set_period_size_near(pcm, hw.p, &period, &dir);
  snd_pcm_uframes_t buffer = period * std::max(2u, c.periods);
  snd_pcm_hw_params_set_buffer_size_near(pcm, hw.p, &buffer);
  if ((err = snd_pcm_hw_params(pcm, hw.p)) < 0)
    throw std::runtime_error("alsa: PCM '" + c.pcm + "' refused its settings (" + errtext(err) + ")");
  snd_pcm_hw_params_get_period_size(hw.p, &period, &dir);
  snd_pcm_hw_params_get_buffer_size(hw.p, &buffer);
  period_frames_ = static_cast<unsigned>(period);
  buffer_frames_ = static_cast<unsigned>(buffer);
  raw_.resize(static_cast<std::size_t>(period_frames_) * channels_ * sample_bytes(format_));
}

Capture::~Capture() = default;

std::int64_t Capture::start() {
  snd_pcm_t* pcm = pcm_->pcm;
  snd_pcm_drop(pcm);
  if (int err = snd_pcm_prepare(pcm); err < 0)
    throw std::runtime_error("alsa: PCM '" + name_ + "' cannot be prepared (" + errtext(err) + ")");
  if (int err = snd_pcm_start(pcm); err < 0)
    throw std::runtime_error("alsa: PCM '" + name_ + "' cannot start (" + errtext(err) + ")");
  return wall_utime();
}

void Capture::wait(int timeout_ms) { snd_pcm_wait(pcm_->pcm, timeout_ms); }

ReadStatus Capture::read(std::vector<double>& values, std::size_t& frames) {
  frames = 0;
  snd_pcm_sframes_t n = snd_pcm_readi(pcm_->pcm, raw_.data(), period_frames_);
  if (n == -ESTRPIPE) {  // suspended (the machine slept): resume, else start again
    while ((n = snd_pcm_resume(pcm_->pcm)) == -EAGAIN) snd_pcm_wait(pcm_->pcm, 10);
    return ReadStatus::kOverrun;
  }
  if (n == -EAGAIN || n == 0) return ReadStatus::kNothingYet;
  if (n == -EPIPE) return ReadStatus::kOverrun;
  if (n < 0)
    throw std::runtime_error("alsa: reading PCM '" + name_ + "' failed: " + errtext(static_cast<int>(n)) +
                             (n == -ENODEV ? " (the interface was unplugged)" : ""));
  frames = static_cast<std::size_t>(n);
  values.resize(frames * channels_);
  decode_samples(format_, raw_.data(), frames * channels_, values.data());
  return ReadStatus::kFrames;
}

}  // namespace noisemon::drivers::alsa
