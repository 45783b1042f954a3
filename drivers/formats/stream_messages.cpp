#include "drivers/formats/stream_messages.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include "drivers/formats/big_endian.hpp"
#include "noisemon/session_v1_t.hpp"

namespace noisemon::drivers::formats {
namespace {

// Every unknown value (NaN) as the one positive quiet NaN: printf writes a NaN with its sign bit set (what
// 0.0 / 0.0 gives on x86) as "-nan", and the CSV files should say "nan" for every unknown alike.
double unknown_as_nan(double v) { return std::isnan(v) ? std::numeric_limits<double>::quiet_NaN() : v; }

}  // namespace

noisemon::operating_point_t to_message(const OperatingPoint& op) {
  noisemon::operating_point_t m;
  m.utime = op.utime;
  m.speed_rpm = unknown_as_nan(op.speed_rpm);
  m.load_nm = unknown_as_nan(op.load_nm);
  m.soi_deg_btdc = unknown_as_nan(op.soi_deg_btdc);
  m.rail_pressure_bar = unknown_as_nan(op.rail_pressure_bar);
  m.motored = op.motored;
  return m;
}

void set_raw_block(noisemon::raw_block_t& m, std::int64_t first_index, std::size_t frames, std::uint32_t channels,
                   std::int8_t stream, std::int64_t epoch_utime) {
  m.epoch_utime = epoch_utime;
  m.first_index = first_index;
  m.utime = utime_of_frame(epoch_utime, static_cast<double>(first_index));
  m.stream = stream;
  m.sample_rate_hz = kPipelineRateHz;
  m.channels = static_cast<std::int16_t>(channels);
  m.frames = static_cast<std::int16_t>(frames);
  m.nsamples = static_cast<std::int32_t>(frames * channels);
  m.data.resize(static_cast<std::size_t>(m.nsamples));
}

noisemon::raw_block_t to_message(const SampleBlock& b, std::int8_t stream, std::int64_t epoch_utime) {
  noisemon::raw_block_t m;
  set_raw_block(m, b.first_index, b.frames, b.channels, stream, epoch_utime);
  std::copy_n(b.data, m.nsamples, m.data.begin());
  return m;
}

noisemon::session_t to_message(const StreamInfo& info, const std::string& source, std::int64_t utime,
                               const std::string& condition) {
  noisemon::session_t m;
  m.condition = condition;
  m.utime = utime;
  m.epoch_utime = info.epoch_utime;
  m.source = source;
  m.sample_rate_hz = kPipelineRateHz;
  m.radius_m = info.radius_m;
  m.acoustic_delay_s = info.acoustic_delay_s;
  m.pressure_full_scale_pa = info.pressure_full_scale_pa;
  m.mic_full_scale_pa = info.mic_full_scale_pa;
  m.pressure_edges_per_rev = info.pressure_edges_per_rev;
  m.mic_passband_hz = info.mic_passband_hz;
  m.tdc_deg = info.tdc_deg;
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
  if (m.nmics < 0 || m.nmics > static_cast<int>(SampleBlock::kMaxChannels))
    throw std::invalid_argument("session with " + std::to_string(m.nmics) + " microphones (0.." +
                                std::to_string(SampleBlock::kMaxChannels) + " expected)");
  // The delay becomes a frame offset: bounded (as run.json's 0..1 s) so that it stays an offset.
  if (!(m.radius_m > 0) || !std::isfinite(m.radius_m) || !(m.acoustic_delay_s >= 0 && m.acoustic_delay_s <= 1))
    throw std::invalid_argument("session with radius " + std::to_string(m.radius_m) + " m and acoustic delay " +
                                std::to_string(m.acoustic_delay_s) + " s (positive radius, delay 0..1 s expected)");
  // A full scale is a level the samples are compared with: finite, and 0 (unknown) or above.
  for (const double fs : {m.pressure_full_scale_pa, m.mic_full_scale_pa})
    if (!(fs >= 0) || !std::isfinite(fs))
      throw std::invalid_argument("session with full scale " + std::to_string(fs) +
                                  " Pa (0 = unknown, or above 0 expected)");
  for (const double limit : {m.pressure_edges_per_rev, m.mic_passband_hz})
    if (!(limit >= 0) || !std::isfinite(limit))
      throw std::invalid_argument("session with encoder edges per revolution " +
                                  std::to_string(m.pressure_edges_per_rev) + " and microphone passband " +
                                  std::to_string(m.mic_passband_hz) + " Hz (0 = unknown, or above 0 expected)");
  StreamInfo info;
  info.epoch_utime = m.epoch_utime;
  info.mic_count = static_cast<std::uint32_t>(m.nmics);
  info.radius_m = m.radius_m;
  info.acoustic_delay_s = m.acoustic_delay_s;
  info.pressure_full_scale_pa = m.pressure_full_scale_pa;
  info.mic_full_scale_pa = m.mic_full_scale_pa;
  info.pressure_edges_per_rev = m.pressure_edges_per_rev;
  info.mic_passband_hz = m.mic_passband_hz;
  info.pressure_angle_step_deg = angle_step_deg(m.pressure_edges_per_rev);
  if (!(std::abs(m.tdc_deg) <= 30.0))
    throw std::invalid_argument("session with firing TDC at " + std::to_string(m.tdc_deg) +
                                " deg (-30 ... 30 expected)");
  info.tdc_deg = m.tdc_deg;
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
    throw std::invalid_argument("raw block holds " + std::to_string(m.nsamples) +
                                " samples, expected frames x channels = " + std::to_string(m.frames * m.channels));
  std::copy(m.data.begin(), m.data.end(), b.data);
  return b;
}

OperatingPoint from_message(const noisemon::operating_point_t& m) {
  OperatingPoint op;
  op.utime = m.utime;
  op.speed_rpm = unknown_as_nan(m.speed_rpm);
  op.load_nm = unknown_as_nan(m.load_nm);
  op.soi_deg_btdc = unknown_as_nan(m.soi_deg_btdc);
  op.rail_pressure_bar = unknown_as_nan(m.rail_pressure_bar);
  op.motored = m.motored;
  return op;
}

namespace {

// A string field at pos: int32 length (including the terminating NUL) then the bytes. Advances pos.
bool skip_string(const std::uint8_t* d, std::size_t size, std::size_t& pos) {
  if (size - pos < 4) return false;
  const std::int32_t len = read_be32(d + pos);
  pos += 4;
  if (len < 1 || static_cast<std::size_t>(len) > size - pos || d[pos + static_cast<std::size_t>(len) - 1] != 0)
    return false;
  pos += static_cast<std::size_t>(len);
  return true;
}

template <class Message>
bool decode_exact(const void* data, std::size_t size, Message& m) {
  if (size > static_cast<std::size_t>(INT32_MAX)) return false;
  try {
    return m.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size);
  } catch (const std::exception&) {
    return false;
  }
}

// The session's layout up to its trailing doubles (pressure_full_scale_pa, mic_full_scale_pa, pressure_edges_per_rev,
// mic_passband_hz and, since session_t's tdc_deg, that): how many bytes follow the condition string; SIZE_MAX when the
// lengths do not fit.
std::size_t session_tail_bytes(const void* data, std::size_t size) {
  // fingerprint, utime, epoch_utime, source, sample_rate_hz, radius_m, acoustic_delay_s, nmics, positions, condition
  const auto* d = static_cast<const std::uint8_t*>(data);
  std::size_t pos = 24;
  if (size < pos || !skip_string(d, size, pos)) return SIZE_MAX;
  pos += 24;
  if (size < pos + 2) return SIZE_MAX;
  const std::int16_t nmics = read_be16(d + pos);
  pos += 2;
  if (nmics < 0 || static_cast<std::size_t>(nmics) * 24 > size - pos) return SIZE_MAX;
  pos += static_cast<std::size_t>(nmics) * 24;
  if (!skip_string(d, size, pos)) return SIZE_MAX;
  return size - pos;
}

}  // namespace

bool decode_message(const void* data, std::size_t size, noisemon::session_t& m) {
  const std::size_t tail = session_tail_bytes(data, size);
  if (tail == 5 * 8) return decode_exact(data, size, m);
  noisemon::session_v1_t old;  // a log from before tdc_deg
  if (tail != 4 * 8 || !decode_exact(data, size, old)) return false;
  m = noisemon::session_t{};
  m.utime = old.utime, m.epoch_utime = old.epoch_utime, m.source = old.source, m.sample_rate_hz = old.sample_rate_hz;
  m.radius_m = old.radius_m, m.acoustic_delay_s = old.acoustic_delay_s, m.nmics = old.nmics;
  m.mic_positions_m = old.mic_positions_m, m.condition = old.condition;
  m.pressure_full_scale_pa = old.pressure_full_scale_pa, m.mic_full_scale_pa = old.mic_full_scale_pa;
  m.pressure_edges_per_rev = old.pressure_edges_per_rev, m.mic_passband_hz = old.mic_passband_hz;
  m.tdc_deg = 0.0;
  return true;
}

bool decode_message(const void* data, std::size_t size, noisemon::raw_block_t& m) {
  // fingerprint, utime, epoch_utime, first_index, stream (1), sample_rate_hz, channels (2), frames (2), nsamples
  constexpr std::size_t kNsamplesAt = 8 + 8 + 8 + 8 + 1 + 8 + 2 + 2;
  const auto* d = static_cast<const std::uint8_t*>(data);
  if (size < kNsamplesAt + 4) return false;
  const std::int32_t n = read_be32(d + kNsamplesAt);
  if (n < 0 || static_cast<std::size_t>(n) * 8 != size - kNsamplesAt - 4) return false;
  return decode_exact(data, size, m);
}

bool decode_message(const void* data, std::size_t size, noisemon::operating_point_t& m) {
  return decode_exact(data, size, m);
}

namespace {

const char* stream_name(std::int8_t stream) {
  if (stream == noisemon::raw_block_t::STREAM_PRESSURE) return "pressure";
  if (stream == noisemon::raw_block_t::STREAM_MICS) return "microphone";
  return "crank-angle";
}

// A crank-angle block's edges: no more than its encoder's block holds, angles within [-360, 360] or NaN (not known).
std::string angle_block_problem(const noisemon::raw_block_t& m, const StreamInfo& info) {
  if (static_cast<std::uint32_t>(m.frames) > max_edges_per_angle_block(info.pressure_angle_step_deg))
    return "crank-angle block of " + std::to_string(m.frames) + " edges: more than " +
           std::to_string(kMaxAngleBlockDeg) + " deg of crank angle";
  for (std::int16_t f = 0; f < m.frames; ++f) {
    const double c = m.data[static_cast<std::size_t>(f) * kAngleStreamChannels + kAngleCrankChannel];
    if (c < -360.0 || c > 360.0) return "crank angle outside [-360, 360] deg";
  }
  return "";
}

}  // namespace

std::string raw_block_problem(const noisemon::raw_block_t& m, const StreamInfo& info) {
  if (m.sample_rate_hz != kPipelineRateHz)
    return "sample rate " + std::to_string(m.sample_rate_hz) + " Hz, expected 40000";
  if (m.frames < 0 || m.frames > static_cast<int>(SampleBlock::kMaxFrames) || m.channels < 1 ||
      m.channels > static_cast<int>(SampleBlock::kMaxChannels) || m.nsamples != m.frames * m.channels ||
      m.data.size() != static_cast<std::size_t>(m.nsamples))
    return "block of " + std::to_string(m.frames) + " frames x " + std::to_string(m.channels) + " channels holding " +
           std::to_string(m.nsamples) + " samples";
  if (m.epoch_utime != info.epoch_utime)
    return "block of another session (epoch " + std::to_string(m.epoch_utime) + ")";
  if (m.first_index < -(std::int64_t{1} << 50) || m.first_index > (std::int64_t{1} << 50) ||
      m.utime != utime_of_frame(m.epoch_utime, static_cast<double>(m.first_index)))
    return "utime does not match first_index (a damaged field)";
  std::size_t expected;
  if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE)
    expected = kPressureStreamChannels;
  else if (m.stream == noisemon::raw_block_t::STREAM_MICS)
    expected = info.mic_count;
  else if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE_ANGLE && info.pressure_angle_step_deg > 0)
    expected = kAngleStreamChannels;
  else if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE_ANGLE)
    return "crank-angle block in a session whose encoder (pressure_edges_per_rev) has no crank-angle stream";
  else
    return "unknown stream " + std::to_string(m.stream);
  if (static_cast<std::size_t>(m.channels) != expected)
    return std::string(stream_name(m.stream)) + " block with " + std::to_string(m.channels) + " channels, expected " +
           std::to_string(expected);
  for (double v : m.data)
    if (std::isinf(v)) return "infinite sample";
  if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE_ANGLE) return angle_block_problem(m, info);
  if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE)
    for (std::int16_t f = 0; f < m.frames; ++f) {
      const double c = m.data[static_cast<std::size_t>(f) * kPressureStreamChannels + kCrankChannel];
      if (c < -360.0 || c > 360.0) return "crank angle outside [-360, 360] deg";
    }
  return "";
}

std::string raw_block_problem_for_recording(const noisemon::raw_block_t& m, const StreamInfo& info) {
  if (std::string why = raw_block_problem(m, info); !why.empty()) return why;
  for (double v : m.data)
    if (std::isnan(v)) return "non-finite sample";
  return "";
}

}  // namespace noisemon::drivers::formats
