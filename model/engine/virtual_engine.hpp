// The acoustic side of the virtual engine: from the true cylinder pressure and crank angle (uniform grid) to the
// microphone signals a test cell records, with the effects of model/engine/effects.hpp injected. One implementation,
// used by the real-time sim source (drivers/sim/sim_generators) and by the offline run generator (drivers/sim/sim_run).
//
// Signal path (input rate fs_in, e.g. 102.4 kHz = twice the card rate; output rate fs_out = fs_in / D):
//   p_true --true block (eq. 4.13 + cubic_damping, cubic_stiffness)--> y
//   y --second_mode--> --structural gain (speed_dependence, foreign)--> --AC coupling (2 Hz high-pass, as the
//   microphones and the card)--> + mechanical_noise impacts (crank-angle locked) = the engine's sound at the
//   origin --decimate to fs_out--> microphone i hears it delayed by |x_i| / c (whole output samples), scaled
//   by its spread gain and through its directivity filter (model/engine/mic_chain.hpp), plus the test cell's pink
//   floor, background_noise and its own self-noise; its ADC (clipping counted), then mic_gain scales everything one
//   microphone records.
// Measured pressure = the pressure chain (model/engine/pressure_chain.hpp: floor, flicker, transducer_noise, ADC) on
// the true pressure (measured_pressure()).
//
// Deterministic from the seeds: `seed` for every random realisation of a run (noise, impacts), `setup_seed` for
// the per-microphone spread gains and directivity (a property of the installation, the same for every run of a
// campaign).
// Streaming and allocation-free after construction; output frame j is the microphone signal at t = j / fs_out,
// t = 0 being input sample 0.
#pragma once

#include <array>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "model/block_params.hpp"
#include "model/engine/effects.hpp"
#include "model/engine/mic_chain.hpp"
#include "model/engine/pressure_chain.hpp"

namespace noisemon::model::engine {

struct VirtualEngineConfig {
  double input_rate_hz = 102400.0;                     // pressure / crank grid
  double output_rate_hz = 51200.0;                     // microphones; input_rate / output_rate must be a whole number
  BlockParams true_block = preset("linear");           // before the structural effects
  std::vector<std::array<double, 3>> mic_positions_m;  // engine at the origin; one entry per microphone
  double speed_of_sound_m_s = 343.0;
  double mic_gain_spread_db = 0.3;  // per-microphone directivity differences (normal, energy mean exactly 1)
  // Stationary floor at each microphone: pink (equal energy per octave), unweighted Lp up to 20 kHz,
  // dB re 20 uPa; -inf: none. The background_noise effect comes on top of it.
  double floor_db = 40.0;
  // The measurement chains (realistic by default; MicChainConfig::ideal(), PressureChainConfig::ideal(): none).
  MicChainConfig mic_chain;
  PressureChainConfig pressure_chain;
  double ac_coupling_hz = 2.0;
  double mean_pressure_pa = 0.0;  // expected mean input: the AC coupling starts settled on its static response
  // Operating point (for the speed- and timing-dependent effects).
  double speed_rpm = 3050.0;
  double soi_deg_btdc = 18.0;
  bool motored = false;
  Effects effects;
  std::uint64_t seed = 1;
  std::uint64_t setup_seed = 1;
};

// Per-microphone spread gains: 10^(spread_db N(0,1) / 20), normalised to an energy mean of exactly 1.
std::vector<double> mic_spread_gains(std::size_t count, double spread_db, std::uint64_t setup_seed);

// What drives the virtual engine: n consecutive input samples from input index `first` (index 0 at t = 0).
class PressureFeed {
 public:
  virtual ~PressureFeed() = default;
  virtual void fill(std::int64_t first, double* pressure_pa, double* crank_deg, std::size_t n) = 0;
};

class VirtualEngine {
 public:
  explicit VirtualEngine(const VirtualEngineConfig& config);
  ~VirtualEngine();
  VirtualEngine(VirtualEngine&&) noexcept;
  VirtualEngine& operator=(VirtualEngine&&) noexcept;

  std::size_t mic_count() const;
  // The next `frames` microphone frames (frame-major: mics[f * mic_count() + i], Pa), pulling input from the
  // feed as needed (always in order, in batches).
  void render(PressureFeed& feed, double* mics, std::size_t frames);
  std::int64_t frames_rendered() const;

  // The pressure chain on the true pressure of input samples [first, first + n) at the input rate
  // (counter-based noise: any chunking gives the same values).
  void measured_pressure(std::int64_t first, const double* p_true, double* p_measured, std::size_t n);
  // Samples clipped by the ADCs so far (microphones: every channel's samples).
  std::uint64_t pressure_clipped() const;
  std::uint64_t mic_clipped() const;

  const VirtualEngineConfig& config() const;
  const BlockParams& structural_block() const;      // the true block with the cubic effects
  const std::vector<double>& spread_gains() const;  // per microphone, on the engine's sound
  // Per microphone, the directivity filter's response at f (complex; 1 without directivity).
  std::complex<double> directivity_response(std::size_t mic, double f_hz) const;
  std::vector<double> delays_s() const;  // per microphone (whole output samples)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace noisemon::model::engine
