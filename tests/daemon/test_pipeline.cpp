// The daemon's pipeline in-process: an in-memory source feeds it, the in-memory publisher keeps what it publishes.
// Its reports are the cycle processor's driven by hand on the same blocks (a second path), byte for byte whatever
// the threads' timing; stop() drains every complete cycle; the cycle limit, the status message and the dropped
// cycles; a failing source ends it with the failure's text; a source that runs out finishes it; a slow publisher
// loses nothing when the pipeline is lossless; the raw streams go out as they came in.
#include "daemon/pipeline.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <numbers>
#include <optional>
#include <thread>
#include <vector>

#include "daemon/calibration_history.hpp"
#include "daemon/cycle_processor.hpp"
#include "daemon/memory_publisher.hpp"
#include "daemon/report_messages.hpp"
#include "drivers/crank_reference.hpp"
#include "drivers/worker_thread.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/unique_temp.hpp"

namespace noisemon::daemon {
namespace {

namespace nd = noisemon::drivers;
using Clock = std::chrono::steady_clock;

constexpr std::int64_t kEpoch = 1'000'000;

nd::StreamInfo one_mic() {
  nd::StreamInfo i;
  i.epoch_utime = kEpoch;
  i.mic_count = 1;
  i.mic_positions_m = {{0, 0, 1.75}};
  i.radius_m = 1.75;
  return i;
}

struct Block {
  std::int8_t stream;  // raw_block_t::STREAM_*
  nd::SampleBlock block;
};

// A 1 kHz tone in the pressure and, scaled, at the one microphone; the crank angle runs through a 720-deg cycle
// every `cycle` frames. Blocks of 200 frames, pressure and microphone alternating.
std::vector<Block> tone(int cycles, int cycle = 1000) {
  std::vector<Block> out;
  for (int first = 0; first < cycles * cycle; first += 200) {
    Block p{noisemon::raw_block_t::STREAM_PRESSURE, {}}, m{noisemon::raw_block_t::STREAM_MICS, {}};
    p.block.first_index = m.block.first_index = first;
    p.block.frames = m.block.frames = 200;
    p.block.channels = 2;
    m.block.channels = 1;
    for (int f = 0; f < 200; ++f) {
      const int k = first + f;
      const double x = 1e3 * std::sin(2 * std::numbers::pi * 1000.0 * k / 40000.0);
      p.block.data[2 * f] = 1e5 + x;
      p.block.data[2 * f + 1] = -360.0 + 720.0 * (k % cycle) / cycle;
      m.block.data[f] = 1e-3 * x;
    }
    out.push_back(p);
    out.push_back(m);
  }
  return out;
}

nd::OperatingPoint operating_point() {
  nd::OperatingPoint op;
  op.utime = kEpoch;
  op.speed_rpm = 2400;
  op.load_nm = 30;
  op.soi_deg_btdc = 8;
  op.rail_pressure_bar = 900;
  return op;
}

// An in-memory source: the operating point, then the blocks in order, waiting while a ring is full. Finite: it
// reports exhausted() after the last block; otherwise it idles like a live source until stopped.
class MemorySource final : public nd::Source {
 public:
  struct Script {
    std::vector<Block> blocks;
    bool finite = false;
    std::size_t fail_at = SIZE_MAX;  // throws "device unplugged" instead of delivering this block
    double tdc_deg = 0.0;            // the session's (a log's producer's) firing TDC
    double sync_angle_deg = NAN;     // a microphone front-end's sync pulse angle (StreamInfo::sync_angle_deg)
  };
  explicit MemorySource(Script script) : script_(std::move(script)) {}
  ~MemorySource() override { stop(); }

  std::string name() const override { return "memory"; }
  nd::StreamInfo info() const override {
    nd::StreamInfo i = one_mic();
    i.tdc_deg = script_.tdc_deg;
    i.sync_angle_deg = script_.sync_angle_deg;
    return i;
  }
  void start(const nd::Streams& s) override {
    reference_ = s.crank_reference;
    worker_.start("nm-memory", {}, [this, s](const std::atomic<bool>& stop) { run(s, stop); });
  }
  void stop() override { worker_.stop(); }
  bool running() const override { return worker_.blocks_written() > 0; }
  bool exhausted() const override { return exhausted_.load(); }
  std::vector<nd::DriverThreadStatus> thread_status() const override { return {worker_.status()}; }
  std::vector<nd::DriverCounter> counters() const override {
    return {{"memory.blocks", static_cast<std::int64_t>(worker_.blocks_written())}};
  }
  bool delivered() const { return delivered_.load(); }
  const nd::CrankReference* reference() const { return reference_; }

 private:
  void run(const nd::Streams& s, const std::atomic<bool>& stop) {
    (void)s.operating_point->push(operating_point());
    while (!s.operating_point->empty() && !stop) std::this_thread::sleep_for(std::chrono::microseconds(100));
    for (std::size_t i = 0; i < script_.blocks.size(); ++i) {
      if (i == script_.fail_at) throw std::runtime_error("device unplugged");
      const Block& b = script_.blocks[i];
      nd::BlockRing& ring = b.stream == noisemon::raw_block_t::STREAM_PRESSURE ? *s.pressure : *s.mics;
      while (ring.size() == ring.capacity()) {
        if (stop) return;
        std::this_thread::sleep_for(std::chrono::microseconds(100));
      }
      (void)ring.push(b.block);
      worker_.add_blocks_written();
    }
    delivered_ = true;
    if (script_.finite) {
      exhausted_ = true;
      return;
    }
    while (!stop) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }

  Script script_;
  const nd::CrankReference* reference_ = nullptr;
  std::atomic<bool> delivered_{false}, exhausted_{false};
  nd::WorkerThread worker_{"memory.feed"};
};

// The second path: the cycle processor driven by hand, block by block, as the pipeline configures it.
struct Reference {
  std::vector<noisemon::cycle_report_t> reports;
  ProcessorCounters counters;
};

Reference by_hand(const Config& c, const std::vector<Block>& blocks) {
  ProcessorConfig pc;
  pc.model = c.model;
  pc.acoustic_delay_s = c.acoustic_delay_s;
  pc.engine = c.engine;
  pc.fifo_seconds = std::max(1.0, 2 * c.ring_seconds);
  pc.mic_low_db = c.mic_low_db;
  Reference ref;
  CycleProcessor p(pc, one_mic(), [&](const CycleReport& r) { ref.reports.push_back(to_message(r)); });
  p.set_operating_point(operating_point());
  for (const Block& b : blocks) {
    if (b.stream == noisemon::raw_block_t::STREAM_PRESSURE)
      p.add_pressure(b.block);
    else
      p.add_mics(b.block);
    p.process();
  }
  ref.counters = p.counters();
  return ref;
}

std::vector<char> bytes_without_cpu_time(noisemon::cycle_report_t m) {
  m.processing_ms = 0;  // the CPU time the cycle took: a measurement of this run, not of the engine
  std::vector<char> b(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

void expect_same_reports(const std::vector<Published<noisemon::cycle_report_t>>& got,
                         const std::vector<noisemon::cycle_report_t>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(got[i].channel, "NOISEMON_CYCLE");
    EXPECT_EQ(bytes_without_cpu_time(got[i].message), bytes_without_cpu_time(want[i])) << "cycle " << i;
  }
}

// Waits until `done` or the deadline; false on the deadline. The longest of these runs (ASlowPublisherLosesNothing:
// 600 reports at 2 ms each) takes about 1.5 s in the normal build.
template <class Condition>
bool wait_for(Condition done, std::chrono::milliseconds limit = noisemon::test::allowance(std::chrono::seconds(3))) {
  const auto deadline = Clock::now() + limit;
  while (!done()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

Config quiet_config() {
  Config c;
  c.lcm.publish_raw = false;
  c.lcm.publish_operating_point = false;
  return c;
}

}  // namespace

TEST(Pipeline, StopDrainsEveryCompleteCycleAndTheReportsAreTheProcessorsByHand) {
  const std::vector<Block> blocks = tone(40);
  const Config config = quiet_config();
  auto source = std::make_unique<MemorySource>(MemorySource::Script{blocks});
  const MemorySource* feed = source.get();
  auto out = std::make_shared<MemoryPublisher>();
  Pipeline pipeline(config, std::move(source), out);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return feed->delivered(); }));
  EXPECT_FALSE(pipeline.finished());  // a live source never runs out
  pipeline.stop();                    // blocks may still wait in the rings: stop processes them all
  // Boundaries at frames 1000, 2000, ... 39000: 38 closed cycles (the one from 39000 never closes).
  const Reference ref = by_hand(config, blocks);
  ASSERT_EQ(ref.reports.size(), 38u);
  expect_same_reports(out->reports(), ref.reports);
  EXPECT_EQ(pipeline.cycles_published(), 38);
  EXPECT_EQ(pipeline.cycles_dropped(), 0);
  for (const auto& r : out->reports()) {
    EXPECT_EQ(r.message.load_nm, 30);  // the source's operating point reached every cycle
    EXPECT_GT(r.utime, r.message.utime) << "a report is stamped with the end of its cycle's window";
  }
  EXPECT_TRUE(pipeline.failure().empty());
}

// A source that asks for its sync pulse's crank instants (a microphone front-end aligning its clock) gets them from
// the pipeline, read off the crank angle it delivers: in tone(), 0.72 deg a frame from -360 at each 1000th frame,
// so 90 deg (and -270) are passed at frames 625 and 125 of each cycle.
TEST(Pipeline, ASourceWithASyncPulseGetsTheInstantsTheCrankPassesItsAngle) {
  MemorySource::Script script{tone(40)};
  script.sync_angle_deg = 90.0;
  auto source = std::make_unique<MemorySource>(script);
  const MemorySource* feed = source.get();
  Pipeline pipeline(quiet_config(), std::move(source), std::make_shared<MemoryPublisher>());
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return feed->delivered(); }));
  pipeline.stop();
  ASSERT_NE(feed->reference(), nullptr);
  for (double frame = 125.0; frame < 7900.0; frame += 500.0)
    EXPECT_NEAR(feed->reference()->nearest(frame / 40000.0).instant_s * 40000.0, frame, 1e-6) << frame;

  auto plain = std::make_unique<MemorySource>(MemorySource::Script{tone(2)});
  const MemorySource* none = plain.get();
  Pipeline without(quiet_config(), std::move(plain), std::make_shared<MemoryPublisher>());
  without.start();
  ASSERT_TRUE(wait_for([&] { return none->delivered(); }));
  without.stop();
  EXPECT_EQ(none->reference(), nullptr);  // no sync pulse asked for: none made
}

TEST(Pipeline, TheCycleLimitFinishesItWithExactlyThatManyReports) {
  Config config = quiet_config();
  config.cycles = 5;
  auto out = std::make_shared<MemoryPublisher>();
  Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{tone(40)}), out);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return pipeline.finished(); }));
  pipeline.stop();
  EXPECT_EQ(pipeline.cycles_published(), 5);
  ASSERT_EQ(out->reports().size(), 5u);
  EXPECT_EQ(out->reports().back().message.cycle, 4);
}

TEST(Pipeline, ASourceThatRunsOutFinishesItAndEveryCycleIsReported) {
  const std::vector<Block> blocks = tone(30);
  const Config config = quiet_config();
  auto out = std::make_shared<MemoryPublisher>();
  Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{blocks, true}), out);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return pipeline.finished(); }));
  pipeline.stop();
  expect_same_reports(out->reports(), by_hand(config, blocks).reports);
}

TEST(Pipeline, LostSamplesDropTheirCyclesAndTheStatusSaysSo) {
  std::vector<Block> blocks = tone(40);
  blocks.erase(blocks.begin() + 100);  // the pressure of frames 10000 .. 10200: lost on the way
  const Config config = quiet_config();
  const Reference ref = by_hand(config, blocks);
  ASSERT_GE(ref.counters.cycles_dropped, 1);
  auto out = std::make_shared<MemoryPublisher>();
  Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{blocks, true}), out);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return pipeline.finished(); }));
  pipeline.stop();
  expect_same_reports(out->reports(), ref.reports);
  EXPECT_EQ(pipeline.cycles_dropped(), ref.counters.cycles_dropped);
  EXPECT_EQ(pipeline.cycles_published() + pipeline.cycles_dropped(), 38);
  // The last status, published when the processing has ended, holds the final counts.
  const auto statuses = out->statuses();
  ASSERT_FALSE(statuses.empty());
  const noisemon::status_t& s = statuses.back().message;
  EXPECT_EQ(statuses.back().channel, "NOISEMON_STATUS");
  EXPECT_EQ(s.source, "memory");
  EXPECT_EQ(s.cycles_published, pipeline.cycles_published());
  EXPECT_EQ(s.cycles_dropped, ref.counters.cycles_dropped);
  const auto counter = [&](const std::string& name) -> std::optional<std::int64_t> {
    for (int i = 0; i < s.ncounters; ++i)
      if (s.counter_name[i] == name) return s.counter_value[i];
    return std::nullopt;
  };
  EXPECT_EQ(counter("memory.blocks"), static_cast<std::int64_t>(blocks.size()));
  EXPECT_EQ(counter("processing.gap_frames"), ref.counters.gap_frames);
  EXPECT_GE(ref.counters.gap_frames, 200);
  // Every report's latency (its last block taken by the processing thread -> published) is in one status.
  float latency_max = 0.f;
  for (const auto& st : statuses) {
    EXPECT_LE(st.message.report_latency_ms_p50, st.message.report_latency_ms_p99);
    EXPECT_LE(st.message.report_latency_ms_p99, st.message.report_latency_ms_max);
    EXPECT_GE(st.message.report_latency_ms_p50, 0.f);
    latency_max = std::max(latency_max, st.message.report_latency_ms_max);
  }
  EXPECT_GT(latency_max, 0.f);
  ASSERT_EQ(s.nthreads, 3);
  EXPECT_EQ(s.thread_name[0], "memory.feed");
  EXPECT_EQ(s.thread_name[1], "processing");
}

// A microphone calibrated three days and an hour ago (and ten days ago before that, and a line a person mistyped):
// the status says 3 days for it, -1 (never) for none calibrated; and nothing when the microphones are the sim's.
TEST(Pipeline, TheStatusCarriesEachMicrophonesCalibrationAge) {
  const std::string history = noisemon::test::unique_temp("cell.calibrations.csv").string();
  const std::int64_t day = 86'400'000'000, now = noisemon::drivers::wall_utime();
  auto calibrated = [&](std::int64_t utime, const std::string& serial, double mv_per_pa) {
    noisemon::daemon::CalibrationRecord r;
    r.utime = utime, r.microphone = 1, r.serial = serial, r.sensitivity = mv_per_pa;
    noisemon::daemon::append_calibration(history, r);
  };
  calibrated(now - 10 * day, "", 50.0);
  calibrated(now - 3 * day - day / 24, "3021456", 50.2);
  std::ofstream(history, std::ios::app) << "2026-12-01,one,x,y\n";
  std::size_t skipped = 0;
  const auto rows = noisemon::daemon::read_calibration_history(history, &skipped);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(skipped, 1u);
  EXPECT_EQ(rows[1].serial, "3021456");
  EXPECT_DOUBLE_EQ(rows[1].sensitivity, 50.2);

  auto last_status = [&](const Config& config) {
    auto out = std::make_shared<MemoryPublisher>();
    Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{tone(10), true}), out);
    pipeline.start();
    EXPECT_TRUE(wait_for([&] { return pipeline.finished(); }));
    pipeline.stop();
    return out->statuses().back().message;
  };
  auto counter = [](const noisemon::status_t& s, const std::string& name) -> std::optional<std::int64_t> {
    for (int i = 0; i < s.ncounters; ++i)
      if (s.counter_name[i] == name) return s.counter_value[i];
    return std::nullopt;
  };
  Config config = quiet_config();
  config.microphones = "alsa";
  config.calibration_history = history;
  EXPECT_EQ(counter(last_status(config), "calibration.mic1.age_days"), 3);
  std::ofstream(history, std::ios::trunc);
  EXPECT_EQ(counter(last_status(config), "calibration.mic1.age_days"), -1);
  config.microphones.clear();  // the sim's microphones: nothing to calibrate
  EXPECT_EQ(counter(last_status(config), "calibration.mic1.age_days"), std::nullopt);
  EXPECT_EQ(counter(last_status(config), "calibration.pressure_zero.age_days"), std::nullopt);  // nor a pressure row

  // The pressure chain's zero, five days ago, and a gain twelve days ago: each step's age (any source that has them).
  auto pressure = [&](std::int64_t utime, const char* step) {
    noisemon::daemon::CalibrationRecord r;
    r.utime = utime, r.microphone = 0, r.pressure_step = step, r.sensitivity = 100.0, r.reference_bar = 1.013;
    noisemon::daemon::append_calibration(history, r);
  };
  pressure(now - 12 * day, "gain");
  pressure(now - 20 * day, "zero");
  pressure(now - 5 * day - day / 24, "zero");
  const noisemon::status_t with_pressure = last_status(config);
  EXPECT_EQ(counter(with_pressure, "calibration.pressure_zero.age_days"), 5);
  EXPECT_EQ(counter(with_pressure, "calibration.pressure_gain.age_days"), 12);
}

TEST(Pipeline, AFailingSourceFinishesItWithTheFailuresText) {
  const std::vector<Block> blocks = tone(40);
  const Config config = quiet_config();
  auto out = std::make_shared<MemoryPublisher>();
  Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{blocks, false, 60}), out);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return pipeline.finished(); }));
  EXPECT_EQ(pipeline.failure(), "driver thread 'memory.feed': device unplugged");
  pipeline.stop();
  // What came before the failure is still processed and published: frames up to 6000, cycles up to 5000.
  const Reference ref = by_hand(config, std::vector<Block>(blocks.begin(), blocks.begin() + 60));
  EXPECT_EQ(ref.reports.size(), 4u);
  expect_same_reports(out->reports(), ref.reports);
}

TEST(Pipeline, ASlowPublisherLosesNothingWhenLossless) {
  // More cycles than the report queue holds (256), published far slower than they are processed.
  class SlowPublisher final : public Publisher {
   public:
    void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                       std::int64_t utime) override {
      if (decode_as<noisemon::cycle_report_t>(data, size)) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      kept.publish_bytes(channel, data, size, utime);
    }
    MemoryPublisher kept;
  };
  const std::vector<Block> blocks = tone(600, 400);
  const Config config = quiet_config();
  auto out = std::make_shared<SlowPublisher>();
  PipelineOptions options;
  options.lossless = std::getenv("NOISEMON_TEST_LOSSY") == nullptr;  // set it to see this test fail
  Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{blocks, true}), out, options);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return pipeline.finished(); }));
  pipeline.stop();
  EXPECT_EQ(pipeline.cycles_dropped(), 0);
  expect_same_reports(out->kept.reports(), by_hand(config, blocks).reports);
  EXPECT_EQ(out->kept.reports().size(), 598u);
}

TEST(Pipeline, TheRawStreamsAndTheSessionGoOutAsTheyCameIn) {
  const std::vector<Block> blocks = tone(10);
  Config config;  // publishes the raw streams and operating points
  auto out = std::make_shared<MemoryPublisher>();
  Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{blocks, true}), out);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return pipeline.finished(); }));
  pipeline.stop();
  const auto sessions = out->sessions();
  ASSERT_FALSE(sessions.empty());
  EXPECT_EQ(sessions.front().channel, "NOISEMON_SESSION");
  EXPECT_EQ(sessions.front().message.epoch_utime, kEpoch);
  EXPECT_EQ(sessions.front().message.nmics, 1);
  EXPECT_EQ(sessions.front().message.source, "memory");
  const auto raw = out->raw_blocks();
  ASSERT_EQ(raw.size(), blocks.size());
  std::size_t pressure = 0, mics = 0;
  for (const auto& r : raw) {
    // Each stream in its order; the two streams interleave as the processing took them.
    const bool is_pressure = r.message.stream == noisemon::raw_block_t::STREAM_PRESSURE;
    const nd::SampleBlock& want = blocks[2 * (is_pressure ? pressure++ : mics++) + (is_pressure ? 0 : 1)].block;
    EXPECT_EQ(r.channel, "NOISEMON_RAW");
    EXPECT_EQ(r.message.first_index, want.first_index);
    EXPECT_EQ(r.utime, kEpoch + want.first_index * 25);
    EXPECT_EQ(r.message.data, std::vector<double>(want.data, want.data + want.frames * want.channels));
  }
  const auto ops = out->operating_points();
  ASSERT_EQ(ops.size(), 1u);
  EXPECT_EQ(ops[0].message.load_nm, 30);
  EXPECT_EQ(ops[0].channel, "NOISEMON_OP");
}

// The rolling statistics: once a second and when the pipeline finishes, the statistics of the last
// stats_window_cycles reports on their own channel, as computed here from the published reports themselves
// (energy mean of the levels, sample standard deviation, min and max; settling cycles counted, not averaged).
TEST(Pipeline, TheRollingStatisticsAreThoseOfTheLastWindowOfPublishedReports) {
  std::vector<Block> blocks = tone(80);  // the lowest bands' filters have settled for the last ten cycles
  for (Block& b : blocks)                // a level that changes from cycle to cycle: 1 + 0.3 sin(cycle)
    for (std::uint32_t f = 0; f < b.block.frames; ++f) {
      const double gain = 1.0 + 0.3 * std::sin(static_cast<double>((b.block.first_index + f) / 1000));
      double& x = b.block.data[f * b.block.channels];
      x = b.stream == noisemon::raw_block_t::STREAM_MICS ? x * gain : 1e5 + (x - 1e5) * gain;
    }
  Config config = quiet_config();
  config.stats_window_cycles = 10;
  auto out = std::make_shared<MemoryPublisher>();
  Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{blocks, true}), out);
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return pipeline.finished(); }));
  pipeline.stop();
  const auto reports = out->reports();
  const auto stats = out->statistics();
  ASSERT_GE(reports.size(), 20u);
  ASSERT_FALSE(stats.empty());
  const noisemon::cycle_stats_t& s = stats.back().message;  // the last: after every report
  EXPECT_EQ(stats.back().channel, "NOISEMON_STATS");
  EXPECT_EQ(s.window_cycles, 10);
  ASSERT_EQ(s.cycles, 10);
  double energy = 0, sum = 0, sum_sq = 0, lo = INFINITY, hi = -INFINITY, db_sum = 0, db_sq = 0;
  int valid = 0;
  for (std::size_t i = reports.size() - 10; i < reports.size(); ++i) {
    const noisemon::cycle_report_t& r = reports[i].message;
    constexpr int kNotValid = static_cast<int>(noisemon::cycle_report_t::CYCLE_SETTLING) |
                              static_cast<int>(noisemon::cycle_report_t::CYCLE_GAP);
    if (r.flags & kNotValid) continue;
    ++valid;
    energy += std::pow(10.0, r.lpa_measured_db / 10);
    db_sum += r.lpa_measured_db;
    db_sq += r.lpa_measured_db * r.lpa_measured_db;
    sum += r.peak_pressure_bar;
    sum_sq += r.peak_pressure_bar * r.peak_pressure_bar;
    lo = std::min(lo, r.peak_pressure_bar);
    hi = std::max(hi, r.peak_pressure_bar);
  }
  ASSERT_GE(valid, 5);
  EXPECT_EQ(s.valid, valid);
  EXPECT_EQ(s.flagged, 10 - valid);
  const auto at = [&s](const std::string& name) {
    for (int i = 0; i < s.nscalars; ++i)
      if (s.name[i] == name) return i;
    ADD_FAILURE() << "no " << name;
    return 0;
  };
  const int lpa = at("lpa_measured_db"), peak = at("peak_pressure_bar");
  EXPECT_TRUE(s.level[lpa]);
  EXPECT_NEAR(s.mean[lpa], 10 * std::log10(energy / valid), 1e-9);
  const double db_mean = db_sum / valid;  // a level's spread is that of its dB values
  EXPECT_NEAR(s.stddev[lpa], std::sqrt((db_sq - valid * db_mean * db_mean) / (valid - 1)), 1e-6);
  EXPECT_GT(s.stddev[lpa], 0.5);  // the level did change from cycle to cycle
  const double mean = sum / valid;
  EXPECT_NEAR(s.mean[peak], mean, 1e-9);
  EXPECT_NEAR(s.stddev[peak], std::sqrt((sum_sq - valid * mean * mean) / (valid - 1)), 1e-6);
  EXPECT_NEAR(s.cov[peak], s.stddev[peak] / mean, 1e-9);
  EXPECT_EQ(s.min[peak], lo);
  EXPECT_EQ(s.max[peak], hi);
  // A window of 0: no statistics at all.
  config.stats_window_cycles = 0;
  auto none = std::make_shared<MemoryPublisher>();
  Pipeline quiet(config, std::make_unique<MemorySource>(MemorySource::Script{tone(10), true}), none);
  quiet.start();
  ASSERT_TRUE(wait_for([&] { return quiet.finished(); }));
  quiet.stop();
  EXPECT_TRUE(none->statistics().empty());
}

// The TDC a log's producer used (its session's tdc_deg) is what a replay uses unless [combustion] tdc_deg is given:
// then the figures are the live ones. The session the pipeline publishes says which TDC its processing uses.
TEST(Pipeline, TheSessionsTdcIsUsedUnlessTheConfigurationSetsOne) {
  for (const bool configured : {false, true}) {
    Config config = quiet_config();
    config.lcm.publish_raw = true;
    config.tdc_deg_configured = configured;  // [combustion] tdc_deg = 0
    auto out = std::make_shared<MemoryPublisher>();
    Pipeline pipeline(config, std::make_unique<MemorySource>(MemorySource::Script{tone(12), false, SIZE_MAX, -2.6}),
                      out);
    pipeline.start();
    ASSERT_TRUE(wait_for([&] { return out->reports().size() >= 5; }));
    pipeline.stop();
    const double want = configured ? 0.0 : -2.6;
    for (const auto& r : out->reports()) EXPECT_EQ(r.message.tdc_deg, want) << configured;
    ASSERT_FALSE(out->sessions().empty());
    EXPECT_EQ(out->sessions().front().message.tdc_deg, want) << configured;
  }
}

}  // namespace noisemon::daemon
