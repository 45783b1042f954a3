#include "cli/sim_run.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <tuple>

#include "cli/formats/recording.hpp"
#include "drivers/sim/sim_generators.hpp"
#include "dsp/resample.hpp"
#include "model/engine/pressure_chain.hpp"
#include "model/engine/random.hpp"
#include "model/engine/virtual_engine.hpp"

namespace noisemon::cli {

namespace {

constexpr double kPreRollS = drivers::sim::kPreRollS;  // virtual engine run before t = 0 (grid aligned)
constexpr std::size_t kRenderBatch = 4096;             // microphone frames per render call

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// The sim configuration of a spec: its `engine` with the spec's operating point, true block, effects and seed.
drivers::sim::SimConfig run_config(const SimRunSpec& spec) {
  drivers::sim::SimConfig c = spec.engine;
  c.speed_rpm = spec.condition.speed_rpm;
  c.load_nm = spec.condition.load_nm;
  c.soi_deg_btdc = spec.condition.soi_deg_btdc;
  c.motored = spec.condition.motored;
  c.true_block = spec.true_block;
  c.effects = spec.effects;
  c.seed = spec.seed;
  return c;
}

// Renders `frames` microphone frames after skipping `skip` (the pre-roll) into run.mic_pa.
void render_mics(model::engine::VirtualEngine& engine, model::engine::PressureFeed& feed, std::int64_t skip,
                 std::int64_t frames, drivers::formats::RunDir& run) {
  const std::size_t m = engine.mic_count();
  std::vector<double> buf(kRenderBatch * m);
  while (skip > 0) {
    const auto n = static_cast<std::size_t>(std::min<std::int64_t>(skip, kRenderBatch));
    engine.render(feed, buf.data(), n);
    skip -= static_cast<std::int64_t>(n);
  }
  run.mic_pa.clear();
  run.mic_pa.reserve(static_cast<std::size_t>(frames) * m);
  while (frames > 0) {
    const auto n = static_cast<std::size_t>(std::min<std::int64_t>(frames, kRenderBatch));
    engine.render(feed, buf.data(), n);
    for (std::size_t i = 0; i < n * m; ++i) run.mic_pa.push_back(static_cast<float>(buf[i]));
    frames -= static_cast<std::int64_t>(n);
  }
}

// The engine model as the virtual engine's feed, emitting the encoder samples of [-360, 720 cycles - 360) on the
// way: both walk forward in crank angle, so one engine-cycle cache serves both (each cycle is computed once).
class RunFeed final : public model::engine::PressureFeed {
 public:
  RunFeed(const drivers::sim::SimConfig& config, double t0_s, double rate_hz, int cycles, drivers::formats::RunDir& run)
      : kin_(drivers::sim::crank_kinematics(config)), cache_(config), t0_(t0_s), rate_(rate_hz), run_(run) {
    // Encoder sample m at -360 + m * resolution; for resolutions 1/k deg, m / k keeps the CSV short.
    const double res = config.encoder_resolution_deg;
    const double per_deg = 1.0 / res;
    divide_ = std::abs(per_deg - std::round(per_deg)) < 1e-9;
    per_deg_ = std::round(per_deg);
    res_ = res;
    end_ = static_cast<std::int64_t>(std::llround(720.0 * cycles / res));
    run_.time_s.reserve(static_cast<std::size_t>(end_));
    run_.crank_deg.reserve(static_cast<std::size_t>(end_));
    run_.pressure_pa.reserve(static_cast<std::size_t>(end_));
  }
  void fill(std::int64_t first, double* pressure_pa, double* crank_deg, std::size_t n) override {
    for (std::size_t i = 0; i < n; ++i) {
      const double t = t0_ + static_cast<double>(first + static_cast<std::int64_t>(i)) / rate_;
      const double theta = kin_.theta_deg(t);
      encoder_until(theta);
      crank_deg[i] = theta;
      pressure_pa[i] = cache_.pressure_pa(theta);
    }
  }
  // Emits the encoder samples up to crank angle theta (all of them for +inf).
  void encoder_until(double theta) {
    for (; next_ < end_; ++next_) {
      const double a =
          divide_ ? -360.0 + static_cast<double>(next_) / per_deg_ : -360.0 + static_cast<double>(next_) * res_;
      if (a > theta) break;
      run_.time_s.push_back(kin_.time_s(a));
      run_.crank_deg.push_back(a);
      run_.pressure_pa.push_back(cache_.pressure_pa(a));
    }
  }
  double last_time_s() const { return kin_.time_s(-360.0 + static_cast<double>(end_ - 1) * res_); }

 private:
  model::CrankKinematics kin_;
  drivers::sim::EngineCycleCache cache_;
  double t0_, rate_;
  drivers::formats::RunDir& run_;
  bool divide_ = false;
  double per_deg_ = 1.0, res_ = 0.1;
  std::int64_t next_ = 0, end_ = 0;
};

// A given pressure run on the virtual engine's uniform grid (resampled beforehand): fine sample k at
// t = t_first + k / rate. Past the end it holds the last value (only the look-ahead of the filters sees it).
class ArrayFeed final : public model::engine::PressureFeed {
 public:
  ArrayFeed(std::vector<double> p, std::vector<double> crank) : p_(std::move(p)), crank_(std::move(crank)) {}
  void fill(std::int64_t first, double* pressure_pa, double* crank_deg, std::size_t n) override {
    const auto size = static_cast<std::int64_t>(p_.size());
    for (std::size_t i = 0; i < n; ++i) {
      const std::int64_t k = std::min(first + static_cast<std::int64_t>(i), size - 1);
      pressure_pa[i] = p_[static_cast<std::size_t>(k)];
      crank_deg[i] = crank_[static_cast<std::size_t>(k)];
    }
  }

 private:
  std::vector<double> p_, crank_;
};

void check_config(const SimRunSpec& spec) {
  const drivers::sim::SimConfig& c = spec.engine;
  if (!(spec.condition.speed_rpm > 0.0 && spec.condition.speed_rpm <= 10000.0))
    throw std::invalid_argument("sim run " + spec.condition.name + ": speed " + fmt(spec.condition.speed_rpm) +
                                " rpm outside (0, 10000]");
  if (!(spec.condition.soi_deg_btdc >= 0.0 && spec.condition.soi_deg_btdc <= 60.0))
    throw std::invalid_argument("sim run " + spec.condition.name + ": SOI " + fmt(spec.condition.soi_deg_btdc) +
                                " deg BTDC outside [0, 60]");
  if (!(spec.condition.load_nm >= 0.0))
    throw std::invalid_argument("sim run " + spec.condition.name + ": negative load");
  if (spec.cycles < 1 || spec.cycles > 100000) throw std::invalid_argument("sim run: cycles must be in [1, 100000]");
  if (!(c.encoder_resolution_deg >= 0.01 && c.encoder_resolution_deg <= 6.0))
    throw std::invalid_argument("sim run: encoder resolution must be in [0.01, 6] deg");
  if (!(c.mic_rate_hz >= 8000.0 && c.mic_rate_hz == std::round(c.mic_rate_hz) &&
        std::fmod(c.mic_rate_hz, 1600.0) == 0.0))
    throw std::invalid_argument("sim run: the microphone rate must be a multiple of 1600 Hz, >= 8000 Hz");
}

}  // namespace

drivers::sim::SimConfig SimRunSpec::default_engine() {
  drivers::sim::SimConfig c;
  c.encoder_resolution_deg = 0.2;
  return c;
}

std::vector<SimCondition> thesis_conditions() {
  const double full_load = drivers::sim::SimConfig{}.full_load_nm;
  std::vector<SimCondition> out;
  for (const auto& [prefix, rpm, load] : {std::tuple{"idle", 3050.0, 0.0}, std::tuple{"full", 3450.0, full_load}})
    for (int soi : {12, 15, 18, 21, 24})
      out.push_back({std::string(prefix) + "_mi" + std::to_string(soi), rpm, load, static_cast<double>(soi), false});
  out.push_back({"motored_idle", 3050.0, 0.0, 18.0, true});
  out.push_back({"motored_full", 3450.0, 0.0, 18.0, true});
  return out;
}

std::vector<SimCondition> resolve_conditions(const std::vector<std::string>& names) {
  const auto all = thesis_conditions();
  std::vector<SimCondition> out;
  const auto add = [&out](const SimCondition& c) {
    for (const auto& o : out)
      if (o.name == c.name) return;
    out.push_back(c);
  };
  for (const auto& name : names) {
    if (name == "all") {
      for (const auto& c : all) add(c);
      continue;
    }
    const auto it = std::find_if(all.begin(), all.end(), [&](const SimCondition& c) { return c.name == name; });
    if (it == all.end()) {
      std::string valid = "all";
      for (const auto& c : all) valid += ", " + c.name;
      throw std::invalid_argument("unknown condition \"" + name + "\"; valid conditions: " + valid);
    }
    add(*it);
  }
  return out;
}

std::uint64_t condition_seed(std::uint64_t seed, std::string_view condition_name) {
  std::uint64_t h = 0xCBF29CE484222325ULL;  // FNV-1a
  for (char ch : condition_name) h = (h ^ static_cast<unsigned char>(ch)) * 0x100000001B3ULL;
  return model::engine::rnd::key(seed, h, 0);
}

namespace {

// The microphone layout and the measured pressure of a generated run: the pressure chain on every encoder sample
// (counter-based on the sample index), the configured floor recorded (without the transducer_noise effect: the
// unknown a diagnosis must find).
void finish_run(const SimRunSpec& spec, const drivers::sim::SimConfig& config,
                const model::engine::VirtualEngineConfig& vcfg, const model::engine::VirtualEngine& engine,
                drivers::formats::RunDir& run, SimRunStats* stats) {
  model::engine::PressureChain chain(config.pressure_chain, spec.effects, spec.seed);
  chain.measure(0, run.pressure_pa.data(), run.pressure_pa.size());
  run.pressure_noise_floor_bar = config.pressure_chain.floor_bar();
  run.mic_rate_hz = config.mic_rate_hz;
  run.mic_count = static_cast<std::uint32_t>(engine.mic_count());
  run.mic_positions_m = vcfg.mic_positions_m;
  run.radius_m = config.radius_m;
  run.acoustic_delay_s = config.radius_m / config.speed_of_sound_m_s;
  if (stats) *stats = {chain.clipped_samples(), engine.mic_clipped()};
}

// The engine off as the virtual engine's feed: no pressure reaches the structure; the crank angle only clocks.
class SilentFeed final : public model::engine::PressureFeed {
 public:
  SilentFeed(const drivers::sim::SimConfig& config, double t0_s, double rate_hz)
      : kin_(drivers::sim::crank_kinematics(config)), t0_(t0_s), rate_(rate_hz) {}
  void fill(std::int64_t first, double* pressure_pa, double* crank_deg, std::size_t n) override {
    for (std::size_t i = 0; i < n; ++i) {
      pressure_pa[i] = 0.0;
      crank_deg[i] = kin_.theta_deg(t0_ + static_cast<double>(first + static_cast<std::int64_t>(i)) / rate_);
    }
  }

 private:
  model::CrankKinematics kin_;
  double t0_, rate_;
};

}  // namespace

drivers::formats::RunDir simulate_run(const SimRunSpec& spec, SimRunStats* stats) {
  check_config(spec);
  const drivers::sim::SimConfig config = run_config(spec);
  const double fine_rate = 2.0 * config.mic_rate_hz;
  drivers::formats::RunDir run;
  run.condition = {spec.condition.name, spec.condition.speed_rpm, spec.condition.load_nm, spec.condition.soi_deg_btdc,
                   std::nullopt,        spec.condition.motored};
  model::engine::VirtualEngineConfig vcfg = drivers::sim::virtual_engine_config(config, fine_rate);
  vcfg.setup_seed = spec.setup_seed;
  model::engine::VirtualEngine engine(vcfg);
  RunFeed feed(config, -kPreRollS, fine_rate, spec.cycles, run);
  // Microphone frames for t in [0, last encoder sample].
  const auto skip = static_cast<std::int64_t>(std::llround(kPreRollS * config.mic_rate_hz));
  const auto frames = static_cast<std::int64_t>(std::floor(feed.last_time_s() * config.mic_rate_hz)) + 1;
  render_mics(engine, feed, skip, frames, run);
  feed.encoder_until(std::numeric_limits<double>::infinity());
  finish_run(spec, config, vcfg, engine, run, stats);
  return run;
}

drivers::formats::RunDir simulate_background_run(const SimRunSpec& given, SimRunStats* stats) {
  SimRunSpec spec = given;
  spec.condition.name = std::string(kBackgroundRunName);
  spec.condition.load_nm = 0.0;
  spec.condition.motored = true;
  spec.effects.mechanical_noise_dba.reset();  // impacts need a turning engine
  check_config(spec);
  const drivers::sim::SimConfig config = run_config(spec);
  const double fine_rate = 2.0 * config.mic_rate_hz;
  drivers::formats::RunDir run;
  run.condition = {spec.condition.name, spec.condition.speed_rpm, 0.0, spec.condition.soi_deg_btdc, std::nullopt, true};
  // The clock: encoder samples of spec.cycles cycles; the transducer reads the ambient (intake) pressure.
  const model::CrankKinematics kin = drivers::sim::crank_kinematics(config);
  const double res = config.encoder_resolution_deg, ambient = drivers::sim::engine_params(config).intake_pressure_pa;
  const auto samples = static_cast<std::int64_t>(std::llround(720.0 * spec.cycles / res));
  for (std::int64_t m = 0; m < samples; ++m) {
    const double a = -360.0 + static_cast<double>(m) * res;
    run.time_s.push_back(kin.time_s(a));
    run.crank_deg.push_back(a);
    run.pressure_pa.push_back(ambient);
  }
  model::engine::VirtualEngineConfig vcfg = drivers::sim::virtual_engine_config(config, fine_rate);
  vcfg.setup_seed = spec.setup_seed;
  vcfg.mean_pressure_pa = 0.0;
  model::engine::VirtualEngine engine(vcfg);
  SilentFeed feed(config, -kPreRollS, fine_rate);
  const auto skip = static_cast<std::int64_t>(std::llround(kPreRollS * config.mic_rate_hz));
  const auto frames = static_cast<std::int64_t>(std::floor(run.time_s.back() * config.mic_rate_hz)) + 1;
  render_mics(engine, feed, skip, frames, run);
  finish_run(spec, config, vcfg, engine, run, stats);
  return run;
}

namespace {

// Missing encoder samples (a crank step of 1.5 .. kMaxCrankGapSteps nominal steps, e.g. a dropped pegging row)
// filled by linear interpolation in time, angle and pressure: the band-limited resampler wants the samples
// evenly spaced in angle. The nominal step is the most common one (the median step).
void fill_encoder_gaps(std::vector<double>& t, std::vector<double>& th, std::vector<double>& p,
                       const std::string& what) {
  std::vector<double> steps(th.size() - 1);
  for (std::size_t i = 1; i < th.size(); ++i) steps[i - 1] = th[i] - th[i - 1];
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
  const double step = steps[steps.size() / 2];
  std::vector<double> t2, th2, p2;
  t2.reserve(t.size());
  th2.reserve(t.size());
  p2.reserve(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (i > 0) {
      const double gap = (th[i] - th[i - 1]) / step;
      if (gap > drivers::formats::kMaxCrankGapSteps + 1e-6)
        throw std::invalid_argument(what + ": crank angle jumps by " + fmt(th[i] - th[i - 1]) +
                                    " deg at pressure sample " + std::to_string(i) + " (more than " +
                                    fmt(drivers::formats::kMaxCrankGapSteps) + " encoder steps)");
      const auto missing = static_cast<int>(std::lround(gap)) - 1;
      for (int k = 1; k <= missing && gap >= 1.5; ++k) {
        const double f = static_cast<double>(k) / (missing + 1);
        t2.push_back(t[i - 1] + f * (t[i] - t[i - 1]));
        th2.push_back(th[i - 1] + f * (th[i] - th[i - 1]));
        p2.push_back(p[i - 1] + f * (p[i] - p[i - 1]));
      }
    }
    t2.push_back(t[i]);
    th2.push_back(th[i]);
    p2.push_back(p[i]);
  }
  t.swap(t2);
  th.swap(th2);
  p.swap(p2);
}

// A pressure trace on its encoder clock: time (s), crank angle (deg), pressure (Pa).
struct EncoderTrace {
  std::vector<double> t, th, p;
};

// The given run's pressure, checked (enough samples, time and crank angle increasing, a whole cycle) and with its
// missing encoder samples filled.
EncoderTrace checked_pressure(const drivers::formats::RunDir& run, const std::string& what) {
  const std::size_t n = run.time_s.size();
  if (n < 16 || run.crank_deg.size() != n || run.pressure_pa.size() != n)
    throw std::invalid_argument(what + ": too few or inconsistent pressure samples");
  for (std::size_t i = 1; i < n; ++i)
    if (!(run.time_s[i] > run.time_s[i - 1]) || !(run.crank_deg[i] > run.crank_deg[i - 1]))
      throw std::invalid_argument(what + ": time and crank angle must increase (pressure sample " + std::to_string(i) +
                                  ")");
  EncoderTrace tr{run.time_s, run.crank_deg, run.pressure_pa};
  fill_encoder_gaps(tr.t, tr.th, tr.p, what);
  if (tr.th.back() - tr.th.front() < 720.0)
    throw std::invalid_argument(what + ": needs at least one whole cycle (720 deg) of pressure");
  return tr;
}

// The time at a crank angle, linear in crank angle (extrapolated from the first or last interval outside).
double time_at(const EncoderTrace& tr, double theta) {
  const auto it = std::upper_bound(tr.th.begin(), tr.th.end(), theta);
  const std::size_t j = std::clamp<std::size_t>(static_cast<std::size_t>(it - tr.th.begin()), 1, tr.t.size() - 1);
  return tr.t[j - 1] + (tr.t[j] - tr.t[j - 1]) * (theta - tr.th[j - 1]) / (tr.th[j] - tr.th[j - 1]);
}

// A trace with its first and last whole cycles (by crank angle) repeated as periodic extensions before and after
// it, far enough before t = 0 for the pre-roll.
struct ExtendedTrace {
  EncoderTrace x;
  std::size_t first_end = 0;  // the samples of the first whole cycle: [0, first_end) of the given trace
  double last_period = 0.0;   // s
};

ExtendedTrace extend_periodically(const EncoderTrace& tr) {
  const std::vector<double>& t = tr.t;
  const std::vector<double>& th = tr.th;
  const std::vector<double>& p = tr.p;
  const std::size_t n = t.size();
  const double first_period = time_at(tr, th.front() + 720.0) - t.front();
  ExtendedTrace e;
  e.last_period = t.back() - time_at(tr, th.back() - 720.0);
  e.first_end = static_cast<std::size_t>(std::lower_bound(th.begin(), th.end(), th.front() + 720.0) - th.begin());
  const auto last_begin =
      static_cast<std::size_t>(std::upper_bound(th.begin(), th.end(), th.back() - 720.0) - th.begin());
  const int pre_copies = static_cast<int>(std::ceil((std::max(t.front(), 0.0) + 1.5 * kPreRollS) / first_period));
  std::vector<double>& et = e.x.t;
  std::vector<double>& eth = e.x.th;
  std::vector<double>& ep = e.x.p;
  for (int k = pre_copies; k >= 1; --k)
    for (std::size_t i = 0; i < e.first_end; ++i) {
      et.push_back(t[i] - k * first_period);
      eth.push_back(th[i] - 720.0 * k);
      ep.push_back(p[i]);
    }
  et.insert(et.end(), t.begin(), t.end());
  eth.insert(eth.end(), th.begin(), th.end());
  ep.insert(ep.end(), p.begin(), p.end());
  for (std::size_t i = last_begin; i < n; ++i) {
    et.push_back(t[i] + e.last_period);
    eth.push_back(th[i] + 720.0);
    ep.push_back(p[i]);
  }
  return e;
}

// The spec of the virtual engine that hears a given run: the run's operating point (its speed from the data when it
// states none) and its microphones, if it has them.
SimRunSpec acoustics_spec(const drivers::formats::RunDir& pressure_run, const SimRunSpec& spec,
                          const EncoderTrace& tr) {
  SimRunSpec s = spec;
  s.condition = {pressure_run.condition.name, pressure_run.condition.speed_rpm, pressure_run.condition.load_nm,
                 pressure_run.condition.soi_deg_btdc, pressure_run.condition.motored};
  if (!(s.condition.speed_rpm > 0.0))
    s.condition.speed_rpm = (tr.th.back() - tr.th.front()) / (6.0 * (tr.t.back() - tr.t.front()));  // deg/s -> rpm
  s.condition.soi_deg_btdc = std::clamp(s.condition.soi_deg_btdc, 0.0, 60.0);
  if (pressure_run.mic_count > 0 && pressure_run.mic_positions_m.size() == pressure_run.mic_count) {
    s.engine.mic_positions_m = pressure_run.mic_positions_m;
    s.engine.mic_count = pressure_run.mic_count;
  }
  check_config(s);
  return s;
}

// The pressure on the virtual engine's fine grid t = t0 + k / fine_rate, with the crank angle at each sample.
struct FinePressure {
  std::vector<double> p, th;
  double t0 = 0.0;
};

// The crank angle at count instants t0 + k / rate, linear in time between the trace's samples.
std::vector<double> crank_on_grid(const EncoderTrace& e, double t0, double rate, std::size_t count) {
  std::vector<double> th(count);
  std::size_t j = 1;
  for (std::size_t k = 0; k < count; ++k) {
    const double tk = t0 + static_cast<double>(k) / rate;
    while (j + 1 < e.t.size() && e.t[j] < tk) ++j;
    th[k] = e.th[j - 1] + (e.th[j] - e.th[j - 1]) * (tk - e.t[j - 1]) / (e.t[j] - e.t[j - 1]);
  }
  return th;
}

// Band-limited resampling of an (extended) trace onto the fine grid t = t_ref + k / fine_rate, t_ref on the
// 1/1600 s grid (so t = 0 falls on a microphone frame); the result starts on an even fine index (a microphone
// frame) inside the resampled data.
FinePressure resample_fine(const EncoderTrace& e, double fine_rate, const std::string& what) {
  const double t_ref = std::floor(e.t.front() * 1600.0) / 1600.0;
  dsp::NonuniformResampler resampler(fine_rate, 1);
  FinePressure fine;
  fine.p.reserve(static_cast<std::size_t>((e.t.back() - t_ref) * fine_rate) + 16);
  std::vector<double> out(8192), tt(256);
  std::int64_t k_first = -1;
  const auto take = [&](std::size_t got) {
    if (k_first < 0 && got > 0) k_first = resampler.next_output_index() - static_cast<std::int64_t>(got);
    fine.p.insert(fine.p.end(), out.begin(), out.begin() + static_cast<std::ptrdiff_t>(got));
    return got == out.size();  // more may be waiting
  };
  for (std::size_t i = 0; i < e.t.size(); i += tt.size()) {
    const std::size_t m = std::min(tt.size(), e.t.size() - i);
    for (std::size_t j = 0; j < m; ++j) tt[j] = e.t[i + j] - t_ref;
    if (take(resampler.process(tt.data(), e.p.data() + i, m, out.data(), out.size())))
      while (take(resampler.process(nullptr, nullptr, 0, out.data(), out.size()))) {
      }
  }
  if (k_first < 0) throw std::invalid_argument(what + ": the pressure could not be resampled");
  std::int64_t k0 = k_first + 64;
  if (k0 % 2 != 0) ++k0;
  fine.t0 = t_ref + static_cast<double>(k0) / fine_rate;
  if (fine.t0 > -kPreRollS) throw std::invalid_argument(what + ": internal: pre-roll too short");
  fine.p.erase(fine.p.begin(), fine.p.begin() + (k0 - k_first));
  fine.th = crank_on_grid(e, fine.t0, fine_rate, fine.p.size());
  return fine;
}

// simulate_acoustics with microphone frames up to t_end_s (at most one cycle past the pressure's end).
drivers::formats::RunDir acoustics(const drivers::formats::RunDir& pressure_run, const SimRunSpec& spec,
                                   double t_end_s) {
  const std::string what = "sim acoustics for run \"" + pressure_run.condition.name + "\"";
  const EncoderTrace tr = checked_pressure(pressure_run, what);
  const ExtendedTrace ext = extend_periodically(tr);
  const drivers::sim::SimConfig config = run_config(acoustics_spec(pressure_run, spec, tr));
  const double fine_rate = 2.0 * config.mic_rate_hz;
  FinePressure fine = resample_fine(ext.x, fine_rate, what);
  // Expected mean input (AC coupling start): the first cycle's mean.
  double mean = 0.0;
  for (std::size_t i = 0; i < ext.first_end; ++i) mean += tr.p[i];
  mean /= static_cast<double>(std::max<std::size_t>(ext.first_end, 1));

  model::engine::VirtualEngineConfig vcfg = drivers::sim::virtual_engine_config(config, fine_rate);
  vcfg.setup_seed = spec.setup_seed;
  vcfg.mean_pressure_pa = mean;
  model::engine::VirtualEngine engine(vcfg);
  ArrayFeed feed(std::move(fine.p), std::move(fine.th));

  drivers::formats::RunDir run = pressure_run;
  const auto skip = static_cast<std::int64_t>(std::llround(-fine.t0 * config.mic_rate_hz));
  if (t_end_s > tr.t.back() + 0.9 * ext.last_period)
    throw std::invalid_argument(what + ": internal: microphones past the data");
  const auto frames = static_cast<std::int64_t>(std::floor(t_end_s * config.mic_rate_hz)) + 1;
  if (frames < 1) throw std::invalid_argument(what + ": the pressure ends before t = 0");
  render_mics(engine, feed, skip, frames, run);
  // The given pressure went through its own chain already: only the injected extra floor is added.
  model::engine::add_transducer_noise(spec.effects, spec.seed, 0, run.pressure_pa.data(), pressure_run.time_s.size());
  run.mic_rate_hz = config.mic_rate_hz;
  run.mic_count = static_cast<std::uint32_t>(engine.mic_count());
  run.mic_positions_m = vcfg.mic_positions_m;
  if (pressure_run.mic_count == 0) run.radius_m = config.radius_m;
  run.acoustic_delay_s = run.radius_m / config.speed_of_sound_m_s;
  return run;
}

}  // namespace

drivers::formats::RunDir simulate_acoustics(const drivers::formats::RunDir& pressure_run, const SimRunSpec& spec) {
  drivers::formats::RunDir run =
      acoustics(pressure_run, spec, pressure_run.time_s.empty() ? 0.0 : pressure_run.time_s.back());
  // The virtual engine hears the given pressure as it is (its own noise included): between that engine and this
  // file no chain adds a floor, so the stated floor is 0 (only a transducer_noise effect comes on top, unstated).
  run.pressure_noise_floor_bar = 0.0;
  return run;
}

void synthesize_recording_mics(formats::Recording& rec, const SimRunSpec& spec) {
  if (rec.frames() < 2) throw std::invalid_argument("sim microphones: the recording has no pressure");
  drivers::formats::RunDir pressure = formats::to_run_dir(rec);
  pressure.mic_count = 0;
  pressure.mic_pa.clear();
  pressure.mic_positions_m.clear();
  // Microphones at the card rate a little past the last frame, so the resampler to 40 kHz has its look-ahead.
  const drivers::formats::RunDir sim = acoustics(pressure, spec, pressure.time_s.back() + 0.005);
  const std::size_t m = sim.mic_count;
  dsp::RationalResampler to_grid(sim.mic_rate_hz, drivers::kPipelineRateHz, m);
  std::vector<double> in(sim.mic_pa.begin(), sim.mic_pa.end());
  std::vector<double> out(to_grid.max_output_frames(in.size() / m) * m + m);
  const std::size_t made = to_grid.process(in.data(), in.size() / m, out.data(), out.size() / m);
  if (made < rec.frames()) throw std::logic_error("sim microphones: resampling fell short of the recording");
  rec.mics_pa.assign(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(rec.frames() * m));
  rec.info.mic_count = static_cast<std::uint32_t>(m);
  rec.info.mic_positions_m = sim.mic_positions_m;
  rec.info.radius_m = sim.radius_m;
  rec.info.acoustic_delay_s = sim.acoustic_delay_s;
}

}  // namespace noisemon::cli
