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
#include <vector>

#include "drivers/sim_source.hpp"
#include "dsp/resample.hpp"
#include "model/block_model.hpp"
#include "model/engine_cycle.hpp"

namespace noisemon::drivers::sim {

// Pre-roll computed (not published) before the first frame: settles the resamplers and the block model.
inline constexpr double kPreRollS = 0.2;
// Start instants are multiples of this (s): the 40 kHz, 51.2 kHz and 102.4 kHz grids all meet there.
inline constexpr double kGridAlignS = 1.0 / 1600.0;

// Engine parameters and operating condition of the virtual engine for a configuration.
model::EngineCycleParams engine_params(const SimConfig& config);
model::OperatingCondition operating_condition(const SimConfig& config);
model::CrankKinematics crank_kinematics(const SimConfig& config);

// Cylinder pressure at an unwrapped crank angle: the engine cycle of that angle's cycle index (with its
// seeded cycle-to-cycle variation), recomputed when the index changes. Deterministic, so the encoder and
// microphone threads, each with its own cache, see the same pressure.
class EngineCycleCache {
 public:
  explicit EngineCycleCache(const SimConfig& config);
  double pressure_pa(double theta_deg);

 private:
  model::OperatingCondition op_;
  std::uint64_t seed_;
  double sigma_;
  model::EngineCycle cycle_;
  std::int64_t index_ = 0;
  bool valid_ = false;
};

// Fills SampleBlocks frame by frame and writes each full block (and the partial one on flush) to the ring;
// a failed write is an overrun, counted by the ring.
class BlockWriter {
 public:
  explicit BlockWriter(std::uint32_t channels) { block_.channels = channels; }
  // Frame `index` must follow the previous one; returns the slot for its channels.
  double* frame(std::int64_t index, BlockRing& ring);
  void flush(BlockRing& ring);
  std::uint64_t blocks_written() const { return written_; }

 private:
  SampleBlock block_{};
  std::uint64_t written_ = 0;
};

// Encoder + pressure: an edge every encoder_resolution_deg at the instant theta(t) reaches it, the cylinder
// pressure at the edge, NonuniformResampler to 40 kHz; the crank channel is theta(k / 40 kHz) wrapped.
class PressureGenerator {
 public:
  PressureGenerator(const SimConfig& config, double t_first_s);
  void advance(double t_end_s, BlockRing& ring);  // every edge before t_end_s
  std::uint64_t blocks_written() const { return writer_.blocks_written(); }
  std::int64_t first_index() const { return first_index_; }

 private:
  model::CrankKinematics kin_;
  EngineCycleCache cache_;
  dsp::NonuniformResampler resampler_;
  BlockWriter writer_;
  double resolution_deg_;
  std::int64_t next_edge_;  // edge m at m * resolution
  std::int64_t first_index_;
  std::size_t batch_;       // edges per resampler call
  std::vector<double> t_, x_, out_;
};

// Pink background noise (Kellet's refined filter on Gaussian white noise) at a given rms.
class PinkNoise {
 public:
  PinkNoise(double rms, std::uint64_t seed);
  double next();

 private:
  double gaussian();
  std::array<std::uint64_t, 4> s_{};
  double spare_ = 0.0;
  bool has_spare_ = false;
  double scale_;
  std::array<double, 7> b_{};
};

// Microphones: the true pressure on a grid at twice the card rate drives the true block model; its output,
// AC-coupled (2 Hz high-pass, as microphone and card), is decimated to the card rate; each microphone takes
// it delayed by its distance / c (whole card samples) and scaled by its gain; the card stream is resampled
// to 40 kHz and each channel gets its pink background noise.
class MicGenerator {
 public:
  MicGenerator(const SimConfig& config, double t_first_s);
  void advance(double t_end_s, BlockRing& ring);  // every 40 kHz frame before t_end_s
  std::uint64_t blocks_written() const { return writer_.blocks_written(); }
  std::int64_t first_index() const { return first_index_; }
  // Per-microphone gain (linear, energy mean 1) and delay (s), for tests and logs.
  const std::vector<double>& gains() const { return gains_; }
  std::vector<double> delays_s() const;

 private:
  void make_fine(std::int64_t n_end);
  void make_card(std::int64_t m_end);

  double fine_rate_, card_rate_;
  double t0_;                  // sim time of fine index 0, card index 0 and local 40 kHz index 0
  std::int64_t index0_;        // global 40 kHz index of local index 0
  std::int64_t first_index_;
  std::uint32_t mics_;
  model::CrankKinematics kin_;
  EngineCycleCache cache_;
  model::BlockModel block_;
  std::size_t latency_left_;   // block-model outputs still to drop (response before fine index 0)
  double hp_a_, hp_x_, hp_y_;  // AC coupling
  dsp::RationalResampler to_card_;
  dsp::RationalResampler to_pipeline_;
  std::vector<double> gains_;
  std::vector<std::int64_t> delay_card_;  // per mic, card samples
  std::int64_t min_delay_card_;
  std::vector<double> card_line_;         // single-channel card-rate signal, circular
  std::size_t card_mask_;
  std::int64_t fine_next_ = 0;            // next fine index to generate
  std::int64_t card_avail_ = 0;           // card samples of the common signal produced
  std::int64_t card_next_ = 0;            // next card frame of the microphones
  std::vector<PinkNoise> noise_;
  BlockWriter writer_;
  std::vector<double> u_, y_, card_tmp_, mic_card_, out_;
};

}  // namespace noisemon::drivers::sim
