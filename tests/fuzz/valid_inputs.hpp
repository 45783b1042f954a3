// Small valid inputs for the fuzz targets, built in code rather than kept as binary blobs: raw LCM logs as
// noisemond records them, and (for the run-directory targets) a run.json, pressure.csv and mics.wav that
// belong together.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "drivers/formats/stream_messages.hpp"

namespace noisemon::fuzz {

template <class Message>
void write_event(lcm::LogFile& log, const std::string& channel, const Message& m, std::int64_t utime) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm::LogEvent e{0, utime, channel, static_cast<std::int32_t>(buf.size()), buf.data()};
  log.writeEvent(&e);
}

// A raw log: one session, an operating point, then `cycles` engine cycles of `cycle_frames` frames each on
// the 40 kHz grid (pressure with a 1 kHz ripple, crank ramping -360..360 per cycle; `mics` microphones hearing
// the ripple), in blocks of `block_frames`. An unknown channel's event rides along when `foreign` is set.
inline void write_raw_log(const std::string& path, std::uint32_t mics, int cycles, int cycle_frames, int block_frames,
                          bool foreign) {
  lcm::LogFile log(path, "w");
  drivers::StreamInfo info;
  info.epoch_utime = 1'700'000'000'000'000;
  info.mic_count = mics;
  for (std::uint32_t m = 0; m < mics; ++m) info.mic_positions_m.push_back({0.5 * m, 0.0, 1.75});
  info.radius_m = 1.75;
  info.acoustic_delay_s = 0.0;
  write_event(log, "NOISEMON_SESSION", drivers::formats::to_message(info, "fuzz-seed", info.epoch_utime),
              info.epoch_utime);
  drivers::OperatingPoint op;
  op.utime = info.epoch_utime;
  op.speed_rpm = 3000;
  op.load_nm = 10;
  op.soi_deg_btdc = 12;
  op.rail_pressure_bar = std::nan("");
  write_event(log, "NOISEMON_OP", drivers::formats::to_message(op), op.utime);
  if (foreign) {
    const char junk[] = "not a noisemon message";
    lcm::LogEvent e{0, info.epoch_utime, "SOMEONE_ELSE", sizeof junk, const_cast<char*>(junk)};
    log.writeEvent(&e);
  }
  const int total = cycles * cycle_frames;
  for (int first = 0; first < total; first += block_frames) {
    drivers::SampleBlock p, m;
    p.first_index = m.first_index = first;
    p.frames = m.frames = static_cast<std::uint32_t>(std::min(block_frames, total - first));
    p.channels = drivers::kPressureStreamChannels;
    m.channels = mics;
    for (std::uint32_t f = 0; f < p.frames; ++f) {
      const int k = first + static_cast<int>(f);
      const double x = 1e3 * std::sin(2 * std::numbers::pi * 1000.0 * k / drivers::kPipelineRateHz);
      p.data[2 * f] = 1e5 + x;
      p.data[2 * f + 1] = -360.0 + 720.0 * (k % cycle_frames) / cycle_frames;
      for (std::uint32_t c = 0; c < mics; ++c) m.data[f * mics + c] = 1e-3 * x * (1 + 0.1 * c);
    }
    const std::int64_t utime = info.epoch_utime + first * 25;
    write_event(log, "NOISEMON_RAW",
                drivers::formats::to_message(p, noisemon::raw_block_t::STREAM_PRESSURE, info.epoch_utime), utime);
    if (mics > 0)
      write_event(log, "NOISEMON_RAW",
                  drivers::formats::to_message(m, noisemon::raw_block_t::STREAM_MICS, info.epoch_utime), utime);
  }
}

// A run directory that belongs together: 1.5 engine cycles (60 ms) at 3000 rpm, pressure in bar every 6 crank
// degrees, one microphone covering the same 60 ms. Written as other programs write a motored run: null for
// what is unknown or does not apply (load not recorded, no injection), and the pressure chain's noise floor.
inline std::string run_json() {
  return R"({"condition": {"name": "fuzz_seed", "speed_rpm": 3000, "load_nm": null, "soi_deg_btdc": null,
               "rail_pressure_bar": null, "motored": true},
 "pressure": {"file": "pressure.csv", "units": "bar", "noise_floor_bar": 0.002},
 "mics": {"file": "mics.wav", "units": "Pa", "positions_m": [[-1.35, 0.78, 0.79]], "radius_m": 1.75}}
)";
}

inline std::string pressure_csv() {
  std::string csv = "time_s,crank_deg,pressure\n";
  char row[96];
  for (int crank = -360; crank < 720; crank += 6) {
    const double c = std::remainder(crank, 720.0);  // degrees from the nearest firing TDC
    std::snprintf(row, sizeof row, "%.9f,%d,%.5f\n", (crank + 360) / 18000.0, crank,
                  1.0 + 60.0 * std::exp(-c * c / 900.0));
    csv += row;
  }
  return csv;
}

// A RIFF/WAVE file of 32-bit IEEE floats, frame-major.
inline std::string float_wav(int channels, int rate_hz, const std::vector<float>& samples) {
  std::string w;
  const auto u32 = [&w](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) w += static_cast<char>(v >> (8 * i));
  };
  const auto u16 = [&w](std::uint16_t v) {
    w += static_cast<char>(v & 0xff);
    w += static_cast<char>(v >> 8);
  };
  const auto bytes = static_cast<std::uint32_t>(samples.size() * 4);
  w += "RIFF";
  u32(4 + 8 + 16 + 8 + bytes);
  w += "WAVEfmt ";
  u32(16);
  u16(3);  // WAVE_FORMAT_IEEE_FLOAT
  u16(static_cast<std::uint16_t>(channels));
  u32(static_cast<std::uint32_t>(rate_hz));
  u32(static_cast<std::uint32_t>(rate_hz * channels * 4));
  u16(static_cast<std::uint16_t>(channels * 4));
  u16(32);
  w += "data";
  u32(bytes);
  for (float f : samples) {
    std::uint32_t v;
    std::memcpy(&v, &f, 4);
    u32(v);
  }
  return w;
}

inline std::string mics_wav(int rate_hz = 40000) {
  const int frames = rate_hz * 60 / 1000;
  std::vector<float> s;
  for (int f = 0; f < frames; ++f)
    s.push_back(static_cast<float>(0.2 * std::sin(2 * std::numbers::pi * 1000.0 * f / rate_hz)));
  return float_wav(1, rate_hz, s);
}

}  // namespace noisemon::fuzz
