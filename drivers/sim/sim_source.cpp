// The virtual engine source: three driver threads paced to the wall clock around the generators of
// sim_generators.hpp. Each thread computes its stream up to the end of the next ~5 ms chunk of simulated
// time, then sleeps until that instant arrives on the wall clock; ring writes never wait (a full ring drops the
// block and counts an overrun).
#include "drivers/sim/sim_source.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <thread>

#include "drivers/mic_positions.hpp"
#include "drivers/sim/sim_generators.hpp"
#include "drivers/sim/sim_stopped.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers::sim {

SimConfig with_ideal_cell(SimConfig config) {
  config.pressure_chain = model::engine::PressureChainConfig::ideal();
  config.mic_chain = model::engine::MicChainConfig::ideal();
  config.gas_ringing = model::engine::GasRingingParams::off();
  return config;
}

namespace {

constexpr double kChunkS = 0.005;               // generation chunk of the sample streams
constexpr double kOperatingPointPeriodS = 0.1;  // 10 Hz
constexpr double kMaxCatchUpS = 0.05;           // simulated time per loop pass when behind (keeps stop() prompt)
constexpr double kMaxLeadS = 0.05;              // unpaced: how far a stream may run ahead of the slowest
constexpr std::size_t kUnpacedRoomBlocks = 16;  // unpaced: free ring slots a pass needs (a pass writes a few blocks)

void validate(const SimConfig& c) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("sim source: " + what); };
  if (!(c.speed_rpm > 0.0 && c.speed_rpm <= 10000.0)) fail("speed_rpm must be in (0, 10000]");
  if (!(c.speed_fluctuation >= 0.0 && c.speed_fluctuation < 0.2)) fail("speed_fluctuation must be in [0, 0.2)");
  if (!(c.cycle_variation >= 0.0 && c.cycle_variation < 0.2)) fail("cycle_variation must be in [0, 0.2)");
  if (!(c.soi_deg_btdc >= 0.0 && c.soi_deg_btdc <= 60.0)) fail("soi_deg_btdc must be in [0, 60]");
  if (!(c.load_nm >= 0.0) || !(c.full_load_nm > 0.0)) fail("load_nm must be >= 0 and full_load_nm > 0");
  if (!(c.encoder_resolution_deg >= 0.01 && c.encoder_resolution_deg <= 6.0))
    fail("encoder_resolution_deg must be in [0.01, 6]");
  if (const double counts = 360.0 / c.encoder_resolution_deg; std::abs(counts - std::round(counts)) > 1e-6)
    fail("encoder_resolution_deg must divide 360 (a whole number of counts per revolution)");
  if (c.mic_count == 0 || c.mic_count > SampleBlock::kMaxChannels) fail("mic_count must be in [1, 16]");
  if (c.mic_positions_m.empty() && c.mic_count > thesis_mic_positions().size())
    fail("mic_positions_m must be given for more than 10 microphones");
  if (!c.mic_positions_m.empty() && c.mic_positions_m.size() != c.mic_count)
    fail("mic_positions_m must have mic_count entries");
  if (!(c.radius_m > 0.0) || !(c.speed_of_sound_m_s > 0.0)) fail("radius_m and speed_of_sound_m_s must be positive");
  if (!(c.mic_rate_hz >= 8000.0 && c.mic_rate_hz == std::round(c.mic_rate_hz)))
    fail("mic_rate_hz must be a whole number >= 8000");
  if (!(c.mic_gain_spread_db >= 0.0 && c.mic_gain_spread_db <= 6.0)) fail("mic_gain_spread_db must be in [0, 6]");
  if (!(c.static_pressure_bar >= 0.0 && c.static_pressure_bar <= 1000.0))
    fail("static_pressure_bar must be in [0, 1000]");
  if (!(c.gas_ringing.gain_s >= 0.0 && c.gas_ringing.gain_s <= 1e-3) ||
      !(c.gas_ringing.decay_s > 0.0 && c.gas_ringing.decay_s <= 0.1))
    fail("gas ringing: gain must be in [0, 1 ms] and decay in (0, 100 ms]");
  if (!c.operating_schedule.empty() &&
      sized_by_operating_point(cumulative_effects(c.effects, c.scheduled_effects, c.scheduled_effects.size())))
    fail(
        "sim.schedule cannot be combined with effects that depend on the operating point (speed_dependence, "
        "mechanical_noise, the foreign SOI gain): they would keep the first operating point's size");
  try {
    validate_operating_schedule(c.operating_schedule);
    c.pressure_chain.validate();
    c.mic_chain.validate();
    validate_faults(c.faults, c.mic_count);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
}

class SimSource final : public Source {
 public:
  explicit SimSource(const SimConfig& config) : config_(config), epoch_utime_(wall_utime()) {
    validate(config_);
    info_.epoch_utime = epoch_utime_;
    info_.mic_count = config_.mic_count;
    info_.mic_positions_m = config_.mic_positions_m;
    if (info_.mic_positions_m.empty()) {
      info_.mic_positions_m = thesis_mic_positions();
      info_.mic_positions_m.resize(config_.mic_count);
    }
    info_.radius_m = config_.radius_m;
    info_.acoustic_delay_s = config_.radius_m / config_.speed_of_sound_m_s;
    if (config_.pressure_chain.adc_bits > 0) info_.pressure_full_scale_pa = config_.pressure_chain.adc_max_bar * 1e5;
    if (config_.mic_chain.adc_bits > 0) info_.mic_full_scale_pa = config_.mic_chain.adc_range_pa;
    info_.pressure_edges_per_rev = 360.0 / config_.encoder_resolution_deg;
    info_.pressure_angle_step_deg = angle_step_deg(info_.pressure_edges_per_rev);
    info_.mic_passband_hz = dsp::converter_passband_hz(config_.mic_rate_hz);
  }
  ~SimSource() override { stop(); }

  std::string name() const override { return "sim"; }
  StreamInfo info() const override { return info_; }

  void start(const Streams& streams) override {
    if (started_) throw std::logic_error("sim source: start() while running; stop() first");
    if (!streams.pressure || !streams.mics || !streams.operating_point)
      throw std::invalid_argument("sim source: start() needs all three rings");
    // First frame: the next grid-aligned instant from now (never before the epoch).
    const double now_s = 1e-6 * static_cast<double>(wall_utime() - epoch_utime_);
    const double t_first = std::ceil(std::max(now_s, 0.0) / sim::kGridAlignS) * sim::kGridAlignS;
    // Generators are built here (allocation happens now, not in the threads), on one operating profile.
    auto profile = std::make_shared<const OperatingProfile>(sim::operating_profile(config_, t_first));
    auto mics = std::make_shared<sim::MicGenerator>(config_, t_first, profile);
    const SimConfig::Threads& policy = config_.threads;
    for (auto& p : progress_) p.store(t_first, std::memory_order_relaxed);
    started_ = true;
    if (config_.stopped)
      start_stopped_pressure(streams, t_first);
    else
      start_pressure(streams, t_first, profile);
    workers_[1].start("nm-mics", policy.mics,
                      [this, mics, ring = streams.mics, t_first](const std::atomic<bool>& stop) {
                        run_stream(workers_[1], 1, *mics, *ring, t_first, stop, [] {});
                      });
    workers_[2].start("nm-op", policy.operating_point,
                      [this, profile, ring = streams.operating_point, t_first](const std::atomic<bool>& stop) {
                        run_operating_point(workers_[2], *profile, *ring, t_first, stop);
                      });
  }

  // The pressure's driver thread: sampled on the encoder's edges (the turning engine) ...
  void start_pressure(const Streams& streams, double t_first, const std::shared_ptr<const OperatingProfile>& profile) {
    auto pressure = std::make_shared<sim::PressureGenerator>(config_, t_first, profile);
    pressure->set_angle_ring(streams.pressure_angle);
    workers_[0].start("nm-pressure", config_.threads.pressure,
                      [this, pressure, ring = streams.pressure, t_first](const std::atomic<bool>& stop) {
                        run_stream(workers_[0], 0, *pressure, *ring, t_first, stop,
                                   [this, &pressure] { publish_encoder(pressure->encoder_counters()); });
                      });
  }
  // ... or on the card's timer (the engine at rest).
  void start_stopped_pressure(const Streams& streams, double t_first) {
    auto pressure = std::make_shared<sim::StoppedPressureGenerator>(config_, t_first);
    workers_[0].start("nm-pressure", config_.threads.pressure,
                      [this, pressure, ring = streams.pressure, t_first](const std::atomic<bool>& stop) {
                        run_stream(workers_[0], 0, *pressure, *ring, t_first, stop, [] {});
                      });
  }

  void stop() override {
    for (WorkerThread& w : workers_) w.request_stop();
    for (WorkerThread& w : workers_) w.join();
    started_ = false;
  }

  bool running() const override {
    for (const WorkerThread& w : workers_)
      if (w.state() != ThreadState::kRunning || w.blocks_written() == 0) return false;
    return true;
  }

  std::vector<DriverCounter> counters() const override {
    auto count = [](const std::atomic<std::uint64_t>& c) {
      return static_cast<std::int64_t>(c.load(std::memory_order_relaxed));
    };
    std::vector<DriverCounter> out{{"sim.pressure.adc_clipped", count(stats_[0].clipped)},
                                   {"sim.mics.adc_clipped", count(stats_[1].clipped)}};
    if (config_.faults.empty()) return out;
    for (const auto& [name, i] : {std::pair{"pressure", 0}, std::pair{"mics", 1}})
      out.push_back({std::string("sim.") + name + ".blocks_lost", count(stats_[i].lost_blocks)});
    for (std::size_t i = 0; i < kEncoderCounterNames.size(); ++i)
      out.push_back({std::string("sim.encoder.") + kEncoderCounterNames[i], count(encoder_[i])});
    return out;
  }

  std::vector<DriverThreadStatus> thread_status() const override {
    std::vector<DriverThreadStatus> out;
    for (const WorkerThread& w : workers_) out.push_back(w.status());
    return out;
  }

 private:
  // Sleeps until simulated time t_s arrives on the wall clock.
  void sleep_until_sim(double t_s) const {
    const auto target = std::chrono::system_clock::time_point(
        std::chrono::microseconds(epoch_utime_ + static_cast<std::int64_t>(std::llround(t_s * 1e6))));
    std::this_thread::sleep_until(target);
  }
  double sim_now_s() const { return 1e-6 * static_cast<double>(wall_utime() - epoch_utime_); }

  // One stream's driver loop. A stream fault (stall, overrun) makes a pass's blocks vanish before the ring, as a
  // device that delivers nothing; they are counted, never silent.
  template <class Generator, class AfterPass>
  void run_stream(WorkerThread& w, int stream, Generator& gen, BlockRing& ring, double t_first,
                  const std::atomic<bool>& stop, AfterPass after_pass) {
    const int target = stream == 0 ? kPressureTarget : kMicsTarget;
    std::unique_ptr<BlockRing> staged;  // with faults configured: each block waits here to be delivered or lost
    if (!config_.faults.empty()) staged = std::make_unique<BlockRing>(64);
    double t = t_first;
    std::uint64_t clipped_seen = 0;
    while (!stop.load(std::memory_order_relaxed)) {
      // Next chunk end; when behind the wall clock, catch up in bounded passes.
      // Like a real device, a chunk is delivered only once its last instant has passed on the wall clock.
      t = config_.paced ? std::max(t + kChunkS, std::min(sim_now_s(), t + kMaxCatchUpS)) : t + kChunkS;
      if (!wait_turn(stream, t, &ring, stop)) break;
      if (staged && active_fault(config_.faults, SimFaultKind::kFail, target, t - t_first))
        throw std::runtime_error(std::string("sim ") + (stream == 0 ? "encoder/pressure" : "microphone") +
                                 " device: input/output error (injected fault)");
      gen.advance(t, staged ? *staged : ring);
      if (staged) route_staged(stream, target, t_first, *staged, ring);
      w.set_blocks_written(gen.blocks_written());
      const std::uint64_t clipped = gen.clipped_samples();
      stats_[stream].clipped.fetch_add(clipped - clipped_seen, std::memory_order_relaxed);
      clipped_seen = clipped;
      after_pass();
      progress_[stream].store(t, std::memory_order_release);
    }
  }

  // A stream fault takes the blocks whose frames were sampled inside it, wherever a (catching-up) pass ends: a
  // stall or an overrun loses what the device would have acquired meanwhile, never a neighbour's frames.
  void route_staged(int stream, int target, double t_first, BlockRing& staged, BlockRing& ring) {
    for (const SampleBlock* b = staged.front(); b != nullptr; staged.consume(1), b = staged.front()) {
      const double first_s = static_cast<double>(b->first_index) / kPipelineRateHz - t_first;
      const double last_s = first_s + static_cast<double>(b->frames - 1) / kPipelineRateHz;
      if (stream_delivers(config_.faults, target, first_s) && stream_delivers(config_.faults, target, last_s))
        (void)ring.write(b, 1);  // a full ring counts its own overrun, as without faults
      else
        stats_[stream].lost_blocks.fetch_add(1, std::memory_order_relaxed);
    }
  }

  // Waits until the stream may produce up to simulated time t; false when stopped meanwhile. Paced: until t has
  // arrived on the wall clock. Unpaced: until no other stream is more than kMaxLeadS behind and the ring has room
  // for a pass (nothing is lost to the pace: the processing thread sets it).
  bool wait_turn(int stream, double t, const BlockRing* ring, const std::atomic<bool>& stop) {
    if (config_.paced) {
      sleep_until_sim(t);
      return !stop.load(std::memory_order_relaxed);
    }
    auto blocked = [&] {
      for (int other = 0; other < 2; ++other)
        if (other != stream && progress_[other].load(std::memory_order_acquire) < t - kMaxLeadS) return true;
      return ring && ring->capacity() - ring->size() < kUnpacedRoomBlocks;
    };
    while (blocked()) {
      if (stop.load(std::memory_order_relaxed)) return false;
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    return !stop.load(std::memory_order_relaxed);
  }

  void publish_encoder(const comedi::EdgeStreamCounters& c) {
    const std::uint64_t values[] = {c.edges,
                                    c.edges_before_lock,
                                    c.encoder_errors,
                                    c.phase_corrections,
                                    c.revolutions_checked,
                                    c.revolutions_flagged,
                                    c.missing_or_extra,
                                    c.lost_index,
                                    c.reverse_steps};
    static_assert(std::size(values) == kEncoderCounterNames.size());
    for (std::size_t i = 0; i < std::size(values); ++i) encoder_[i].store(values[i], std::memory_order_relaxed);
  }

  void run_operating_point(WorkerThread& w, const OperatingProfile& profile, OperatingPointRing& ring, double t_first,
                           const std::atomic<bool>& stop) {
    const model::CrankKinematics& kin = profile.kinematics();
    const double window = kOperatingPointPeriodS;
    for (double t = t_first; !stop.load(std::memory_order_relaxed); t += kOperatingPointPeriodS) {
      if (!wait_turn(2, t, nullptr, stop)) break;
      OperatingPoint op;
      op.utime = epoch_utime_ + std::llround(t * 1e6);
      // Speed as a tachometer measures it: mean over the last window from the crank angle (none at rest).
      op.speed_rpm = config_.stopped ? 0.0 : (kin.theta_deg(t) - kin.theta_deg(t - window)) / (6.0 * window);
      // Load and injection timing as the test bed's controller reports them: the cycle's setting.
      const model::engine::OperatingCondition& now =
          profile.condition(model::CrankKinematics::cycle_index(kin.theta_deg(t)));
      op.load_nm = now.load_nm;
      op.soi_deg_btdc = now.soi_deg_btdc;
      op.rail_pressure_bar = std::numeric_limits<double>::quiet_NaN();
      op.motored = now.motored;
      if (ring.push(op)) w.add_blocks_written();
    }
  }

  SimConfig config_;
  std::int64_t epoch_utime_;
  StreamInfo info_;
  struct StreamStats {
    std::atomic<std::uint64_t> clipped{0};      // samples the ADC clipped, every session
    std::atomic<std::uint64_t> lost_blocks{0};  // blocks a stream fault kept from the ring
  };
  std::array<StreamStats, 2> stats_;               // pressure, microphones
  std::array<std::atomic<double>, 2> progress_{};  // simulated time each stream has delivered up to (unpaced pacing)
  static constexpr std::array<const char*, 9> kEncoderCounterNames{"edges",
                                                                   "edges_before_lock",
                                                                   "errors",
                                                                   "phase_corrections",
                                                                   "revolutions_checked",
                                                                   "revolutions_flagged",
                                                                   "missing_or_extra",
                                                                   "lost_index",
                                                                   "reverse_steps"};
  std::array<std::atomic<std::uint64_t>, kEncoderCounterNames.size()> encoder_{};  // the decoder's counters
  bool started_ = false;
  // Last: destroyed (stopped) first, before anything their bodies use.
  std::array<WorkerThread, 3> workers_{WorkerThread("sim.encoder_pressure"), WorkerThread("sim.microphones"),
                                       WorkerThread("sim.operating_point")};
};

}  // namespace

std::unique_ptr<Source> make_sim_source(const SimConfig& config) { return std::make_unique<SimSource>(config); }

}  // namespace noisemon::drivers::sim
