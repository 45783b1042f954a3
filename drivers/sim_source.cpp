// The virtual engine source: three driver threads paced to the wall clock around the generators of
// sim_generators.hpp. Each thread computes its stream up to the end of the next ~5 ms chunk of simulated
// time, then sleeps until that instant arrives on the wall clock; ring writes never wait (a full ring drops the
// block and counts an overrun).
#include "drivers/sim_source.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <thread>

#include "drivers/sim_generators.hpp"

namespace noisemon::drivers {

std::vector<std::array<double, 3>> thesis_mic_positions() {
  // Thesis Table 3.1 (x, y, z in m), hemisphere r = 1.75 m over the reflecting floor.
  return {{-1.35, 0.78, 0.79}, {0.00, 1.73, 0.26},  {0.00, 1.16, 1.31},  {1.00, -0.58, 1.31}, {0.00, 0.00, 1.75},
          {1.35, 0.78, 0.79},  {1.50, -0.87, 0.26}, {0.00, -1.16, 1.31}, {-1.00, -0.58, 1.31}, {-1.50, -0.87, 0.26}};
}

SimConfig with_ideal_cell(SimConfig config) {
  config.pressure_chain = model::PressureChainConfig::ideal();
  config.mic_chain = model::MicChainConfig::ideal();
  config.gas_ringing = model::GasRingingParams::off();
  return config;
}

namespace {

constexpr double kChunkS = 0.005;             // generation chunk of the sample streams
constexpr double kOperatingPointPeriodS = 0.1;  // 10 Hz
constexpr double kMaxCatchUpS = 0.05;         // simulated time per loop pass when behind (keeps stop() prompt)

void validate(const SimConfig& c) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("sim source: " + what); };
  if (!(c.speed_rpm > 0.0 && c.speed_rpm <= 10000.0)) fail("speed_rpm must be in (0, 10000]");
  if (!(c.speed_fluctuation >= 0.0 && c.speed_fluctuation < 0.2)) fail("speed_fluctuation must be in [0, 0.2)");
  if (!(c.cycle_variation >= 0.0 && c.cycle_variation < 0.2)) fail("cycle_variation must be in [0, 0.2)");
  if (!(c.soi_deg_btdc >= 0.0 && c.soi_deg_btdc <= 60.0)) fail("soi_deg_btdc must be in [0, 60]");
  if (!(c.load_nm >= 0.0) || !(c.full_load_nm > 0.0)) fail("load_nm must be >= 0 and full_load_nm > 0");
  if (!(c.encoder_resolution_deg >= 0.01 && c.encoder_resolution_deg <= 6.0)) fail("encoder_resolution_deg must be in [0.01, 6]");
  if (c.mic_count == 0 || c.mic_count > SampleBlock::kMaxChannels) fail("mic_count must be in [1, 16]");
  if (c.mic_positions_m.empty() && c.mic_count > thesis_mic_positions().size())
    fail("mic_positions_m must be given for more than 10 microphones");
  if (!c.mic_positions_m.empty() && c.mic_positions_m.size() != c.mic_count)
    fail("mic_positions_m must have mic_count entries");
  if (!(c.radius_m > 0.0) || !(c.speed_of_sound_m_s > 0.0)) fail("radius_m and speed_of_sound_m_s must be positive");
  if (!(c.mic_rate_hz >= 8000.0 && c.mic_rate_hz == std::round(c.mic_rate_hz))) fail("mic_rate_hz must be a whole number >= 8000");
  if (!(c.mic_gain_spread_db >= 0.0 && c.mic_gain_spread_db <= 6.0)) fail("mic_gain_spread_db must be in [0, 6]");
  if (!(c.gas_ringing.gain_s >= 0.0 && c.gas_ringing.gain_s <= 1e-3) || !(c.gas_ringing.decay_s > 0.0 && c.gas_ringing.decay_s <= 0.1))
    fail("gas ringing: gain must be in [0, 1 ms] and decay in (0, 100 ms]");
  try {
    c.pressure_chain.validate();
    c.mic_chain.validate();
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
    // Generators are built here (allocation happens now, not in the threads).
    auto pressure = std::make_shared<sim::PressureGenerator>(config_, t_first);
    auto mics = std::make_shared<sim::MicGenerator>(config_, t_first);
    const SimConfig::Threads& policy = config_.threads;
    started_ = true;
    workers_[0].start("nm-pressure", policy.pressure,
                      [this, pressure, ring = streams.pressure, t_first](const std::atomic<bool>& stop) {
                        run_stream(workers_[0], clipped_[0], *pressure, *ring, t_first, stop);
                      });
    workers_[1].start("nm-mics", policy.mics, [this, mics, ring = streams.mics, t_first](const std::atomic<bool>& stop) {
      run_stream(workers_[1], clipped_[1], *mics, *ring, t_first, stop);
    });
    workers_[2].start("nm-op", policy.operating_point,
                      [this, ring = streams.operating_point, t_first](const std::atomic<bool>& stop) {
                        run_operating_point(workers_[2], *ring, t_first, stop);
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
    return {{"sim.pressure.adc_clipped", static_cast<std::int64_t>(clipped_[0].load())},
            {"sim.mics.adc_clipped", static_cast<std::int64_t>(clipped_[1].load())}};
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

  template <class Generator>
  void run_stream(WorkerThread& w, std::atomic<std::uint64_t>& clipped_total, Generator& gen, BlockRing& ring, double t_first,
                  const std::atomic<bool>& stop) {
    double t = t_first;
    std::uint64_t clipped_seen = 0;
    while (!stop.load(std::memory_order_relaxed)) {
      // Next chunk end; when behind the wall clock, catch up in bounded passes.
      // Like a real device, a chunk is delivered only once its last instant has passed on the wall clock.
      t = std::max(t + kChunkS, std::min(sim_now_s(), t + kMaxCatchUpS));
      sleep_until_sim(t);
      if (stop.load(std::memory_order_relaxed)) break;
      gen.advance(t, ring);
      w.set_blocks_written(gen.blocks_written());
      const std::uint64_t clipped = gen.clipped_samples();
      clipped_total.fetch_add(clipped - clipped_seen, std::memory_order_relaxed);
      clipped_seen = clipped;
    }
  }

  void run_operating_point(WorkerThread& w, OperatingPointRing& ring, double t_first, const std::atomic<bool>& stop) {
    const model::CrankKinematics kin = sim::crank_kinematics(config_);
    const double window = kOperatingPointPeriodS;
    for (double t = t_first; !stop.load(std::memory_order_relaxed); t += kOperatingPointPeriodS) {
      sleep_until_sim(t);
      OperatingPoint op;
      op.utime = epoch_utime_ + std::llround(t * 1e6);
      // Speed as a tachometer measures it: mean over the last window from the crank angle.
      op.speed_rpm = (kin.theta_deg(t) - kin.theta_deg(t - window)) / (6.0 * window);
      op.load_nm = config_.load_nm;
      op.soi_deg_btdc = config_.soi_deg_btdc;
      op.rail_pressure_bar = std::numeric_limits<double>::quiet_NaN();
      op.motored = config_.motored;
      if (ring.push(op)) w.add_blocks_written();
    }
  }

  SimConfig config_;
  std::int64_t epoch_utime_;
  StreamInfo info_;
  std::array<std::atomic<std::uint64_t>, 2> clipped_{};  // ADC clipping of the pressure and mic samples, every session
  bool started_ = false;
  // Last: destroyed (stopped) first, before anything their bodies use.
  std::array<WorkerThread, 3> workers_{WorkerThread("sim.encoder_pressure"), WorkerThread("sim.microphones"),
                                       WorkerThread("sim.operating_point")};
};

}  // namespace

std::unique_ptr<Source> make_sim_source(const SimConfig& config) { return std::make_unique<SimSource>(config); }

}  // namespace noisemon::drivers
