// A comedi card that is not there: pipes carrying exactly the bytes a card would deliver, behind the comedi
// source's Acquisition interface, and the analytic engine and microphone signals the bytes are made from.
// Shared by the driver test of the comedi source and the daemon test that runs it through the pipeline.
//
// The engine: 1500 rpm with a 3.5 % speed ripple, a 0.25-degree encoder (position counter reset by an index
// 37.5 degrees after a TDC, timestamps of an 80 MHz timebase) and a known pressure curve against crank angle;
// expected values at any instant come from inverting the angle-time law here, never from the source.
#pragma once

#include <fcntl.h>
#include <unistd.h>
#include <array>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "drivers/comedi/comedi_source.hpp"
#include "dsp/math_constants.hpp"

namespace comedi_fake {

namespace nd = noisemon::drivers;

using noisemon::kPi;
constexpr std::int64_t kEpoch = 1'700'000'000'000'000;  // utime of 40 kHz frame 0

// Card ranges the fake card offers: range 0 = +-10 V, range 1 = +-1 V (16-bit converters).
constexpr double kRangeLo[] = {-10.0, -1.0};
constexpr double kRangeHi[] = {10.0, 1.0};

inline std::uint16_t code16(double volts, unsigned range) {
  const double c = std::round((volts - kRangeLo[range]) / (kRangeHi[range] - kRangeLo[range]) * 65535.0);
  return static_cast<std::uint16_t>(std::clamp(c, 0.0, 65535.0));
}

template <class T>
void append(std::vector<std::byte>& out, T value) {
  const auto* p = reinterpret_cast<const std::byte*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
}

// A pipe standing in for a subdevice's descriptor; conversions as a hard-calibrated 16-bit card (or raw 32-bit
// counters) computes them, the channel's si_offset (the pressure chain's zero) subtracted as the device does.
class PipeAcquisition final : public nd::comedi::Acquisition {
 public:
  PipeAcquisition(const nd::comedi::ComediAcquisitionConfig& cfg, std::int64_t origin) : cfg_(cfg), origin_(origin) {
    if (pipe2(fds_, O_CLOEXEC) != 0) throw std::runtime_error("pipe");
    fcntl(fds_[1], F_SETPIPE_SZ, 1 << 20);
    bool counters = false;
    for (const auto& ch : cfg.channels) {
      counters = counters || ch.raw_counts;
      conversions_.push_back(ch.raw_counts ? nd::comedi::linear_conversion(0.0, 4294967295.0, 4294967295u, 1.0)
                                           : nd::comedi::linear_conversion(kRangeLo[ch.range], kRangeHi[ch.range],
                                                                           65535, ch.si_per_volt, ch.si_offset));
    }
    width_ = counters ? nd::comedi::SampleWidth::k32Bit : nd::comedi::SampleWidth::k16Bit;
  }
  ~PipeAcquisition() override {
    if (writer_.joinable()) writer_.join();
    close(fds_[0]);
    close(fds_[1]);
  }
  std::string where() const override { return cfg_.device_path + " subdevice " + std::to_string(cfg_.subdevice); }
  int fd() const override { return fds_[0]; }
  nd::comedi::SampleWidth sample_width() const override { return width_; }
  const std::vector<nd::comedi::ChannelConversion>& conversions() const override { return conversions_; }
  double scan_period_s() const override {
    return cfg_.clock == nd::comedi::ScanClock::kTimed ? 1.0 / cfg_.scan_rate_hz : 0.0;
  }
  void start() override { ++starts; }
  bool restart() override {
    ++restarts;
    origin_ += restart_shift_us;
    return true;
  }
  void cancel() override { ++cancels; }
  std::int64_t origin_utime() const override { return origin_; }
  nd::comedi::ReadFunction read_function() const override {
    return [this](int fd, void* buf, std::size_t size) -> ssize_t {
      auto* self = const_cast<PipeAcquisition*>(this);
      std::size_t n = size;
      if (epipe_at && !epipe_done) {
        if (self->delivered == *epipe_at) {
          self->epipe_done = true;
          errno = EPIPE;  // the card's buffer overran
          return -1;
        }
        n = std::min<std::size_t>(n, *epipe_at - self->delivered);
      }
      if (hold_at && restarts.load() == 0) {  // a card's buffer is flushed by the cancel: nothing read across it
        if (self->delivered == *hold_at) {
          errno = EAGAIN;
          return -1;
        }
        n = std::min<std::size_t>(n, *hold_at - self->delivered);
      }
      const ssize_t r = ::read(fd, buf, n);
      if (r > 0) self->delivered += static_cast<std::size_t>(r);
      return r;
    };
  }
  // Writes the bytes from a thread of its own (the pipe holds less than a test's worth).
  void feed(std::vector<std::byte> bytes) {
    total = bytes.size();
    writer_ = std::thread([this, b = std::move(bytes)] {
      for (std::size_t pos = 0; pos < b.size();) {
        const ssize_t w = ::write(fds_[1], b.data() + pos, b.size() - pos);
        if (w <= 0) return;
        pos += static_cast<std::size_t>(w);
      }
    });
  }

  nd::comedi::ComediAcquisitionConfig cfg_;
  std::atomic<int> starts{0}, restarts{0}, cancels{0};
  std::atomic<std::size_t> delivered{0};
  std::size_t total = 0;
  std::optional<std::size_t> epipe_at;
  bool epipe_done = false;
  std::optional<std::size_t> hold_at;  // bytes readable before the first restart
  std::int64_t restart_shift_us = 0;

 private:
  int fds_[2];
  std::int64_t origin_;
  nd::comedi::SampleWidth width_;
  std::vector<nd::comedi::ChannelConversion> conversions_;
  std::thread writer_;
};

// ---- the analytic engine ----------------------------------------------------------------------------------

constexpr double kOmega = 9000.0;              // deg/s (1500 rpm)
constexpr double kRipple = 2.0;                // deg
constexpr double kRippleRad = 2.0 * kPi * 25;  // rad/s
constexpr double kTheta0 = -290.3;             // crank angle at the acquisition origin, 0 = firing TDC
constexpr double kResolution = 0.25;           // deg per encoder count
constexpr std::uint32_t kCountsPerRev = 1440;
constexpr double kIndexDeg = 37.5;  // index mark, degrees after a TDC
constexpr double kTimebase = 80e6;

inline double theta_at(double t) { return kTheta0 + kOmega * t + kRipple * std::sin(kRippleRad * t); }
inline double time_at(double theta) {
  double t = (theta - kTheta0) / kOmega;
  for (int i = 0; i < 30; ++i) t -= (theta_at(t) - theta) / (kOmega + kRipple * kRippleRad * std::cos(kRippleRad * t));
  return t;
}
inline double wrap720(double theta) { return theta - 720.0 * std::floor((theta + 360.0) / 720.0); }

// Cylinder pressure (Pa) against crank angle: a combustion peak at firing TDC; `second_peak` puts the same
// peak at the gas-exchange TDC (so only a cam can tell them apart).
inline double pressure_pa(double theta, bool second_peak = false) {
  const double a = wrap720(theta);
  double p = 1.2e5 + 60e5 * std::exp(-(a / 30.0) * (a / 30.0));
  if (second_peak) {
    const double b = a < 0 ? a + 360.0 : a - 360.0;
    p += 60e5 * std::exp(-(b / 30.0) * (b / 30.0));
  }
  return p;
}

struct EdgeBytes {
  std::vector<std::byte> pressure, encoder, timestamp;  // timestamp: only when on a separate subdevice
  std::size_t edges = 0;
};

struct EngineSetup {
  double duration_s = 0.6;
  bool charge_chain = true;  // pC/bar + amplifier, with a sensor drift pegged away
  bool cam = false;
  bool second_peak = false;
  bool period_timestamps = false;
  bool separate_timestamp = false;
  std::uint32_t timestamp_bits = 24;  // wraps every 0.21 s at 80 MHz
  double offset_step_bar = 0.0;       // charge chain: the sensor's offset moves by +-this at each gas-exchange TDC
};

constexpr double kDriftBar = -3.0;  // the relative sensor's offset (bar) the pegging must remove

// Volts at the card for a pressure, through the sensor chain written out here (not the driver's helpers).
inline double chain_volts(double p_pa, bool charge, double drift_bar = kDriftBar) {
  const double bar = p_pa / 1e5;
  return charge ? (bar + drift_bar) * 10.0 /*pC/bar*/ * 5.0 /*mV/pC*/ * 1e-3 : bar * 100.0 /*mV/bar*/ * 1e-3;
}
// The drift in the cycle of theta: kDriftBar, +-offset_step_bar alternately from cycle to cycle.
inline double drift_bar(double theta, double offset_step_bar) {
  const auto cycle = static_cast<std::int64_t>(std::floor((theta + 360.0) / 720.0));
  return kDriftBar + ((cycle % 2 + 2) % 2 == 0 ? offset_step_bar : -offset_step_bar);
}

inline EdgeBytes engine_bytes(const EngineSetup& s, double t_from = 0.0) {
  EdgeBytes b;
  // The card stops just after the first index at or after duration_s: the assembler confirms a revolution at
  // the index that closes it (one still open at a stop goes out with NaN crank), so every revolution the
  // tests check is a confirmed one.
  const double theta_stop = theta_at(s.duration_s);
  const double theta_end = kIndexDeg + 360.0 * std::ceil((theta_stop - kIndexDeg) / 360.0) + 0.5 * kResolution;
  // Edges sit where the count changes: index + k * resolution.
  auto n = static_cast<std::int64_t>(std::floor((theta_at(t_from) - kIndexDeg) / kResolution)) + 1;
  const std::uint64_t mask = (1ULL << s.timestamp_bits) - 1;
  std::uint64_t previous_ticks = static_cast<std::uint64_t>(std::floor(t_from * kTimebase));
  for (;; ++n) {
    const double theta = kIndexDeg + kResolution * static_cast<double>(n);
    if (theta >= theta_end) break;
    const double t = time_at(theta);
    const auto ticks = static_cast<std::uint64_t>(std::floor(t * kTimebase));
    append(
        b.pressure,
        code16(chain_volts(pressure_pa(theta, s.second_peak), s.charge_chain, drift_bar(theta, s.offset_step_bar)), 0));
    if (s.cam) {
      const double a = wrap720(theta);
      append(b.pressure, code16(a >= -100.0 && a < -40.0 ? 5.0 : 0.2, 0));  // cam high from -100 deg
    }
    const std::int64_t count = ((n % kCountsPerRev) + kCountsPerRev) % kCountsPerRev;
    append(b.encoder, static_cast<std::uint32_t>(count));
    const std::uint64_t stamp = s.period_timestamps ? ticks - previous_ticks : ticks & mask;
    append(s.separate_timestamp ? b.timestamp : b.encoder, static_cast<std::uint32_t>(stamp));
    previous_ticks = ticks;
    ++b.edges;
  }
  return b;
}

// ---- microphones ------------------------------------------------------------------------------------------

constexpr double kMicRate = 50000.0;
struct Tone {
  double hz, amplitude_pa, phase;
};
// Frequencies incommensurate with the card and output rates, so the 16-bit quantisation error is noise-like
// rather than a fixed pattern repeating every period (which would bias the level).
inline const Tone kTones[] = {{1013.7, std::sqrt(2.0), 0.3}, {4871.9, 0.1, 1.0}, {14873.1, 0.5, 2.0}};
constexpr double kMicMvPerPa[] = {50.0, 12.5, 31.6};

inline double tone(std::size_t mic, double t) {
  const Tone& k = kTones[mic];
  return k.amplitude_pa * std::sin(2.0 * kPi * k.hz * t + k.phase);
}

inline std::vector<std::byte> mic_bytes(double duration_s, std::size_t from_scan = 0) {
  std::vector<std::byte> out;
  const auto scans = static_cast<std::size_t>(duration_s * kMicRate);
  for (std::size_t m = from_scan; m < scans; ++m)
    for (std::size_t c = 0; c < 3; ++c) append(out, code16(tone(c, m / kMicRate) * kMicMvPerPa[c] * 1e-3, 1));
  return out;
}

// ---- the source under test ---------------------------------------------------------------------------------

inline nd::comedi::ComediSourceConfig source_config(const EngineSetup& s) {
  nd::comedi::ComediSourceConfig c;
  c.pressure.device = "/dev/test-pressure";
  c.pressure.subdevice = 0;
  if (s.charge_chain) {
    c.pressure.sensitivity_pc_per_bar = 10.0;
    c.pressure.amplifier_mv_per_pc = 5.0;
    c.pressure.peg_pa = 1.2e5;  // the curve's pressure at intake BDC
  } else {
    c.pressure.sensitivity_mv_per_bar = 100.0;
  }
  if (s.cam) {
    c.pressure.cam_channel = 3;
    c.phase = nd::comedi::PhaseSource::kCam;
    c.cam_edge_deg = -100.0;
  }
  c.encoder.device = "/dev/test-counter";
  c.encoder.subdevice = 11;
  if (s.separate_timestamp) c.encoder.timestamp_subdevice = 12;
  c.encoder.timestamp_mode =
      s.period_timestamps ? nd::comedi::TimestampMode::kPeriod : nd::comedi::TimestampMode::kAbsolute;
  c.encoder.timestamp_bits = s.timestamp_bits;
  c.encoder.timebase_hz = kTimebase;
  c.encoder.counts_per_rev = kCountsPerRev;
  c.encoder.index_angle_deg = kIndexDeg;
  c.mics.device = "/dev/test-mics";
  c.mics.subdevice = 0;
  c.mics.scan_rate_hz = kMicRate;
  for (unsigned i = 0; i < 3; ++i) c.mics.channels.push_back({.channel = i, .range = 1});
  c.mics.sensitivity_mv_per_pa.assign(std::begin(kMicMvPerPa), std::end(kMicMvPerPa));
  c.initial_backoff = std::chrono::microseconds(100);
  return c;
}

constexpr std::int64_t kEdgeOriginUs = 1000;  // acquisitions start 1 ms after the epoch
constexpr std::int64_t kMicOriginUs = 1000;

struct Harness {
  std::vector<PipeAcquisition*> acquisitions;
  std::unique_ptr<nd::Source> source;
  nd::BlockRing pressure{1024}, mics{1024}, angle{4096};
  nd::OperatingPointRing op{16};

  explicit Harness(const nd::comedi::ComediSourceConfig& config) {
    source = nd::comedi::make_comedi_source(
        config,
        [this](const nd::comedi::ComediAcquisitionConfig& a) {
          const std::int64_t origin =
              kEpoch + (a.clock == nd::comedi::ScanClock::kTimed ? kMicOriginUs : kEdgeOriginUs);
          auto p = std::make_unique<PipeAcquisition>(a, origin);
          acquisitions.push_back(p.get());
          return p;
        },
        kEpoch);
  }
  PipeAcquisition& by_device(const std::string& device, int subdevice) {
    for (auto* a : acquisitions)
      if (a->cfg_.device_path == device && a->cfg_.subdevice == subdevice) return *a;
    throw std::runtime_error("no acquisition " + device);
  }
  // The card delivers the engine of `s` (its edges, encoder and timestamps) and the microphones for as long, then
  // run(); returns the edges the card saw.
  std::size_t run_engine(const EngineSetup& s) {
    EdgeBytes e = engine_bytes(s);
    by_device("/dev/test-pressure", 0).feed(std::move(e.pressure));
    by_device("/dev/test-counter", 11).feed(std::move(e.encoder));
    if (s.separate_timestamp) by_device("/dev/test-counter", 12).feed(std::move(e.timestamp));
    by_device("/dev/test-mics", 0).feed(mic_bytes(s.duration_s));
    run();
    return e.edges;
  }
  // Starts, waits until every byte was read, stops; returns the frames by 40 kHz index.
  void run() {
    source->start(nd::Streams{&pressure, &mics, &op, &angle});
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    for (bool done = false; !done && std::chrono::steady_clock::now() < deadline;) {
      drain();
      done = true;
      for (auto* a : acquisitions) done = done && a->delivered.load() == a->total;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    source->stop();
    drain();
  }
  void drain() {
    for (auto [ring, out] : {std::pair{&pressure, &pressure_frames}, std::pair{&mics, &mic_frames}}) {
      while (const nd::SampleBlock* b = ring->front()) {
        for (std::uint32_t f = 0; f < b->frames; ++f)
          (*out)[b->first_index + f].assign(b->data + f * b->channels, b->data + (f + 1) * b->channels);
        ring->consume(1);
      }
    }
    while (const nd::SampleBlock* b = angle.front()) {  // the crank-angle stream: {first_index, crank, pressure}
      for (std::uint32_t f = 0; f < b->frames; ++f)
        edges.push_back({static_cast<double>(b->first_index), b->data[f * b->channels + nd::kAngleCrankChannel],
                         b->data[f * b->channels + nd::kAnglePressureChannel]});
      angle.consume(1);
    }
  }
  std::int64_t counter(const std::string& name) const {
    for (const auto& c : source->counters())
      if (c.name == name) return c.value;
    throw std::runtime_error("no counter " + name);
  }
  std::map<std::int64_t, std::vector<double>> pressure_frames, mic_frames;
  std::vector<std::array<double, 3>> edges;
};

}  // namespace comedi_fake
