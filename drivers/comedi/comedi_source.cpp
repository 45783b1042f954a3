#include "drivers/comedi/comedi_source.hpp"

#include <atomic>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "drivers/comedi/comedi_rest.hpp"
#include "drivers/mic_positions.hpp"
#include "drivers/timed_stream.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers::comedi {
namespace {

constexpr std::size_t kReadBufferBytes = 1 << 16;

std::string where(const std::string& device, int subdevice) {
  return device + " subdevice " + (subdevice >= 0 ? std::to_string(subdevice) : std::string("(default read)"));
}

class DeviceAcquisition final : public Acquisition {
 public:
  explicit DeviceAcquisition(const ComediAcquisitionConfig& config) : device_(config) {}
  std::string where() const override {
    return device_.device_path() + " subdevice " + std::to_string(device_.subdevice());
  }
  int fd() const override { return device_.fd(); }
  SampleWidth sample_width() const override { return device_.sample_width(); }
  const std::vector<ChannelConversion>& conversions() const override { return device_.conversions(); }
  double scan_period_s() const override { return device_.scan_period_s(); }
  void start() override {
    const std::int64_t before = wall_utime();
    device_.start();
    origin_ = (before + wall_utime()) / 2;
  }
  bool restart() override {
    const std::int64_t before = wall_utime();
    if (!device_.restart()) return false;
    origin_ = (before + wall_utime()) / 2;
    return true;
  }
  void cancel() override { device_.cancel(); }
  std::int64_t origin_utime() const override { return origin_; }
  unsigned buffer_bytes() const override { return device_.buffer_bytes(); }

 private:
  ComediDevice device_;
  std::int64_t origin_ = 0;
};

double pressure_si_per_volt(const ComediSourceConfig::Pressure& p) {
  const bool voltage = p.sensitivity_mv_per_bar > 0.0;
  const bool charge = p.sensitivity_pc_per_bar > 0.0 || p.amplifier_mv_per_pc > 0.0;
  if (voltage == charge)
    throw std::invalid_argument(
        "comedi.pressure: set either sensitivity_mv_per_bar (voltage-output chain) or sensitivity_pc_per_bar and "
        "amplifier_mv_per_pc (charge-output transducer and charge amplifier)");
  if (voltage) return pressure_pa_per_volt(p.sensitivity_mv_per_bar);
  if (p.offset_bar != 0.0)
    throw std::invalid_argument(
        "comedi.pressure: offset_bar applies to a voltage-output chain; a charge amplifier has no absolute zero (it "
        "drifts): reference each cycle by pegging instead (peg_pa)");
  if (!(p.sensitivity_pc_per_bar > 0.0 && p.amplifier_mv_per_pc > 0.0))
    throw std::invalid_argument(
        "comedi.pressure: a charge chain needs both sensitivity_pc_per_bar and amplifier_mv_per_pc");
  return charge_pressure_pa_per_volt(p.sensitivity_pc_per_bar, p.amplifier_mv_per_pc);
}

// Where each value sits in the encoder-clocked scans of comedi_acquisitions().
EdgeStreamConfig edge_stream_config(const ComediSourceConfig& c) {
  EdgeStreamConfig e;
  const bool cam = c.pressure.cam_channel >= 0;
  const bool separate_timestamp = c.encoder.timestamp_subdevice >= 0;
  e.stream_channels = {cam ? 2u : 1u, separate_timestamp ? 1u : 2u};
  if (separate_timestamp) e.stream_channels.push_back(1);
  e.pressure = {0, 0};
  if (cam) e.cam = ScanSlot{0, 1};
  e.position = {1, 0};
  e.timestamp = separate_timestamp ? ScanSlot{2, 0} : ScanSlot{1, 1};
  e.counts_per_rev = c.encoder.counts_per_rev;
  e.index_resets_counter = c.encoder.index_resets_counter;
  e.counts_per_edge = c.encoder.counts_per_edge;
  e.max_rpm = c.encoder.max_rpm;
  e.index_angle_deg = c.encoder.index_angle_deg;
  e.timebase_hz = c.encoder.timebase_hz;
  e.timestamp_bits = c.encoder.timestamp_bits;
  e.timestamp_mode = c.encoder.timestamp_mode;
  e.phase = c.phase;
  e.cam_threshold_v = c.cam_threshold_v;
  e.cam_edge_deg = c.cam_edge_deg;
  e.peg_pa = c.pressure.peg_pa;
  e.peg_angle_deg = c.pressure.peg_angle_deg;
  return e;
}

class ComediSource final : public Source {
 public:
  ComediSource(const ComediSourceConfig& config, const AcquisitionFactory& factory, std::int64_t epoch_utime)
      : config_(config),
        edge_config_(edge_stream_config(config)),
        epoch_utime_(epoch_utime ? epoch_utime : wall_utime()) {
    acquisition_configs_ = comedi_acquisitions(config);
    for (const ComediAcquisitionConfig& a : acquisition_configs_) {
      acquisitions_.push_back(factory ? factory(a) : open_comedi_acquisition(a));
      if (acquisitions_.back()->conversions().size() != a.channels.size())
        throw std::runtime_error("comedi " + acquisitions_.back()->where() + ": " +
                                 std::to_string(acquisitions_.back()->conversions().size()) +
                                 " channel conversions for " + std::to_string(a.channels.size()) +
                                 " configured channels");
    }
    edge_count_ = acquisitions_.size() - 1;
    timestamp_acquisition_ = edge_config_.timestamp.stream;
    info_.epoch_utime = epoch_utime_;
    info_.mic_count = static_cast<std::uint32_t>(config.mics.channels.size());
    info_.mic_positions_m = config.mics.positions_m;
    if (info_.mic_positions_m.empty()) {
      info_.mic_positions_m = thesis_mic_positions();
      info_.mic_positions_m.resize(info_.mic_count);
    }
    info_.radius_m = config.mics.radius_m;
    info_.acoustic_delay_s = config.mics.radius_m / config.mics.speed_of_sound_m_s;
    info_.pressure_edges_per_rev = static_cast<double>(config.encoder.counts_per_rev) / config.encoder.counts_per_edge;
    // (A coarser encoder, a trigger wheel, has too few edges for the figures: they come from the 40 kHz pressure.)
    info_.pressure_angle_step_deg = config.at_rest ? 0.0 : angle_step_deg(info_.pressure_edges_per_rev);
    info_.mic_passband_hz = dsp::converter_passband_hz(config.mics.scan_rate_hz);
  }
  ~ComediSource() override { stop(); }

  std::string name() const override { return "comedi"; }
  StreamInfo info() const override { return info_; }

  void start(const Streams& streams) override {
    if (started_) throw std::logic_error("comedi source: start() while running; stop() first");
    if (!streams.pressure || !streams.mics)
      throw std::invalid_argument("comedi source: start() needs the pressure and mic rings");
    decoders_.clear();
    for (const auto& a : acquisitions_) decoders_.emplace_back(a->sample_width(), a->conversions());
    if (!config_.at_rest) {
      edge_ = std::make_unique<EdgeStreamAssembler>(edge_config_, epoch_utime_);
      if (info_.pressure_angle_step_deg > 0) edge_->set_angle_ring(streams.pressure_angle);
    }
    std::size_t started = 0;
    try {
      for (; started < acquisitions_.size(); ++started) acquisitions_[started]->start();
      mic_ = timed_assembler(*acquisitions_.back(), info_.mic_count, 0);
      if (config_.at_rest) rest_ = timed_assembler(*acquisitions_[0], 1, kPressureStreamChannels - 1);  // crank NaN
    } catch (...) {
      for (std::size_t i = 0; i < started; ++i) acquisitions_[i]->cancel();
      throw;
    }
    if (config_.at_rest) {
      rest_->restart(acquisitions_[0]->origin_utime());
      speed_ = std::make_unique<RestSpeedMeter>(info_.pressure_edges_per_rev);
    } else {
      edge_->restart(acquisitions_[timestamp_acquisition_]->origin_utime());
    }
    mic_->restart(acquisitions_.back()->origin_utime());
    note_buffers();
    started_ = true;
    edge_worker_.start("nm-pressure", config_.threads.pressure,
                       [this, ring = streams.pressure, ops = streams.operating_point](const std::atomic<bool>& stop) {
                         run_edges(*ring, ops, stop);
                       });
    mic_worker_.start("nm-mics", config_.threads.mics,
                      [this, ring = streams.mics](const std::atomic<bool>& stop) { run_mics(*ring, stop); });
  }

  void stop() override {
    edge_worker_.request_stop();
    mic_worker_.request_stop();
    for (auto& a : acquisitions_) a->cancel();  // unblocks a device read
    edge_worker_.join();
    mic_worker_.join();
    started_ = false;
  }

  bool running() const override {
    for (const WorkerThread* w : {&edge_worker_, &mic_worker_})
      if (w->state() != ThreadState::kRunning || w->blocks_written() == 0) return false;
    return true;
  }

  std::vector<DriverThreadStatus> thread_status() const override {
    return {edge_worker_.status(), mic_worker_.status()};
  }

  std::vector<DriverCounter> counters() const override {
    auto v = [](const std::atomic<std::uint64_t>& a) {
      return static_cast<std::int64_t>(a.load(std::memory_order_relaxed));
    };
    return {{"comedi.pressure.overruns", v(c_.pressure_overruns)},
            {"comedi.pressure.restarts", v(c_.pressure_restarts)},
            {"comedi.mics.overruns", v(c_.mic_overruns)},
            {"comedi.mics.restarts", v(c_.mic_restarts)},
            {"comedi.encoder.edges", v(c_.edges)},
            {"comedi.encoder.errors", v(c_.encoder_errors)},
            {"comedi.encoder.edges_before_lock", v(c_.edges_before_lock)},
            {"comedi.encoder.phase_corrections", v(c_.phase_corrections)},
            {"comedi.encoder.revolutions_checked", v(c_.revolutions_checked)},
            {"comedi.encoder.revolutions_flagged", v(c_.revolutions_flagged)},
            {"comedi.encoder.missing_or_extra", v(c_.missing_or_extra)},
            {"comedi.encoder.lost_index", v(c_.lost_index)},
            {"comedi.encoder.reverse_steps", v(c_.reverse_steps)}};
  }

 private:
  struct Counters {
    std::atomic<std::uint64_t> pressure_overruns{0}, pressure_restarts{0}, mic_overruns{0}, mic_restarts{0};
    std::atomic<std::uint64_t> edges{0}, encoder_errors{0}, edges_before_lock{0}, phase_corrections{0};
    std::atomic<std::uint64_t> revolutions_checked{0}, revolutions_flagged{0}, missing_or_extra{0}, lost_index{0},
        reverse_steps{0};
  };

  // A timer-clocked acquisition's stream (the card's settled rate must be a whole number of Hz).
  std::unique_ptr<TimedStreamAssembler> timed_assembler(const Acquisition& a, std::uint32_t channels,
                                                        std::uint32_t unknown_channels) const {
    try {
      return std::make_unique<TimedStreamAssembler>(channels, 1.0 / a.scan_period_s(), epoch_utime_, unknown_channels);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error("comedi " + a.where() + ": " + e.what());
    }
  }

  ReadLoopConfig loop_config() const {
    ReadLoopConfig c;
    c.initial_backoff = config_.initial_backoff;
    c.max_backoff = config_.max_backoff;
    c.max_consecutive_overruns = config_.max_consecutive_overruns;
    return c;
  }

  // One line per kernel buffer: its size and how long it holds at the highest scan rate expected.
  void note_buffers() const {
    for (std::size_t i = 0; i < acquisitions_.size(); ++i) {
      const Acquisition& a = *acquisitions_[i];
      if (a.buffer_bytes() == 0) continue;
      const bool timed = a.scan_period_s() > 0.0;  // the microphones; the pressure at rest
      const std::string rate_what = timed ? "the card's settled scan rate" : edge_rate_what(config_.encoder);
      const double rate = timed ? 1.0 / a.scan_period_s() : edge_scan_rate_hz(config_.encoder);
      const std::string note = buffer_note(a, acquisition_configs_[i], rate, rate_what);
      if (config_.log_info)
        config_.log_info(note);
      else
        std::fprintf(stderr, "%s\n", note.c_str());
    }
  }

  static std::string edge_rate_what(const ComediSourceConfig::Encoder& e) {
    return e.max_rpm > 0.0 ? "encoder edges at max_rpm " + std::to_string(std::lround(e.max_rpm))
                           : "max_rpm not set: the most edges the resampler accepts";
  }

  // A read loop that ended without a stop request ended the acquisition: the thread fails.
  static void finish(const ReadLoopResult& r, const std::atomic<bool>& stop) {
    if (!r.failed && stop.load()) return;
    throw std::runtime_error(r.failed ? r.message : "acquisition ended unexpectedly: " + r.message);
  }

  // Re-arms a group of acquisitions together: all cancelled first, so they start again at the same edge.
  bool rearm(std::size_t first, std::size_t count) {
    for (std::size_t i = first; i < first + count; ++i) acquisitions_[i]->cancel();
    bool ok = true;
    for (std::size_t i = first; i < first + count; ++i) ok = acquisitions_[i]->restart() && ok;
    for (std::size_t i = first; i < first + count; ++i) decoders_[i].reset();
    return ok;
  }

  // Acquisition i's descriptor as the read loop takes it, its bytes decoded into scans for on_scan.
  template <class OnScan>
  ReadStream stream_of(std::size_t i, std::span<std::byte> buffer, OnScan on_scan) {
    return {acquisitions_[i]->fd(), buffer,
            [this, i, on_scan](const std::byte* b, std::size_t n) { decoders_[i].feed(b, n, on_scan); },
            acquisitions_[i]->read_function(), acquisitions_[i]->where()};
  }

  // After an overrun of the pressure's group (edge-clocked, or at rest): what was gathered goes out, the group is
  // re-armed together and the stream starts again from the new origin of acquisition `origin_of`.
  template <class Assembler>
  bool recover_pressure(Assembler& stream, BlockRing& ring, std::size_t origin_of) {
    c_.pressure_overruns.fetch_add(1, std::memory_order_relaxed);
    stream.deliver(ring, true);
    const bool ok = rearm(0, edge_count_);
    stream.restart(acquisitions_[origin_of]->origin_utime());
    if (ok) c_.pressure_restarts.fetch_add(1, std::memory_order_relaxed);
    return ok;
  }

  void publish_edge_counters() {
    const EdgeStreamCounters& e = edge_->counters();
    c_.edges.store(e.edges, std::memory_order_relaxed);
    c_.encoder_errors.store(e.encoder_errors, std::memory_order_relaxed);
    c_.edges_before_lock.store(e.edges_before_lock, std::memory_order_relaxed);
    c_.phase_corrections.store(e.phase_corrections, std::memory_order_relaxed);
    c_.revolutions_checked.store(e.revolutions_checked, std::memory_order_relaxed);
    c_.revolutions_flagged.store(e.revolutions_flagged, std::memory_order_relaxed);
    c_.missing_or_extra.store(e.missing_or_extra, std::memory_order_relaxed);
    c_.lost_index.store(e.lost_index, std::memory_order_relaxed);
    c_.reverse_steps.store(e.reverse_steps, std::memory_order_relaxed);
    edge_worker_.set_blocks_written(edge_->blocks_written());
  }

  // The errors of a thread's reads name the acquisitions it reads.
  void run_edges(BlockRing& ring, OperatingPointRing* ops, const std::atomic<bool>& stop) {
    ReadLoopResult r;
    try {
      r = config_.at_rest ? read_rest(ring, ops, stop) : read_edges(ring, stop);
    } catch (const std::exception& e) {
      std::string names;
      for (std::size_t i = 0; i < edge_count_; ++i) names += (i ? ", " : "") + acquisitions_[i]->where();
      throw std::runtime_error("comedi " + names + ": " + e.what());
    }
    finish(r, stop);
  }

  void run_mics(BlockRing& ring, const std::atomic<bool>& stop) {
    ReadLoopResult r;
    try {
      r = read_mics(ring, stop);
    } catch (const std::exception& e) {
      throw std::runtime_error("comedi " + acquisitions_.back()->where() + ": " + e.what());
    }
    finish(r, stop);
  }

  ReadLoopResult read_edges(BlockRing& ring, const std::atomic<bool>& stop) {
    std::vector<std::vector<std::byte>> buffers(edge_count_, std::vector<std::byte>(kReadBufferBytes));
    std::vector<ReadStream> streams(edge_count_);
    for (std::size_t i = 0; i < edge_count_; ++i) {
      const auto stream = static_cast<std::uint32_t>(i);
      streams[i] =
          stream_of(i, buffers[i], [this, stream, &ring](const double* v) { edge_->add_scan(stream, v, ring); });
    }
    ReadLoopResult r = run_group_read_loop(
        streams,
        [&] {
          edge_->deliver(ring, false);
          publish_edge_counters();
        },
        [&] { return recover_pressure(*edge_, ring, timestamp_acquisition_); }, stop, loop_config());
    edge_->deliver(ring, true);
    publish_edge_counters();
    c_.pressure_overruns.store(r.overruns, std::memory_order_relaxed);
    return r;
  }

  // At rest: the pressure on the card's timer (acquisition 0) and the encoder's counter (1), whose edges, when any
  // come, are counted into the speed.
  ReadLoopResult read_rest(BlockRing& ring, OperatingPointRing* ops, const std::atomic<bool>& stop) {
    std::vector<std::byte> pressure_buffer(kReadBufferBytes), encoder_buffer(kReadBufferBytes);
    std::array<ReadStream, 2> streams{
        stream_of(0, pressure_buffer, [this, &ring](const double* v) { rest_->add_scan(v, ring); }),
        stream_of(1, encoder_buffer, [this](const double*) { speed_->add_edge(); })};
    auto publish = [&] {
      c_.edges.store(speed_->edges(), std::memory_order_relaxed);
      edge_worker_.set_blocks_written(rest_->blocks_written());
    };
    ReadLoopResult r = run_group_read_loop(
        streams,
        [&] {
          rest_->deliver(ring, false);
          speed_->after_pass(ops);
          publish();
        },
        [&] { return recover_pressure(*rest_, ring, 0); }, stop, loop_config());
    rest_->deliver(ring, true);
    publish();
    c_.pressure_overruns.store(r.overruns, std::memory_order_relaxed);
    return r;
  }

  ReadLoopResult read_mics(BlockRing& ring, const std::atomic<bool>& stop) {
    const std::size_t m = acquisitions_.size() - 1;
    std::vector<std::byte> buffer(kReadBufferBytes);
    ReadStream stream = stream_of(m, buffer, [this, &ring](const double* v) { mic_->add_scan(v, ring); });
    ReadLoopResult r = run_group_read_loop(
        std::span<ReadStream>(&stream, 1),
        [&] {
          mic_->deliver(ring, false);
          mic_worker_.set_blocks_written(mic_->blocks_written());
        },
        [&] {
          c_.mic_overruns.fetch_add(1, std::memory_order_relaxed);
          mic_->deliver(ring, true);
          const bool ok = rearm(m, 1);
          mic_->restart(acquisitions_[m]->origin_utime());
          if (ok) c_.mic_restarts.fetch_add(1, std::memory_order_relaxed);
          return ok;
        },
        stop, loop_config());
    mic_->deliver(ring, true);
    mic_worker_.set_blocks_written(mic_->blocks_written());
    c_.mic_overruns.store(r.overruns, std::memory_order_relaxed);
    return r;
  }

  ComediSourceConfig config_;
  EdgeStreamConfig edge_config_;
  std::int64_t epoch_utime_;
  StreamInfo info_;
  std::vector<ComediAcquisitionConfig> acquisition_configs_;  // as comedi_acquisitions() gives them
  std::vector<std::unique_ptr<Acquisition>> acquisitions_;    // encoder-clocked ones, then the microphones
  std::size_t edge_count_ = 0;
  std::uint32_t timestamp_acquisition_ = 1;
  std::vector<ScanDecoder> decoders_;
  std::unique_ptr<EdgeStreamAssembler> edge_;
  std::unique_ptr<TimedStreamAssembler> mic_;
  std::unique_ptr<TimedStreamAssembler> rest_;  // at rest: the pressure on the card's timer
  std::unique_ptr<RestSpeedMeter> speed_;       // at rest: the encoder's edges
  Counters c_;
  bool started_ = false;
  // Last: destroyed (stopped) first, before anything their bodies use.
  WorkerThread edge_worker_{"comedi.encoder_pressure"};
  WorkerThread mic_worker_{"comedi.microphones"};
};

}  // namespace

std::unique_ptr<Acquisition> open_comedi_acquisition(const ComediAcquisitionConfig& config) {
  return std::make_unique<DeviceAcquisition>(config);
}

double edge_scan_rate_hz(const ComediSourceConfig::Encoder& e) {
  return max_edge_rate_hz(e.counts_per_rev, e.counts_per_edge, e.max_rpm);
}

std::string buffer_note(const Acquisition& a, const ComediAcquisitionConfig& config, double scan_rate_hz,
                        const std::string& rate_what) {
  const std::size_t scan_bytes = a.conversions().size() * static_cast<std::size_t>(a.sample_width());
  std::ostringstream s;
  s.precision(3);
  s << "comedi " << a.where() << ": kernel buffer " << a.buffer_bytes() << " bytes ("
    << (config.buffer_bytes > 0 ? "buffer_bytes = " + std::to_string(config.buffer_bytes) : std::string("the driver's"))
    << ") holds " << buffer_seconds(a.buffer_bytes(), scan_bytes, scan_rate_hz) << " s of " << scan_bytes
    << "-byte scans at " << std::lround(scan_rate_hz) << " scans/s (" << rate_what
    << "): the driver thread may stall that long before the card overruns; the reader is woken "
    << (config.wake_every_scan ? "every scan (wake_every_scan)" : "per block");
  return s.str();
}

namespace {

[[noreturn]] void fail_config(const std::string& what) { throw std::invalid_argument(what); }

// The pressure card: the transducer (and the cam channel) clocked by the encoder's edges.
ComediAcquisitionConfig pressure_acquisition(const ComediSourceConfig& c) {
  ComediAcquisitionConfig p;
  p.device_path = c.pressure.device;
  p.subdevice = c.pressure.subdevice;
  p.clock = ScanClock::kExternal;
  p.external_trigger = c.pressure.edge_trigger;
  p.start_trigger = c.pressure.start_trigger;
  p.convert_src = c.pressure.convert_src;
  p.buffer_bytes = c.pressure.buffer_bytes;
  p.wake_every_scan = c.pressure.wake_every_scan;
  ComediChannelConfig pc = c.pressure.channel;
  pc.si_per_volt = pressure_si_per_volt(c.pressure);
  pc.si_offset = 1e5 * c.pressure.offset_bar;
  p.channels.push_back(pc);
  if (c.pressure.cam_channel >= 0)
    p.channels.push_back({.channel = static_cast<unsigned>(c.pressure.cam_channel),
                          .range = c.pressure.cam_range,
                          .aref = c.pressure.cam_aref,
                          .si_per_volt = 1.0});
  else if (c.phase == PhaseSource::kCam)
    fail_config("comedi.phase = \"cam\" needs comedi.pressure.cam_channel");
  return p;
}

// The encoder's counter: position (and timestamp, on its own subdevice when configured so) per edge.
void add_encoder_acquisitions(const ComediSourceConfig& c, std::vector<ComediAcquisitionConfig>& out) {
  if (c.encoder.subdevice < 0)
    fail_config("comedi.encoder.subdevice: set the counter subdevice that streams the encoder");
  ComediAcquisitionConfig e;
  e.device_path = c.encoder.device;
  e.subdevice = c.encoder.subdevice;
  e.clock = ScanClock::kExternal;
  e.external_trigger = c.encoder.edge_trigger;
  e.start_trigger = c.encoder.start_trigger;
  e.convert_src = c.encoder.convert_src;
  e.use_soft_calibration = false;
  e.buffer_bytes = c.encoder.buffer_bytes;
  e.wake_every_scan = c.encoder.wake_every_scan;
  const ComediChannelConfig position{.channel = c.encoder.position_channel,
                                     .range = 0,
                                     .aref = AREF_GROUND,
                                     .si_per_volt = 1.0,
                                     .raw_counts = true,
                                     .counter_mode = c.encoder.position_counter_mode};
  const ComediChannelConfig timestamp{.channel = c.encoder.timestamp_channel,
                                      .range = 0,
                                      .aref = AREF_GROUND,
                                      .si_per_volt = 1.0,
                                      .raw_counts = true,
                                      .counter_mode = c.encoder.timestamp_counter_mode};
  e.channels.push_back(position);
  if (c.encoder.timestamp_subdevice < 0) e.channels.push_back(timestamp);
  out.push_back(e);
  if (c.encoder.timestamp_subdevice >= 0) {
    ComediAcquisitionConfig ts = e;
    ts.subdevice = c.encoder.timestamp_subdevice;
    ts.channels = {timestamp};
    out.push_back(ts);
  }
}

// The microphone card, on its own timed clock.
ComediAcquisitionConfig mic_acquisition(const ComediSourceConfig& c) {
  const auto& m = c.mics;
  if (m.channels.empty() || m.channels.size() > SampleBlock::kMaxChannels)
    fail_config("comedi.mics.channels: 1.." + std::to_string(SampleBlock::kMaxChannels) + " microphone channels");
  if (m.sensitivity_mv_per_pa.size() != m.channels.size())
    fail_config("comedi.mics.sensitivity_mv_per_pa: one sensitivity per channel (" + std::to_string(m.channels.size()) +
                "), got " + std::to_string(m.sensitivity_mv_per_pa.size()));
  if (m.positions_m.empty() && m.channels.size() > thesis_mic_positions().size())
    fail_config("comedi.mics.positions_m: required for more than " + std::to_string(thesis_mic_positions().size()) +
                " microphones");
  if (!m.positions_m.empty() && m.positions_m.size() != m.channels.size())
    fail_config("comedi.mics.positions_m: one position per channel");
  if (!(m.radius_m > 0.0) || !(m.speed_of_sound_m_s > 0.0))
    fail_config("comedi.mics: radius_m and speed_of_sound_m_s must be positive");
  ComediAcquisitionConfig mic;
  mic.device_path = m.device;
  mic.subdevice = m.subdevice;
  mic.clock = ScanClock::kTimed;
  mic.scan_rate_hz = m.scan_rate_hz;
  mic.buffer_bytes = m.buffer_bytes;
  mic.wake_every_scan = m.wake_every_scan;
  for (std::size_t i = 0; i < m.channels.size(); ++i) {
    ComediChannelConfig ch = m.channels[i];
    try {
      ch.si_per_volt = microphone_pa_per_volt(m.sensitivity_mv_per_pa[i]);
    } catch (const std::invalid_argument& err) {
      fail_config("comedi.mics.sensitivity_mv_per_pa[" + std::to_string(i) + "]: " + err.what());
    }
    mic.channels.push_back(ch);
  }
  return mic;
}

}  // namespace

std::vector<ComediAcquisitionConfig> comedi_acquisitions(const ComediSourceConfig& c) {
  std::vector<ComediAcquisitionConfig> out;
  check_rest_scan_rate(c.pressure.rest_scan_rate_hz);
  const ComediAcquisitionConfig pressure = pressure_acquisition(c);
  out.push_back(c.at_rest ? rest_pressure_acquisition(pressure, c.pressure.rest_scan_rate_hz) : pressure);
  add_encoder_acquisitions(c, out);
  if (c.at_rest) out.resize(2);  // the encoder's edges are counted, not timed: no timestamp subdevice
  out.push_back(mic_acquisition(c));
  for (const auto& a : out)
    if (a.device_path.empty()) fail_config("comedi: empty device path for " + where(a.device_path, a.subdevice));
  return out;
}

std::unique_ptr<Source> make_comedi_source(const ComediSourceConfig& config, const AcquisitionFactory& factory,
                                           std::int64_t epoch_utime) {
  return std::make_unique<ComediSource>(config, factory, epoch_utime);
}

}  // namespace noisemon::drivers::comedi
