// [alsa]: the microphones on an audio interface (drivers/alsa/alsa_source.hpp), used with [daemon] microphones =
// "alsa".
#include <string>

#include "daemon/config_reader.hpp"

namespace noisemon::daemon::config_detail {
namespace {

void read_channel_list(TableReader& r, std::vector<unsigned>& channels) {
  const toml::node* n = r.node("channels");
  if (!n) return;
  const toml::array* a = n->as_array();
  if (!a || a->empty() || a->size() > drivers::SampleBlock::kMaxChannels)
    r.fail("channels", "expected an array of 1.." + std::to_string(drivers::SampleBlock::kMaxChannels) +
                           " capture channels (0-based), one per microphone");
  channels.clear();
  for (const toml::node& ch : *a) {
    const std::optional<std::int64_t> v = ch.value<std::int64_t>();
    if (!ch.is_integer() || *v < 0 || *v >= drivers::alsa::kMaxCaptureChannels)
      r.fail("channels",
             "each channel must be an integer in [0, " + std::to_string(drivers::alsa::kMaxCaptureChannels - 1) + "]");
    channels.push_back(static_cast<unsigned>(*v));
  }
}

void read_capture(TableReader& r, const std::string& origin, drivers::alsa::CaptureConfig& c) {
  r.string("pcm", c.pcm);
  std::string file;
  r.string("config_file", file);
  if (!file.empty()) c.config_file = beside_config(origin, file);
  std::int64_t rate = c.rate_hz, capture_channels = c.channels, period = c.period_frames, periods = c.periods;
  r.integer("rate_hz", rate, drivers::alsa::kMinRateHz, drivers::alsa::kMaxRateHz);
  r.integer("capture_channels", capture_channels, 0, drivers::alsa::kMaxCaptureChannels);
  r.integer("period_frames", period, 16, 65536);
  r.integer("periods", periods, 2, 1024);
  c.rate_hz = static_cast<unsigned>(rate);
  c.channels = static_cast<unsigned>(capture_channels);
  c.period_frames = static_cast<unsigned>(period);
  c.periods = static_cast<unsigned>(periods);
  r.string("format", c.format);
  drivers::alsa::SampleFormat f;
  if (!c.format.empty() && !drivers::alsa::parse_format(c.format, f))
    r.fail("format", "unknown sample format '" + c.format + "' (expected S16_LE, S24_LE, S24_3LE, S32_LE or FLOAT_LE)");
}

}  // namespace

void read_alsa(TableReader& top, const std::string& origin, drivers::alsa::AlsaSourceConfig& a) {
  TableReader r(top.table("alsa"), "alsa", origin);
  read_capture(r, origin, a.capture);
  read_channel_list(r, a.channels);
  r.number("full_scale_v", a.full_scale_v, 1e-6, 1000);
  std::int64_t sync = a.sync_channel;
  r.integer("sync_channel", sync, -1, drivers::alsa::kMaxCaptureChannels - 1);
  a.sync_channel = static_cast<int>(sync);
  r.number("sync_angle_deg", a.sync_angle_deg, -720.0, 720.0);
  r.number("host_delay_uncertainty_s", a.host_delay_uncertainty_s, 0.0, 1.0);
  read_mic_chain(r, a.channels.size(), {a.sensitivity_mv_per_pa, a.radius_m, a.positions_m, a.speed_of_sound_m_s});
  r.reject_unknown();
}

}  // namespace noisemon::daemon::config_detail
