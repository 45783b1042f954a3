// [comedi] of the configuration: the DAQ cards of the pressure, the encoder and the microphones.
#include <comedilib.h>

#include <cmath>
#include <string>

#include "daemon/config_reader.hpp"
#include "drivers/comedi/comedi_rest.hpp"

namespace noisemon::daemon::config_detail {
namespace {

// ---- [comedi] -----------------------------------------------------------------------------------------------

unsigned read_aref(TableReader& r, const char* key, const std::string& value) {
  return pick<unsigned>(r, key, value,
                        {{"ground", AREF_GROUND}, {"common", AREF_COMMON}, {"diff", AREF_DIFF}, {"other", AREF_OTHER}});
}

void read_aref_key(TableReader& r, const char* key, unsigned& out) {
  if (!r.node(key)) return;
  std::string name;
  r.string(key, name);
  out = read_aref(r, key, name);
}

void read_convert(TableReader& r, unsigned& out) {
  if (!r.node("convert")) return;
  std::string name;
  r.string("convert", name);
  out = pick<unsigned>(r, "convert", name, {{"timer", TRIG_TIMER}, {"now", TRIG_NOW}, {"follow", TRIG_FOLLOW}});
}

void read_unsigned(TableReader& r, const char* key, unsigned& out, std::int64_t max = 65535) {
  std::int64_t v = out;
  r.integer(key, v, 0, max);
  out = static_cast<unsigned>(v);
}

void read_int(TableReader& r, const char* key, int& out, std::int64_t min, std::int64_t max) {
  std::int64_t v = out;
  r.integer(key, v, min, max);
  out = static_cast<int>(v);
}

// buffer_bytes and wake_every_scan, the kernel buffer and wake-up of one acquisition ([comedi.pressure],
// [comedi.encoder], [comedi.mics]). 0 bytes leaves the driver's buffer; at most 1 GiB.
void read_kernel_buffer(TableReader& r, unsigned& buffer_bytes, bool& wake_every_scan) {
  read_unsigned(r, "buffer_bytes", buffer_bytes, std::int64_t{1} << 30);
  r.boolean("wake_every_scan", wake_every_scan);
}

// [comedi.pressure]: the pressure (and cam) channel.
void read_comedi_pressure(TableReader& r, const std::string& origin, drivers::comedi::ComediSourceConfig::Pressure& p) {
  TableReader pr(r.table("pressure"), "comedi.pressure", origin);
  pr.string("device", p.device);
  read_int(pr, "subdevice", p.subdevice, -1, 255);
  read_unsigned(pr, "edge_trigger", p.edge_trigger, 1 << 30);
  read_int(pr, "start_trigger", p.start_trigger, -1, 1 << 30);
  read_convert(pr, p.convert_src);
  read_unsigned(pr, "channel", p.channel.channel);
  read_unsigned(pr, "range", p.channel.range, 255);
  read_aref_key(pr, "aref", p.channel.aref);
  pr.number("sensitivity_mv_per_bar", p.sensitivity_mv_per_bar, 0, 1e6);
  pr.number("sensitivity_pc_per_bar", p.sensitivity_pc_per_bar, 0, 1e6);
  pr.number("amplifier_mv_per_pc", p.amplifier_mv_per_pc, 0, 1e6);
  pr.number("offset_bar", p.offset_bar, -100, 100);
  pr.number("peg_pa", p.peg_pa, 0, 1e8);
  pr.number("peg_angle_deg", p.peg_angle_deg, -360, 360);
  read_int(pr, "cam_channel", p.cam_channel, -1, 65535);
  read_unsigned(pr, "cam_range", p.cam_range, 255);
  read_aref_key(pr, "cam_aref", p.cam_aref);
  read_kernel_buffer(pr, p.buffer_bytes, p.wake_every_scan);
  pr.number("rest_scan_rate_hz", p.rest_scan_rate_hz, drivers::comedi::kMinRestScanRateHz,
            drivers::comedi::kMaxRestScanRateHz);
  if (p.rest_scan_rate_hz != std::round(p.rest_scan_rate_hz))
    pr.fail("rest_scan_rate_hz", "a whole number of Hz (the card's timer; it is resampled to 40 kHz)");
  pr.reject_unknown();
}

// [comedi.encoder]: the crank encoder's counters.
void read_comedi_encoder(TableReader& r, const std::string& origin, drivers::comedi::ComediSourceConfig::Encoder& e) {
  TableReader er(r.table("encoder"), "comedi.encoder", origin);
  er.string("device", e.device);
  read_int(er, "subdevice", e.subdevice, -1, 255);
  read_unsigned(er, "edge_trigger", e.edge_trigger, 1 << 30);
  read_int(er, "start_trigger", e.start_trigger, -1, 1 << 30);
  read_convert(er, e.convert_src);
  read_unsigned(er, "position_channel", e.position_channel);
  read_int(er, "position_counter_mode", e.position_counter_mode, -1, INT32_MAX);
  read_int(er, "timestamp_subdevice", e.timestamp_subdevice, -1, 255);
  read_unsigned(er, "timestamp_channel", e.timestamp_channel);
  read_int(er, "timestamp_counter_mode", e.timestamp_counter_mode, -1, INT32_MAX);
  if (er.node("timestamp_mode")) {
    std::string mode;
    er.string("timestamp_mode", mode);
    e.timestamp_mode = pick<drivers::comedi::TimestampMode>(
        er, "timestamp_mode", mode,
        {{"absolute", drivers::comedi::TimestampMode::kAbsolute}, {"period", drivers::comedi::TimestampMode::kPeriod}});
  }
  er.number("timebase_hz", e.timebase_hz, 1, 1e10);
  std::int64_t bits = e.timestamp_bits, cpr = e.counts_per_rev;
  er.integer("timestamp_bits", bits, 8, 32);
  er.integer("counts_per_rev", cpr, 4, 1 << 24);
  e.timestamp_bits = static_cast<std::uint32_t>(bits);
  e.counts_per_rev = static_cast<std::uint32_t>(cpr);
  er.number("index_angle_deg", e.index_angle_deg, -360, 360);
  er.boolean("index_resets_counter", e.index_resets_counter);
  std::int64_t per_edge = e.counts_per_edge;
  er.integer("counts_per_edge", per_edge, 1, 64);
  e.counts_per_edge = static_cast<std::uint32_t>(per_edge);
  er.number("max_rpm", e.max_rpm, 0, 100000);
  read_kernel_buffer(er, e.buffer_bytes, e.wake_every_scan);
  er.reject_unknown();
}

// comedi.mics.channels, and the per-channel range and aref (one value for all or one per channel).
void read_mic_channels(TableReader& mr, drivers::comedi::ComediSourceConfig::Mics& m) {
  if (const toml::node* n = mr.node("channels")) {
    const toml::array* a = n->as_array();
    if (!a || a->empty() || a->size() > drivers::SampleBlock::kMaxChannels)
      mr.fail("channels",
              "expected an array of 1.." + std::to_string(drivers::SampleBlock::kMaxChannels) + " channel numbers");
    m.channels.clear();
    for (const toml::node& ch : *a) {
      if (!ch.is_integer() || *ch.value<std::int64_t>() < 0 || *ch.value<std::int64_t>() > 65535)
        mr.fail("channels", "each channel must be an integer in [0, 65535]");
      m.channels.push_back({.channel = static_cast<unsigned>(*ch.value<std::int64_t>())});
    }
  }
  const std::size_t n = m.channels.size();
  const auto ranges = per_channel<unsigned>(mr, "range", n, 0u, [&](const toml::node& v, const char* key) {
    if (!v.is_integer() || *v.value<std::int64_t>() < 0 || *v.value<std::int64_t>() > 255)
      mr.fail(key, "expected integers in [0, 255]");
    return static_cast<unsigned>(*v.value<std::int64_t>());
  });
  const auto arefs = per_channel<unsigned>(mr, "aref", n, static_cast<unsigned>(AREF_GROUND),
                                           [&](const toml::node& v, const char* key) {
                                             if (!v.is_string())
                                               mr.fail(key, "expected \"ground\", \"common\", \"diff\" or \"other\"");
                                             return read_aref(mr, key, *v.value<std::string>());
                                           });
  for (std::size_t i = 0; i < n; ++i) {
    m.channels[i].range = ranges[i];
    m.channels[i].aref = arefs[i];
  }
}

// [comedi.mics]: the microphone channels, their sensitivities and positions.
void read_comedi_mics(TableReader& r, const std::string& origin, drivers::comedi::ComediSourceConfig::Mics& m) {
  TableReader mr(r.table("mics"), "comedi.mics", origin);
  mr.string("device", m.device);
  read_int(mr, "subdevice", m.subdevice, -1, 255);
  mr.number("scan_rate_hz", m.scan_rate_hz, 8000, 1e7);
  read_mic_channels(mr, m);
  read_mic_chain(mr, m.channels.size(), {m.sensitivity_mv_per_pa, m.radius_m, m.positions_m, m.speed_of_sound_m_s});
  read_kernel_buffer(mr, m.buffer_bytes, m.wake_every_scan);
  mr.reject_unknown();
}

}  // namespace

void read_comedi(TableReader& top, const std::string& origin, drivers::comedi::ComediSourceConfig& c) {
  TableReader r(top.table("comedi"), "comedi", origin);
  if (r.node("phase")) {
    std::string phase;
    r.string("phase", phase);
    c.phase = pick<drivers::comedi::PhaseSource>(
        r, "phase", phase,
        {{"pressure", drivers::comedi::PhaseSource::kPressure}, {"cam", drivers::comedi::PhaseSource::kCam}});
  }
  r.number("cam_threshold_v", c.cam_threshold_v, -100, 100);
  r.number("cam_edge_deg", c.cam_edge_deg, -360, 360);
  double initial_ms = 1e-3 * static_cast<double>(c.initial_backoff.count());
  double max_ms = 1e-3 * static_cast<double>(c.max_backoff.count());
  r.number("backoff_initial_ms", initial_ms, 0.001, 60000);
  r.number("backoff_max_ms", max_ms, 0.001, 600000);
  if (max_ms < initial_ms) r.fail("backoff_max_ms", "must not be below backoff_initial_ms");
  c.initial_backoff = std::chrono::microseconds(std::llround(initial_ms * 1e3));
  c.max_backoff = std::chrono::microseconds(std::llround(max_ms * 1e3));
  read_unsigned(r, "max_consecutive_overruns", c.max_consecutive_overruns, 1000000);
  read_comedi_pressure(r, origin, c.pressure);
  read_comedi_encoder(r, origin, c.encoder);
  read_comedi_mics(r, origin, c.mics);
  r.reject_unknown();
}

}  // namespace noisemon::daemon::config_detail
