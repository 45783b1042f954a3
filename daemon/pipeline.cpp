#include "daemon/pipeline.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include "daemon/calibration_history.hpp"
#include "daemon/cycle_processor.hpp"
#include "daemon/cycle_statistics.hpp"
#include "daemon/latency_window.hpp"
#include "daemon/report_messages.hpp"
#include "daemon/wakeup.hpp"
#include "drivers/crank_reference.hpp"
#include "drivers/worker_thread.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::daemon {
namespace {

using Clock = std::chrono::steady_clock;

struct RawItem {
  std::int8_t stream;
  drivers::SampleBlock block;
};

// Mean and maximum of values added since the last take.
struct Stat {
  double sum = 0, max = 0;
  std::int64_t n = 0;
  void add(double v) {
    sum += v;
    max = std::max(max, v);
    ++n;
  }
};

}  // namespace

struct Pipeline::Impl {
  Config config;
  std::unique_ptr<drivers::Source> source;
  std::shared_ptr<Publisher> publisher;
  PipelineOptions options;
  drivers::StreamInfo info;

  std::size_t ring_blocks;
  drivers::BlockRing pressure_ring, mic_ring;
  drivers::BlockRing angle_ring;  // the crank-angle stream, when the source has one (one edge per frame: larger)
  drivers::OperatingPointRing op_ring;
  // The instants the crank passes a microphone front-end's sync pulse angle, when the source has one.
  std::unique_ptr<drivers::CrankReference> crank_reference;
  dsp::SpscRing<CycleReport> report_ring{256};
  dsp::SpscRing<RawItem> raw_ring;  // every stream's blocks on their way to NOISEMON_RAW (the bus, the recorder or
                                    // both: Config::raw_streams()): the driver rings' room
  dsp::SpscRing<drivers::OperatingPoint> op_publish_ring{64};

  std::unique_ptr<CycleProcessor> processor;  // made with the pipeline, run by the processing thread
  std::deque<noisemon::cycle_report_t>
      stats_window;  // the latest reports, for the rolling statistics (publishing thread)
  std::atomic<std::int64_t> cycles_dropped{0};
  // Heartbeats: the steady clock (ns) at the top of the processing and publishing loops' latest iteration.
  std::atomic<std::int64_t> processing_beat_ns{0}, publishing_beat_ns{0};
  std::int64_t last_input_ns = 0;  // processing thread: when it last took a block from a driver ring
  Wakeup report_wakeup;            // a report is queued for the publishing thread
  static std::int64_t now_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
  }
  std::atomic<std::int64_t> frames_discarded{0};      // the processor's FIFOs: one stream ran ahead of a stalled one
  std::atomic<std::int64_t> gap_frames{0};            // frames lost in the streams, held or skipped
  std::atomic<std::int64_t> samples_replaced{0};      // non-finite pressure or microphone samples replaced
  std::atomic<std::int64_t> crank_unknown_frames{0};  // frames whose crank angle was NaN (encoder fault)
  std::atomic<std::int64_t> reports_queued{0};
  std::atomic<std::uint64_t> report_overruns{0};
  // The status's calibration ages: each gauge's name and its latest calibration (0: never); none: not published.
  std::vector<std::pair<std::string, std::int64_t>> calibrated_utime;
  Clock::time_point started;
  // Last: destroyed (stopped) first, before anything their bodies use. A stop request to the processing thread
  // means the drivers have stopped: it processes what is left in the rings, then returns.
  drivers::WorkerThread processing_thread{"processing"};
  drivers::WorkerThread publishing_thread{"lcm"};  // the status name it has always had

  // Blocks of the crank-angle stream per 40 kHz block (half full at worst: 312 a second) at up to 4000 rpm, whose
  // blocks are full: 3 for a 0.1 deg encoder, 1 for 0.5 deg; 0 without the stream. (A block is 32 KiB however few
  // channels it carries: rings sized for 6000 rpm at 0.1 deg were 60 MB more of the daemon's memory.)
  static std::size_t angle_ring_factor(const drivers::StreamInfo& i) {
    if (!(i.pressure_angle_step_deg > 0)) return 0;
    const double edges_per_s = 360.0 / i.pressure_angle_step_deg * 4000.0 / 60.0;
    return static_cast<std::size_t>(std::clamp(std::ceil(edges_per_s / 256.0 / 312.5), 1.0, 5.0));
  }
  static std::size_t blocks_for(double seconds) {
    return static_cast<std::size_t>(
        std::ceil(seconds * drivers::kPipelineRateHz / 128.0));  // room even for half-full blocks
  }

  Impl(const Config& c, std::unique_ptr<drivers::Source> s, std::shared_ptr<Publisher> p, PipelineOptions o)
      : config(c),
        source(std::move(s)),
        publisher(std::move(p)),
        options(std::move(o)),
        info(source->info()),
        ring_blocks(blocks_for(c.ring_seconds)),
        pressure_ring(ring_blocks),
        mic_ring(ring_blocks),
        angle_ring(angle_ring_factor(info) > 0 ? angle_ring_factor(info) * ring_blocks : 1),
        op_ring(256),
        raw_ring(c.raw_streams() ? (2 + angle_ring_factor(info)) * ring_blocks : 1),
        processor(make_processor()) {
    if (std::isfinite(info.sync_angle_deg))
      crank_reference = std::make_unique<drivers::CrankReference>(info.sync_angle_deg);
    read_calibrations();
  }

  std::unique_ptr<CycleProcessor> make_processor();
  void read_calibrations();
  void run_processing(const std::atomic<bool>& drain);
  void queue_report(const CycleReport& r);
  void run_publishing(std::atomic<std::int64_t>& published);
  void remember_for_statistics(const noisemon::cycle_report_t& m);
  void publish_statistics();
  noisemon::status_t make_status(std::int64_t published, const Stat& latency, const Stat& processing,
                                 LatencyWindow& report_latency) const;
};

std::unique_ptr<CycleProcessor> Pipeline::Impl::make_processor() {
  ProcessorConfig pc;
  pc.model = config.model;
  pc.acoustic_delay_s = config.acoustic_delay_s;
  pc.engine = config.engine;
  pc.metrics = config.combustion;
  // The configured TDC, else the one the stream's producer used (a replayed log's session): replay gives the live
  // figures. The session this pipeline publishes says which it uses.
  if (!config.tdc_deg_configured) pc.metrics.tdc_deg = info.tdc_deg;
  info.tdc_deg = pc.metrics.tdc_deg;
  pc.fifo_seconds = options.fifo_seconds > 0 ? options.fifo_seconds : std::max(1.0, 2 * config.ring_seconds);
  pc.mic_low_db = config.mic_low_db;
  pc.sound_power = config.sound_power;
  pc.time_average_mics = config.mic_average_time;
  return std::make_unique<CycleProcessor>(pc, info, [this](const CycleReport& r) { queue_report(r); });
}

void Pipeline::Impl::run_processing(const std::atomic<bool>& drain) {
  CycleProcessor& processor = *this->processor;
  if (!options.quiet)
    spdlog::info("processing: acoustic delay {} frames, {} microphones, model k1={:.3g} k3={:.3g} b1={:.3g} b3={:.3g}",
                 processor.delay_frames(), info.mic_count, config.model.k1, config.model.k3, config.model.b1,
                 config.model.b3);
  for (const std::string& problem : processor.sound_power().problems())
    if (!options.quiet) spdlog::warn("sound power (ISO 3744): {}", problem);
  std::int64_t dropped_seen = 0;
  bool ended = false;  // end_of_streams() told
  while (true) {
    processing_beat_ns.store(now_ns(), std::memory_order_relaxed);
    const bool draining = drain.load(std::memory_order_acquire);
    const bool raw = config.raw_streams();
    bool any = false;
    // Operating points first, process() last: an operating point a source hands over once the block rings are
    // empty applies to exactly the cycles its blocks complete after it (the log source's ordering relies on it).
    drivers::OperatingPoint op;
    while (op_ring.read(&op, 1) == 1) {
      processor.set_operating_point(op);
      if (config.lcm.publish_operating_point) (void)op_publish_ring.push(op);  // full: the publisher is behind, counted
    }
    // One CPU-time measurement for the batch (the idle polls are not counted).
    std::optional<CycleProcessor::CpuBatch> cpu_batch;
    if (pressure_ring.front() || mic_ring.front() || angle_ring.front()) cpu_batch.emplace(processor);
    // Alternate between the streams so neither runs far ahead of the other.
    for (int i = 0; i < 8; ++i) {
      bool got = false;
      if (const drivers::SampleBlock* b = pressure_ring.front()) {
        last_input_ns = now_ns();
        processor.add_pressure(*b);
        if (crank_reference) crank_reference->add_crank(*b);
        if (raw) (void)raw_ring.push(RawItem{0, *b});
        pressure_ring.consume(1);
        got = true;
      }
      if (const drivers::SampleBlock* b = mic_ring.front()) {
        last_input_ns = now_ns();
        processor.add_mics(*b);
        if (raw) (void)raw_ring.push(RawItem{1, *b});
        mic_ring.consume(1);
        got = true;
      }
      // Edges come many to a 40 kHz frame: take what the ring holds, so the stream is never what waits.
      for (int k = 0; k < 8; ++k) {
        const drivers::SampleBlock* b = angle_ring.front();
        if (!b) break;
        processor.add_pressure_angle(*b);
        if (raw) (void)raw_ring.push(RawItem{noisemon::raw_block_t::STREAM_PRESSURE_ANGLE, *b});
        angle_ring.consume(1);
        got = true;
      }
      if (!got) break;
      any = true;
    }
    processor.process();
    cpu_batch.reset();
    const ProcessorCounters& counted = processor.counters();
    if (counted.cycles_dropped != dropped_seen) {
      cycles_dropped += counted.cycles_dropped - dropped_seen;
      dropped_seen = counted.cycles_dropped;
    }
    frames_discarded.store(counted.frames_discarded, std::memory_order_relaxed);
    gap_frames.store(counted.gap_frames, std::memory_order_relaxed);
    samples_replaced.store(counted.samples_replaced, std::memory_order_relaxed);
    crank_unknown_frames.store(counted.crank_unknown_frames, std::memory_order_relaxed);
    if (config.cycles > 0 && reports_queued.load() >= config.cycles) break;
    if (!any) {
      if (draining && !ended) {  // drivers are joined and the rings are empty: process what waited for edges
        ended = true;
        processor.end_of_streams();
        processor.process();
        continue;
      }
      if (draining) break;
      std::this_thread::sleep_for(std::chrono::microseconds(options.lossless ? 100 : 1000));
    }
  }
}

void Pipeline::Impl::queue_report(const CycleReport& r) {
  if (config.cycles > 0 && reports_queued.load() >= config.cycles) return;
  // Lossless: wait for the publisher, unless it has failed (then nobody would ever make room).
  while (options.lossless && report_ring.size() == report_ring.capacity() &&
         publishing_thread.state() == drivers::ThreadState::kRunning)
    std::this_thread::sleep_for(std::chrono::microseconds(100));
  CycleReport stamped = r;
  stamped.input_ns = last_input_ns;
  if (!report_ring.push(stamped)) {
    ++report_overruns;
    ++cycles_dropped;
    return;
  }
  ++reports_queued;
  report_wakeup.notify();
}

noisemon::status_t Pipeline::Impl::make_status(std::int64_t published, const Stat& latency, const Stat& processing,
                                               LatencyWindow& report_latency) const {
  noisemon::status_t s;
  s.utime = drivers::wall_utime();
  s.uptime_s = std::chrono::duration<double>(Clock::now() - started).count();
  s.source = source->name();
  for (const drivers::DriverThreadStatus& t : source->thread_status()) {
    s.thread_name.push_back(t.name);
    s.thread_state.push_back(static_cast<std::int8_t>(t.state));
    s.thread_error.push_back(t.error);
  }
  for (const drivers::DriverThreadStatus& t : {processing_thread.status(), publishing_thread.status()}) {
    s.thread_name.push_back(t.name);
    s.thread_state.push_back(static_cast<std::int8_t>(t.state));
    s.thread_error.push_back(t.error);
  }
  auto ring = [&](const char* name, double fill, std::uint64_t overruns) {
    s.ring_name.push_back(name);
    s.ring_fill.push_back(static_cast<float>(fill));
    s.ring_overruns.push_back(static_cast<std::int64_t>(overruns));
  };
  ring("pressure", pressure_ring.fill_fraction(), pressure_ring.overrun_events());
  ring("mics", mic_ring.fill_fraction(), mic_ring.overrun_events());
  if (info.pressure_angle_step_deg > 0) ring("pressure_angle", angle_ring.fill_fraction(), angle_ring.overrun_events());
  ring("operating_point", op_ring.fill_fraction(), op_ring.overrun_events());
  ring("reports", report_ring.fill_fraction(), report_ring.overrun_events());
  ring("raw_publish", raw_ring.fill_fraction(), raw_ring.overrun_events());
  s.cycles_published = published;
  s.cycles_dropped = cycles_dropped.load();
  s.latency_ms_mean = latency.n ? static_cast<float>(latency.sum / latency.n) : 0.f;
  s.latency_ms_max = static_cast<float>(latency.max);
  s.processing_ms_mean = processing.n ? static_cast<float>(processing.sum / processing.n) : 0.f;
  s.processing_ms_max = static_cast<float>(processing.max);
  s.report_latency_ms_p50 = static_cast<float>(report_latency.quantile(0.5));
  s.report_latency_ms_p99 = static_cast<float>(report_latency.quantile(0.99));
  s.report_latency_ms_max = static_cast<float>(report_latency.max());
  for (const drivers::DriverCounter& c : source->counters()) {
    s.counter_name.push_back(c.name);
    s.counter_value.push_back(c.value);
    s.counter_is_gauge.push_back(c.gauge);
  }
  const std::pair<const char*, const std::atomic<std::int64_t>*> processing_counters[] = {
      {"processing.frames_discarded", &frames_discarded},
      {"processing.gap_frames", &gap_frames},
      {"processing.samples_replaced", &samples_replaced},
      {"processing.crank_unknown_frames", &crank_unknown_frames}};
  for (const auto& [name, value] : processing_counters) {
    s.counter_name.push_back(name);
    s.counter_value.push_back(value->load(std::memory_order_relaxed));
    s.counter_is_gauge.push_back(false);
  }
  const std::int64_t now = drivers::wall_utime();
  for (const auto& [name, utime] : calibrated_utime) {
    s.counter_name.push_back(name);
    s.counter_value.push_back(utime > 0 ? (now - utime) / 86'400'000'000 : -1);
    s.counter_is_gauge.push_back(true);
  }
  publisher->add_status(s);
  s.nthreads = static_cast<std::int16_t>(s.thread_name.size());
  s.nrings = static_cast<std::int16_t>(s.ring_name.size());
  s.ncounters = static_cast<std::int16_t>(s.counter_name.size());
  return s;
}

// The calibration ages that go out with the status: the microphones' when they come from a front-end `noisemon
// calibrate` writes the sensitivities of (an audio interface, the comedi card); the pressure chain's zero and gain on
// the comedi card, or wherever the history holds them (the virtual engine's chain is calibrated too). A charge chain
// has no zero to calibrate.
void Pipeline::Impl::read_calibrations() {
  if (config.calibration_history.empty()) return;
  std::size_t skipped = 0;
  const std::vector<CalibrationRecord> history = read_calibration_history(config.calibration_history, &skipped);
  if (skipped > 0)
    spdlog::warn("{}: {} rows that are not calibrations were skipped", config.calibration_history, skipped);
  if (config.microphones == "alsa" || config.source == "comedi") {
    const std::vector<std::int64_t> mics = last_calibrations(history, info.mic_count);
    for (std::size_t m = 0; m < mics.size(); ++m)
      calibrated_utime.emplace_back("calibration.mic" + std::to_string(m + 1) + ".age_days", mics[m]);
  }
  const bool charge = config.comedi.pressure.sensitivity_pc_per_bar > 0;
  for (const char* step : {"zero", "gain"}) {
    const CalibrationRecord* last = last_pressure_calibration(history, step);
    if ((config.source == "comedi" && !(charge && std::string(step) == "zero")) || last)
      calibrated_utime.emplace_back(std::string("calibration.pressure_") + step + ".age_days", last ? last->utime : 0);
  }
}

void Pipeline::Impl::remember_for_statistics(const noisemon::cycle_report_t& m) {
  if (config.stats_window_cycles <= 0) return;
  stats_window.push_back(m);
  if (static_cast<std::int64_t>(stats_window.size()) > config.stats_window_cycles) stats_window.pop_front();
}

// Once a second, with the status: the statistics of the window's reports (none before the first report).
void Pipeline::Impl::publish_statistics() {
  if (config.stats_window_cycles <= 0 || stats_window.empty()) return;
  CycleStatisticsAccumulator window;
  for (const noisemon::cycle_report_t& m : stats_window) window.add(m);
  const std::int64_t utime = drivers::wall_utime();
  publisher->publish(config.lcm.stats_channel, to_message(window.result(), config.stats_window_cycles, utime), utime);
}

void Pipeline::Impl::run_publishing(std::atomic<std::int64_t>& published) {
  Stat latency, processing;
  LatencyWindow report_latency;
  auto next_status = Clock::now() + std::chrono::seconds(1);
  // The session (time base, microphones) goes out before any raw block, then each second for late loggers.
  auto publish_session = [&] {
    if (!config.raw_streams()) return;  // the session describes the raw streams
    const noisemon::session_t session = to_message(info, source->name(), drivers::wall_utime());
    publisher->publish(config.lcm.session_channel, session, session.utime);
  };
  publish_session();
  while (true) {
    publishing_beat_ns.store(now_ns(), std::memory_order_relaxed);
    bool any = false;
    CycleReport r;
    while (report_ring.read(&r, 1) == 1) {
      const noisemon::cycle_report_t msg = to_message(r);
      publisher->publish(config.lcm.report_channel, msg, r.window_end_utime);
      if (r.input_ns > 0) report_latency.add(1e-6 * static_cast<double>(now_ns() - r.input_ns));
      remember_for_statistics(msg);
      ++published;
      latency.add(1e-3 * static_cast<double>(drivers::wall_utime() - r.window_end_utime));
      processing.add(r.processing_ms);
      if (options.on_report) options.on_report(r);
      any = true;
    }
    RawItem raw;
    for (int i = 0; i < 64 && raw_ring.read(&raw, 1) == 1; ++i) {
      const noisemon::raw_block_t msg = to_message(raw.block, raw.stream, info.epoch_utime);
      publisher->publish(config.lcm.raw_channel, msg, msg.utime);
      any = true;
    }
    drivers::OperatingPoint op;
    while (op_publish_ring.read(&op, 1) == 1) {
      const noisemon::operating_point_t msg = to_message(op);
      publisher->publish(config.lcm.operating_point_channel, msg, msg.utime);
    }
    const bool done = processing_thread.state() != drivers::ThreadState::kRunning;  // its last reports are queued
    if (Clock::now() >= next_status || (done && !any)) {
      publish_session();
      const noisemon::status_t s = make_status(published.load(), latency, processing, report_latency);
      publisher->publish(config.lcm.status_channel, s, s.utime);
      publish_statistics();
      latency = Stat{};
      processing = Stat{};
      report_latency.clear();
      next_status += std::chrono::seconds(1);
    }
    if (!any) {
      if (done && report_ring.empty() && raw_ring.empty()) break;
      report_wakeup.wait_for(std::chrono::microseconds(500));  // a queued report wakes it at once
    }
  }
  publisher->flush();
}

Pipeline::Pipeline(const Config& config, std::unique_ptr<drivers::Source> source, std::shared_ptr<Publisher> publisher,
                   PipelineOptions options)
    : impl_(std::make_unique<Impl>(config, std::move(source), std::move(publisher), std::move(options))) {
  if (!impl_->publisher) throw std::invalid_argument("Pipeline: a publisher is required");
}

Pipeline::~Pipeline() { stop(); }

void Pipeline::start() {
  Impl& d = *impl_;
  d.started = Clock::now();
  // spdlog's registry is a static made on first use: make it here, before the threads that log. (Its guard lives
  // in libspdlog, which ThreadSanitizer does not see into: two threads' first logs were reported as a race.)
  spdlog::default_logger_raw();
  drivers::Streams streams{&d.pressure_ring, &d.mic_ring, &d.op_ring, &d.angle_ring, d.crank_reference.get()};
  // Processing first: the publishing thread ends once the processing thread no longer runs.
  d.processing_thread.start("nm-processing", d.config.threads.processing,
                            [this](const std::atomic<bool>& drain) { impl_->run_processing(drain); });
  d.publishing_thread.start("nm-publish", d.config.threads.publishing,
                            [this](const std::atomic<bool>&) { impl_->run_publishing(published_); });
  try {
    d.source->start(streams);
  } catch (...) {
    d.processing_thread.stop();
    d.publishing_thread.join();
    throw;
  }
  if (!d.options.quiet)
    spdlog::info("source '{}' started: {} microphones, acoustic delay {:.2f} ms", d.source->name(), d.info.mic_count,
                 1e3 * d.info.acoustic_delay_s);
}

void Pipeline::stop() {
  Impl& d = *impl_;
  if (!d.processing_thread.joinable() && !d.publishing_thread.joinable()) return;
  d.source->stop();
  d.processing_thread.stop();
  d.publishing_thread.join();
  if (!d.options.quiet)
    spdlog::info("stopped: {} cycles published, {} dropped", published_.load(), d.cycles_dropped.load());
}

bool Pipeline::ready() const { return impl_->source->running(); }

bool Pipeline::healthy(double max_beat_age_s) const {
  const Impl& d = *impl_;
  for (const auto& t : d.source->thread_status())
    if (t.state != drivers::ThreadState::kRunning) return false;
  const std::int64_t now = Impl::now_ns(), max_age = static_cast<std::int64_t>(max_beat_age_s * 1e9);
  for (const auto* beat : {&d.processing_beat_ns, &d.publishing_beat_ns})
    if (now - beat->load(std::memory_order_relaxed) > max_age) return false;
  return d.processing_thread.state() == drivers::ThreadState::kRunning &&
         d.publishing_thread.state() == drivers::ThreadState::kRunning;
}

std::int64_t Pipeline::cycles_dropped() const { return impl_->cycles_dropped.load(); }

bool Pipeline::finished() const {
  const Impl& d = *impl_;
  for (const drivers::WorkerThread* t : {&d.processing_thread, &d.publishing_thread})
    if (t->state() == drivers::ThreadState::kFailed) return true;
  for (const auto& t : d.source->thread_status())
    if (t.state == drivers::ThreadState::kFailed) return true;
  return d.source->exhausted() || (d.config.cycles > 0 && published_.load() >= d.config.cycles);
}

std::string Pipeline::failure() const {
  const Impl& d = *impl_;
  if (const drivers::DriverThreadStatus t = d.processing_thread.status(); t.state == drivers::ThreadState::kFailed)
    return "processing thread: " + t.error;
  if (const drivers::DriverThreadStatus t = d.publishing_thread.status(); t.state == drivers::ThreadState::kFailed)
    return "publishing thread: " + t.error;
  for (const auto& t : d.source->thread_status())
    if (t.state == drivers::ThreadState::kFailed) return "driver thread '" + t.name + "': " + t.error;
  return {};
}

}  // namespace noisemon::daemon
