#include "daemon/report_messages.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace noisemon::daemon {

noisemon::cycle_report_t to_message(const CycleReport& r) {
  noisemon::cycle_report_t m;
  m.utime = r.utime;
  m.cycle = r.cycle;
  m.duration_s = r.duration_s;
  m.speed_rpm = r.op.speed_rpm;
  m.load_nm = r.op.load_nm;
  m.soi_deg_btdc = r.op.soi_deg_btdc;
  m.rail_pressure_bar = r.op.rail_pressure_bar;
  m.motored = r.op.motored;
  m.lpa_measured_db = r.lpa_measured_db;
  m.lpa_predicted_db = r.lpa_predicted_db;
  m.lwa_measured_db = r.lwa_measured_db;
  m.lwa_predicted_db = r.lwa_predicted_db;
  m.radius_m = r.radius_m;
  m.nbands = static_cast<std::int16_t>(r.nbands);
  m.band_hz.assign(r.band_hz, r.band_hz + r.nbands);
  m.spl_a_measured_db.assign(r.spl_a_measured_db, r.spl_a_measured_db + r.nbands);
  m.spl_a_predicted_db.assign(r.spl_a_predicted_db, r.spl_a_predicted_db + r.nbands);
  m.cpl_db.assign(r.cpl_db, r.cpl_db + r.nbands);
  m.att_measured_db.assign(r.att_measured_db, r.att_measured_db + r.nbands);
  m.att_predicted_db.assign(r.att_predicted_db, r.att_predicted_db + r.nbands);
  m.band_flags.assign(r.band_flags, r.band_flags + r.nbands);
  m.nmics = static_cast<std::int16_t>(r.nmics);
  m.mic_lpa_db.assign(r.mic_lpa_db, r.mic_lpa_db + r.nmics);
  m.flags = r.flags;
  m.processing_ms = r.processing_ms;
  return m;
}

noisemon::operating_point_t to_message(const drivers::OperatingPoint& op) {
  noisemon::operating_point_t m;
  m.utime = op.utime;
  m.speed_rpm = op.speed_rpm;
  m.load_nm = op.load_nm;
  m.soi_deg_btdc = op.soi_deg_btdc;
  m.rail_pressure_bar = op.rail_pressure_bar;
  m.motored = op.motored;
  return m;
}

noisemon::raw_block_t to_message(const drivers::SampleBlock& b, std::int8_t stream, std::int64_t epoch_utime) {
  noisemon::raw_block_t m;
  m.epoch_utime = epoch_utime;
  m.first_index = b.first_index;
  m.utime = epoch_utime + static_cast<std::int64_t>(std::llround(static_cast<double>(b.first_index) * 1e6 / drivers::kPipelineRateHz));
  m.stream = stream;
  m.sample_rate_hz = drivers::kPipelineRateHz;
  m.channels = static_cast<std::int16_t>(b.channels);
  m.frames = static_cast<std::int16_t>(b.frames);
  m.data.resize(b.frames);
  for (std::uint32_t f = 0; f < b.frames; ++f) m.data[f].assign(b.data + f * b.channels, b.data + (f + 1) * b.channels);
  return m;
}

noisemon::session_t to_message(const drivers::StreamInfo& info, const std::string& source, std::int64_t utime) {
  noisemon::session_t m;
  m.utime = utime;
  m.epoch_utime = info.epoch_utime;
  m.source = source;
  m.sample_rate_hz = drivers::kPipelineRateHz;
  m.radius_m = info.radius_m;
  m.acoustic_delay_s = info.acoustic_delay_s;
  m.nmics = static_cast<std::int16_t>(info.mic_count);
  m.mic_positions_m.assign(info.mic_count, std::vector<double>(3, 0.0));
  for (std::size_t i = 0; i < info.mic_count; ++i) {
    const auto& p = i < info.mic_positions_m.size() ? info.mic_positions_m[i] : std::array<double, 3>{};
    for (int j = 0; j < 3; ++j) m.mic_positions_m[i][j] = p[j];
  }
  return m;
}

drivers::StreamInfo from_message(const noisemon::session_t& m) {
  if (m.sample_rate_hz != drivers::kPipelineRateHz)
    throw std::invalid_argument("session sample rate " + std::to_string(m.sample_rate_hz) + " Hz, expected 40000");
  if (m.nmics < 1 || m.nmics > static_cast<int>(drivers::SampleBlock::kMaxChannels))
    throw std::invalid_argument("session with " + std::to_string(m.nmics) + " microphones");
  drivers::StreamInfo info;
  info.epoch_utime = m.epoch_utime;
  info.mic_count = static_cast<std::uint32_t>(m.nmics);
  info.radius_m = m.radius_m;
  info.acoustic_delay_s = m.acoustic_delay_s;
  for (const auto& p : m.mic_positions_m) info.mic_positions_m.push_back({p[0], p[1], p[2]});
  return info;
}

drivers::SampleBlock from_message(const noisemon::raw_block_t& m) {
  if (m.sample_rate_hz != drivers::kPipelineRateHz)
    throw std::invalid_argument("raw block at " + std::to_string(m.sample_rate_hz) + " Hz, expected 40000");
  if (m.channels < 1 || m.channels > static_cast<int>(drivers::SampleBlock::kMaxChannels) || m.frames < 0 ||
      m.frames > static_cast<int>(drivers::SampleBlock::kMaxFrames))
    throw std::invalid_argument("raw block of " + std::to_string(m.frames) + " frames x " + std::to_string(m.channels) +
                                " channels (at most 256 x 16)");
  drivers::SampleBlock b;
  b.first_index = m.first_index;
  b.frames = static_cast<std::uint32_t>(m.frames);
  b.channels = static_cast<std::uint32_t>(m.channels);
  for (std::uint32_t f = 0; f < b.frames; ++f)
    for (std::uint32_t c = 0; c < b.channels; ++c) b.data[f * b.channels + c] = m.data[f][c];
  return b;
}

drivers::OperatingPoint from_message(const noisemon::operating_point_t& m) {
  drivers::OperatingPoint op;
  op.utime = m.utime;
  op.speed_rpm = m.speed_rpm;
  op.load_nm = m.load_nm;
  op.soi_deg_btdc = m.soi_deg_btdc;
  op.rail_pressure_bar = m.rail_pressure_bar;
  op.motored = m.motored;
  return op;
}

std::string cycle_csv_header() {
  return "cycle,utime,speed_rpm,load_nm,soi_deg_btdc,motored,lpa_measured_db,lpa_predicted_db,lwa_measured_db,"
         "lwa_predicted_db,flags\n";
}

std::string cycle_csv_row(const noisemon::cycle_report_t& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf, "%lld,%lld,%.3f,%.3f,%.3f,%d,%.4f,%.4f,%.4f,%.4f,%d\n", static_cast<long long>(r.cycle),
                static_cast<long long>(r.utime), r.speed_rpm, r.load_nm, r.soi_deg_btdc, r.motored ? 1 : 0,
                r.lpa_measured_db, r.lpa_predicted_db, r.lwa_measured_db, r.lwa_predicted_db, r.flags);
  return buf;
}

std::string cycle_flags_text(std::int32_t flags) {
  if (flags == 0) return "ok";
  std::string s;
  auto add = [&](std::int32_t bit, const char* name) {
    if (flags & bit) s += (s.empty() ? "" : ",") + std::string(name);
  };
  add(noisemon::cycle_report_t::CYCLE_SETTLING, "settling");
  add(noisemon::cycle_report_t::CYCLE_GAP, "gap");
  add(noisemon::cycle_report_t::CYCLE_NO_OPERATING_POINT, "no-op");
  add(noisemon::cycle_report_t::CYCLE_LENGTH_ODD, "odd-length");
  return s;
}

std::string cycle_line_header() {
  return "   cycle   speed     SOI   Lp(A) meas   pred    LW(A) meas   pred    pred-meas  flags\n"
         "           rpm   degBTDC      dB(A)  dB(A)         dB(A)  dB(A)           dB";
}

std::string cycle_line(const noisemon::cycle_report_t& r) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%8lld %7.1f %7.1f %12.2f %6.2f %13.2f %6.2f %12.2f  %s", static_cast<long long>(r.cycle),
                r.speed_rpm, r.soi_deg_btdc, r.lpa_measured_db, r.lpa_predicted_db, r.lwa_measured_db, r.lwa_predicted_db,
                r.lpa_predicted_db - r.lpa_measured_db, cycle_flags_text(r.flags).c_str());
  return buf;
}

}  // namespace noisemon::daemon
