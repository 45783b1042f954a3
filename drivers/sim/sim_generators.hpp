// The sim source's stream generators, without threads: each advances its stream to a given simulated time
// and writes SampleBlocks into a ring. The driver threads (sim_source.cpp) pace them to the wall clock; the
// benchmark runs them flat out.
//
// Simulated time t (s) is the source's clock: t = 0 is frame index 0 of the 40 kHz grid (the epoch). Both
// generators start publishing at frame first_index = t_first * 40 kHz and compute a pre-roll before it so
// filters and resamplers have settled by then.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "drivers/block_writer.hpp"
#include "drivers/comedi/comedi_streams.hpp"
#include "drivers/sim/sim_faults.hpp"
#include "drivers/sim/sim_source.hpp"
#include "dsp/resample.hpp"
#include "model/block_model.hpp"
#include "model/engine/engine_cycle.hpp"
#include "model/engine/virtual_engine.hpp"

namespace noisemon::drivers::sim {

// Pre-roll computed (not published) before the first frame: settles the resamplers and the block model.
inline constexpr double kPreRollS = 0.2;
// Start instants are multiples of this (s): the 40 kHz, 51.2 kHz and 102.4 kHz grids all meet there.
inline constexpr double kGridAlignS = 1.0 / 1600.0;

// The card's reading of the pressure chain's output (SimConfig::pressure_readout), in place.
void read_out_pressure(const SimConfig::PressureReadout& readout, double* pressure_pa, std::size_t n);

// Engine parameters and operating condition of the virtual engine for a configuration.
model::engine::EngineCycleParams engine_params(const SimConfig& config);
model::engine::OperatingCondition operating_condition(const SimConfig& config);
// The operating point over the run (config.operating_schedule) for a source whose first frame is at t_first_s.
OperatingProfile operating_profile(const SimConfig& config, double t_first_s);
model::CrankKinematics crank_kinematics(const SimConfig& config);  // the run started at source time 0

// Cylinder pressure at an unwrapped crank angle: the engine cycle of that angle's cycle index (with its
// seeded cycle-to-cycle variation, at that cycle's operating point), recomputed when the index changes.
// Deterministic, so the encoder and microphone threads, each with its own cache, see the same pressure.
class EngineCycleCache {
 public:
  explicit EngineCycleCache(const SimConfig& config);  // the run started at source time 0
  EngineCycleCache(const SimConfig& config, std::shared_ptr<const OperatingProfile> profile);
  double pressure_pa(double theta_deg);

 private:
  std::shared_ptr<const OperatingProfile> profile_;
  double full_load_nm_;
  std::uint64_t seed_;
  double sigma_;
  model::engine::EngineCycle cycle_;
  std::int64_t index_ = 0;
  bool valid_ = false;
};

using drivers::BlockWriter;

// Encoder + pressure as a DAQ card sees them: an edge every encoder_resolution_deg at the instant theta(t)
// reaches it; each edge clocks a scan of the true cylinder pressure through the pressure chain (floor, flicker,
// transducer_noise, ADC: counter-based on the edge index), the card's 32-bit position counter (reset to 0 by the
// once-per-revolution index, kIndexAngleDeg after firing TDC) and an 80 MHz timestamp. The scans go through
// EdgeStreamAssembler, the decoder of a real encoder-clocked card: it finds the phase from the pressure, checks
// each revolution's count at the index, and resamples to 40 kHz (NaN crank where the encoder cannot be trusted).
// Encoder, pressure-channel faults of config.faults act on the counter and on the converter's samples.
class PressureGenerator {
 public:
  static constexpr double kIndexAngleDeg = 37.0;  // crank angle of the index after a TDC (rounded to an edge)
  static constexpr double kTimebaseHz = 80e6;

  PressureGenerator(const SimConfig& config, double t_first_s);
  // With the run's operating profile (operating_profile(config, t_first_s)), built once for every generator.
  PressureGenerator(const SimConfig& config, double t_first_s, std::shared_ptr<const OperatingProfile> profile);
  ~PressureGenerator();
  void advance(double t_end_s, BlockRing& ring);  // every edge before t_end_s
  // The crank-angle stream (each edge's sample) goes to this ring too, its blocks that begin at first_index() or
  // later; nullptr: nowhere.
  void set_angle_ring(BlockRing* ring);
  std::uint64_t blocks_written() const { return forwarded_; }
  std::int64_t first_index() const { return first_index_; }
  std::uint64_t clipped_samples() const { return chain_.clipped_samples(); }  // encoder samples the ADC clipped
  const comedi::EdgeStreamCounters& encoder_counters() const;

 private:
  void fill_batch(double t_end_s, std::size_t& n);
  void apply_channel_faults(std::size_t n);
  void add_scheduled_transducer_noise(std::size_t n);
  void count_edge(std::int64_t edge, double t, double pressure, BlockRing& ring);
  void scan(double t, double pressure, BlockRing& ring);
  void forward(BlockRing& ring);
  void forward_angles();

  std::shared_ptr<const OperatingProfile> profile_;
  model::CrankKinematics kin_;
  EngineCycleCache cache_;
  model::engine::PressureChain chain_;
  SimConfig::PressureReadout readout_;
  std::vector<SimFault> faults_;
  std::vector<ScheduledEffect> schedule_;  // those with transducer_noise: on the measured pressure
  std::uint64_t seed_;
  double resolution_deg_;
  double min_rpm_;  // the slowest operating point of the run
  std::int64_t counts_per_rev_;
  std::int64_t index_edge_;  // an edge at the index (edges index_edge_ + k * counts_per_rev_)
  std::int64_t next_edge_;   // edge m at m * resolution
  std::int64_t first_index_;
  double t_first_;
  double origin_s_;             // the counters' start, s on the source clock (whole microseconds)
  std::uint32_t counter_ = 0;   // the card's position counter
  double held_pressure_ = 0.0;  // last converter sample (a stuck converter repeats it)
  std::unique_ptr<comedi::EdgeStreamAssembler> decoder_;
  BlockRing staging_;  // the decoder's output, passed on from first_index_ (pre-roll frames trimmed)
  SampleBlock trimmed_;
  BlockRing* angle_out_ = nullptr;  // the crank-angle stream's ring
  BlockRing angle_staging_;         // the decoder's crank-angle blocks, passed on from first_index_
  std::uint64_t forwarded_ = 0;     // blocks written to the ring
  std::size_t batch_;               // edges per chain call
  std::vector<double> t_, x_;
  std::vector<std::int64_t> edge_;
};

// The virtual engine's acoustic side for a configuration: thesis microphone layout unless given, the configured
// true block, spread, floor, microphone and pressure chains and effects, the mean pressure of the nominal cycle
// (so the AC coupling starts settled). input_rate_hz: rate of the pressure feed; the microphones come out at
// config.mic_rate_hz.
model::engine::VirtualEngineConfig virtual_engine_config(const SimConfig& config, double input_rate_hz);

// The true engine as a model::engine::PressureFeed: cylinder pressure and unwrapped crank angle at t0 + i / rate
// (an engine at rest: its static pressure, the crank at 0).
class EngineFeed final : public model::engine::PressureFeed {
 public:
  EngineFeed(const SimConfig& config, std::shared_ptr<const OperatingProfile> profile, double t0_s, double rate_hz);
  void fill(std::int64_t first, double* pressure_pa, double* crank_deg, std::size_t n) override;

 private:
  model::CrankKinematics kin_;
  EngineCycleCache cache_;
  double t0_, rate_;
  bool stopped_;
  double static_pa_;
};

// Microphones: model::engine::VirtualEngine fed with the true pressure at twice the card rate renders the card-rate
// microphone frames (true block, effects, acoustic delay, per-microphone spread and directivity, floor,
// self-noise, ADC); the card stream is resampled to 40 kHz.
class MicGenerator {
 public:
  MicGenerator(const SimConfig& config, double t_first_s);
  MicGenerator(const SimConfig& config, double t_first_s, const std::shared_ptr<const OperatingProfile>& profile);
  void advance(double t_end_s, BlockRing& ring);  // every 40 kHz frame before t_end_s
  std::uint64_t blocks_written() const { return writer_.blocks_written(); }
  std::int64_t first_index() const { return first_index_; }
  // Per-microphone gain (linear, energy mean 1) and delay (s), for tests and logs.
  const std::vector<double>& gains() const { return engines_.front().spread_gains(); }
  std::vector<double> delays_s() const { return engines_.front().delays_s(); }
  std::uint64_t clipped_samples() const { return engines_.front().mic_clipped(); }  // card samples the ADC clipped

 private:
  void render(std::size_t n);
  void apply_channel_faults(std::size_t n);

  double card_rate_;
  double t0_;            // sim time of fine index 0, card index 0 and local 40 kHz index 0
  std::int64_t index0_;  // global 40 kHz index of local index 0
  std::int64_t first_index_;
  std::uint32_t mics_;
  // One engine per step of the effect schedule (sim_effect_schedule.hpp), each with its own feed: engine 0 the
  // configured effects, engine k the first k scheduled ones on top.
  std::vector<EngineFeed> feeds_;
  std::vector<model::engine::VirtualEngine> engines_;
  std::vector<ScheduledEffect> schedule_;
  std::vector<double> layer_card_;  // engine k's frames while mixing
  dsp::RationalResampler to_pipeline_;
  std::int64_t card_next_ = 0;  // next card frame of the microphones
  double t_first_;
  double adc_range_pa_;  // the card's rails (overload clips there)
  std::uint64_t seed_;
  std::vector<SimFault> faults_;
  std::vector<double> held_;  // per microphone: last card sample (a stuck converter repeats it)
  BlockWriter writer_;
  std::vector<double> mic_card_, out_;
};

}  // namespace noisemon::drivers::sim
