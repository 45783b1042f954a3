#include "drivers/stream_messages.hpp"

#include <cmath>
#include <algorithm>
#include <stdexcept>

namespace noisemon::drivers {

noisemon::operating_point_t to_message(const OperatingPoint& op) {
  noisemon::operating_point_t m;
  m.utime = op.utime;
  m.speed_rpm = op.speed_rpm;
  m.load_nm = op.load_nm;
  m.soi_deg_btdc = op.soi_deg_btdc;
  m.rail_pressure_bar = op.rail_pressure_bar;
  m.motored = op.motored;
  return m;
}

noisemon::raw_block_t to_message(const SampleBlock& b, std::int8_t stream, std::int64_t epoch_utime) {
  noisemon::raw_block_t m;
  m.epoch_utime = epoch_utime;
  m.first_index = b.first_index;
  m.utime = epoch_utime + static_cast<std::int64_t>(std::llround(static_cast<double>(b.first_index) * 1e6 / kPipelineRateHz));
  m.stream = stream;
  m.sample_rate_hz = kPipelineRateHz;
  m.channels = static_cast<std::int16_t>(b.channels);
  m.frames = static_cast<std::int16_t>(b.frames);
  m.nsamples = static_cast<std::int32_t>(b.frames * b.channels);
  m.data.assign(b.data, b.data + m.nsamples);
  return m;
}

noisemon::session_t to_message(const StreamInfo& info, const std::string& source, std::int64_t utime) {
  noisemon::session_t m;
  m.utime = utime;
  m.epoch_utime = info.epoch_utime;
  m.source = source;
  m.sample_rate_hz = kPipelineRateHz;
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

StreamInfo from_message(const noisemon::session_t& m) {
  if (m.sample_rate_hz != kPipelineRateHz)
    throw std::invalid_argument("session sample rate " + std::to_string(m.sample_rate_hz) + " Hz, expected 40000");
  if (m.nmics < 1 || m.nmics > static_cast<int>(SampleBlock::kMaxChannels))
    throw std::invalid_argument("session with " + std::to_string(m.nmics) + " microphones");
  StreamInfo info;
  info.epoch_utime = m.epoch_utime;
  info.mic_count = static_cast<std::uint32_t>(m.nmics);
  info.radius_m = m.radius_m;
  info.acoustic_delay_s = m.acoustic_delay_s;
  for (const auto& p : m.mic_positions_m) info.mic_positions_m.push_back({p[0], p[1], p[2]});
  return info;
}

SampleBlock from_message(const noisemon::raw_block_t& m) {
  if (m.sample_rate_hz != kPipelineRateHz)
    throw std::invalid_argument("raw block at " + std::to_string(m.sample_rate_hz) + " Hz, expected 40000");
  if (m.channels < 1 || m.channels > static_cast<int>(SampleBlock::kMaxChannels) || m.frames < 0 ||
      m.frames > static_cast<int>(SampleBlock::kMaxFrames))
    throw std::invalid_argument("raw block of " + std::to_string(m.frames) + " frames x " + std::to_string(m.channels) +
                                " channels (at most 256 x 16)");
  SampleBlock b;
  b.first_index = m.first_index;
  b.frames = static_cast<std::uint32_t>(m.frames);
  b.channels = static_cast<std::uint32_t>(m.channels);
  if (m.nsamples != m.frames * m.channels || m.data.size() != static_cast<std::size_t>(m.nsamples))
    throw std::invalid_argument("raw block holds " + std::to_string(m.nsamples) + " samples, expected frames x channels = " +
                                std::to_string(m.frames * m.channels));
  std::copy(m.data.begin(), m.data.end(), b.data);
  return b;
}

OperatingPoint from_message(const noisemon::operating_point_t& m) {
  OperatingPoint op;
  op.utime = m.utime;
  op.speed_rpm = m.speed_rpm;
  op.load_nm = m.load_nm;
  op.soi_deg_btdc = m.soi_deg_btdc;
  op.rail_pressure_bar = m.rail_pressure_bar;
  op.motored = m.motored;
  return op;
}

}  // namespace noisemon::drivers
