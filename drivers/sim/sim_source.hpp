// The virtual engine: the daemon's embedded default source, so noisemond runs with no hardware.
//
// Driver threads (paced to the wall clock):
//  - encoder + pressure: crank kinematics with small speed fluctuation, an encoder with configurable
//    resolution and a once-per-cycle reference; cylinder pressure from a single-zone model with the gas ringing
//    of the premixed burn, sampled on every encoder edge through the pressure chain (floor, flicker, ADC);
//    resampled (NonuniformResampler) to 40 kHz -> Streams::pressure.
//  - microphones: the "true" block model driven by the true pressure, acoustic delay, small per-microphone
//    differences and directivity, the test cell's background floor and each microphone's self-noise and ADC,
//    sampled at the card rate (51.2 kHz) and resampled (RationalResampler) to 40 kHz -> Streams::mics. The
//    acoustic side is model::engine::VirtualEngine, with the configured effects.
//  The measurement chains are realistic by default (docs/sources-and-formats.md, "The simulated engine"); ADC clipping
//  is counted in counters() ("sim.pressure.adc_clipped", "sim.mics.adc_clipped").
//  - operating point: speed, load, injection timing at 10 Hz -> Streams::operating_point.
//  With the engine stopped (SimConfig::stopped), the pressure is sampled on a timer instead (sim_stopped.hpp).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/sim/sim_effect_schedule.hpp"
#include "drivers/sim/sim_faults.hpp"
#include "drivers/sim/sim_operating_schedule.hpp"
#include "drivers/source.hpp"
#include "drivers/worker_thread.hpp"
#include "model/block_params.hpp"
#include "model/engine/effects.hpp"
#include "model/engine/gas_ringing.hpp"
#include "model/engine/mic_chain.hpp"
#include "model/engine/pressure_chain.hpp"

namespace noisemon::drivers::sim {

struct SimConfig {
  // Operating point (thesis conditions: idle 3050 rpm / 0 N m, full load 3450 rpm; SOI 12..24 deg BTDC).
  double speed_rpm = 3050.0;
  double load_nm = 0.0;
  double full_load_nm = 20.0;  // load at which the fuelling is full; sets the injected fuel mass
  double soi_deg_btdc = 18.0;
  bool motored = false;
  double speed_fluctuation = 0.01;  // peak relative speed ripple within a cycle
  double cycle_variation = 0.03;    // relative cycle-to-cycle variation of the heat release
  // true: the engine at rest (sim_stopped.hpp): the pressure sampled on the card's timer at static_pressure_bar, the
  // microphones hearing the cell's floor, the speed 0; the operating point above is not run.
  bool stopped = false;
  double static_pressure_bar = 1.013;  // the cylinder's pressure at rest: ambient, or a dead-weight tester's
  // Changes of the operating point mid-run (sim_operating_schedule.hpp): none, the one above throughout.
  std::vector<OperatingStep> operating_schedule;
  // Encoder.
  double encoder_resolution_deg = 0.1;
  // Acoustics.
  std::uint32_t mic_count = 10;
  std::vector<std::array<double, 3>> mic_positions_m;  // empty: thesis Table 3.1
  double radius_m = 1.75;
  double speed_of_sound_m_s = 343.0;
  double mic_rate_hz = 51200.0;
  double mic_gain_spread_db = 0.3;    // per-microphone gain differences (deterministic from seed)
  double background_noise_db = 40.0;  // per-microphone pink floor, unweighted Lp up to 20 kHz, dB re 20 uPa
  model::BlockParams true_block = model::preset("linear");  // the engine's "true" structural response
  model::engine::Effects effects;  // effects injected into the true engine (model/engine/effects.hpp); none by default
  std::vector<ScheduledEffect> scheduled_effects;  // effects that switch on mid-run (sim_effect_schedule.hpp): none
  // The realistic test cell (each part documented and cited in its header; each switchable off):
  model::engine::PressureChainConfig pressure_chain;  // floor 0.02 bar, flicker off, 16-bit ADC over 0..250 bar
  // The card's conversion of the chain's output. With nominal_mv_per_bar > 0 the chain is a voltage-output
  // transducer of that sheet sensitivity (its gain_error against the sheet) and the card converts its volts with
  // card_mv_per_bar, less card_offset_bar, as [comedi.pressure] does (the daemon hands its values over): a
  // calibration of [comedi.pressure] shows on the virtual engine. 0: the chain's output is the reading.
  struct PressureReadout {
    double nominal_mv_per_bar = 0.0;
    double card_mv_per_bar = 0.0;  // 0: the sheet's
    double card_offset_bar = 0.0;
  } pressure_readout;
  model::engine::MicChainConfig mic_chain;      // self-noise 20 dB(A), directivity +-1 dB, 24-bit ADC +-800 Pa
  model::engine::GasRingingParams gas_ringing;  // combustion-excited gas ringing in the true pressure
  std::uint64_t seed = 1;
  std::vector<SimFault> faults;  // injected faults (drivers/sim/sim_faults.hpp): none by default
  // true: the driver threads keep to the wall clock, as hardware does. false: as fast as the processing takes the
  // data, the streams in step and never a block lost to the pace (soak tests, benchmarks); utimes then run ahead of
  // the wall clock.
  bool paced = true;
  // Scheduling of the driver threads nm-pressure, nm-mics and nm-op (the daemon's [threads]).
  struct Threads {
    ThreadPolicy pressure, mics, operating_point;
  } threads;
};

// The configuration with an ideal test cell: no pressure-chain floor or ADC, no microphone self-noise, directivity
// or ADC, no gas ringing (the pink floor background_noise_db and the gain spread stay as configured).
SimConfig with_ideal_cell(SimConfig config);

std::unique_ptr<Source> make_sim_source(const SimConfig& config);

}  // namespace noisemon::drivers::sim
