// An independent test cell: run directories (the interchange format of docs/sources-and-formats.md) made from the REAL
// Yanmar L100V cylinder-pressure records by code that shares nothing with the project (no model/, drivers/, dsp/,
// daemon/): its own table parser, its own frequency-domain synthesis of the thesis's eq. 4.1, its own microphones,
// floors and effects, its own A-weighting and its own writers. The gap diagnosis is then proven on data whose truth it
// did not define (tests/independent/test_independent_diagnosis.cpp runs the real `noisemon diagnose` on it).
//
// The pressure (per condition, `cycles` engine cycles end to end, 0.2 deg encoder steps)
//   The record's cycles are laid out in crank angle as they were recorded (column j covers -180 ... 539.8 deg of
//   cycle j; its 360 ... 539.8 part is the -360 ... -180 part of cycle j+1), so `cycles` complete cycles
//   [720k - 360, 720k + 360) use `cycles + 1` consecutive record columns from `first_cycle`. At a constant speed
//   the crank-angle samples are uniform in time (30 * rpm samples per second): the speed is only a time scale.
//   The record's first row is its pegging value (the same in every column); it is kept as recorded.
//   Load: p = motored + load_scale * (fired - motored), applied to the CLEAN pressure (below) with the motored
//   record's ensemble mean over all its cycles, low-passed at 4 kHz, as "motored"; the record-minus-clean
//   difference (what the chain added) is then added back unscaled.
//
// The clean pressure the engine hears, the recorded pressure the chain writes
//   The real records carry their chain's broadband floor (data README: about 0.15 bar per sample motored, 0.25
//   fired). That floor is a measurement artefact: the structure never hears it. What else the record holds above a
//   few kHz, nobody can tell sample by sample: the combustion-excited gas ringing (about 5.7 kHz here, a new random
//   phase every cycle), other cycle-to-cycle combustion variation, and broadband bursts near -150 deg (intake valve
//   closing) and 360 deg (gas-exchange TDC) in both records, 7 ... 24 dB above the quiet strokes. The floor is
//   taken as the chain's definition has it: STATIONARY, at the record's own level where it is quietest. Per band
//   (third octaves, kFloorBands) and crank angle the record's power P (over all its cycles, +-10 deg) is compared
//   with that floor F (its 5th percentile over the cycle), and the engine hears the record less its floor's power
//   (spectral subtraction):
//     clean = LP4k(mean) + LP1k(cycle - mean) + sum over bands of sqrt(max(0, 1 - F/P(theta))) * rest_band
//   where rest = record - LP4k(mean) - LP1k(cycle - mean), mean = the condition's ensemble mean per crank angle and
//   LP = zero-phase (frequency-domain, raised-cosine edge 0.8 ... 1.25 fc) low-passes in Hz at the condition's
//   speed. So the engine hears the gas ringing and the bursts nearly whole (P >> F), the quiet strokes' floor not
//   at all (P = F), and pressure.csv minus what the engine hears carries about the same power above 4 kHz in every
//   90 deg window (checked by a test: the floor is stationary as defined). The microphones hear eq. 4.1 driven by
//   `clean`; pressure.csv gets the RECORDED values: with load_scale = 1, the record itself, sample for sample.
//   The price: the record's content within a dB or two of its quietest level, wherever it stands, is partly
//   treated as floor; what the record cannot tell apart, no analysis of it can.
//
// The microphones (51.2 kHz, 10-channel IEEE-float WAV, Pa)
//   y = ka (j2pi f + wb) / ((j2pi f)^2 + 2 zeta wn j2pi f + wn^2) u (eq. 4.1, u = clean pressure in Pa minus its
//   mean), synthesised in the frequency domain over the whole run as one period (the run's cycles repeat; its
//   two ends are both in the gas exchange at about 1 bar): FFT of the crank-angle samples, multiply by H(f), the
//   microphone's directivity gain and the delay exp(-j2pi f r/c) (r = 1.75 m, c = 343 m/s: the sound radiated
//   at the run's end arrives at its start, as in a periodic engine), inverse FFT onto the 51.2 kHz grid
//   (band-limited trigonometric interpolation; only frequencies below both Nyquist limits are kept). To make
//   the run an integer number of 51.2 kHz samples with small prime factors, the speed is adjusted by < 1 %;
//   run.json states the speed used. Microphones at the thesis's Table 3.1 positions, each with a fixed
//   directivity gain within +-1 dB, its own white self-noise (20 dB(A)) and an independent pink floor (40 dB
//   re 20 uPa, unweighted, 20 Hz ... Nyquist).
//
// The structure (Structure, Chain::structure)
//   Eq. 4.1's form with the cell's own constants, far from the thesis's (Table 4.1's linear preset is ka 11.885,
//   100 Hz, zeta 0.35, 5 kHz): the diagnosis starts from the preset and must tune its baseline to this engine.
//
// Effects (each independent of the project's implementation, and none the form of a candidate exactly)
//   second_mode        a panel radiating beside the block, driven by the same pressure: its own mass-spring-damper
//                      velocity response (f0, Q) added to the structural path, Y = H U + c R(f) U, c real and sized
//                      so that |Y| / |H U| is +magnitude dB at f0. The two paths' phases are the physics' (not the
//                      candidate's |1 + a R|^2 on the block's output)
//   mic_gain           one microphone's sensitivity error over its whole channel (engine, impacts, floors,
//                      background), a first-order shelf G(f) = 1 + (g - 1) jf/fc / (1 + jf/fc), g = 10^(dB/20):
//                      0 dB at low frequency, +dB well above the corner fc (a flat error with fc = 0)
//   background_noise   stationary noise at every microphone, independent per microphone, spectrum 1/(1+(f/500)^2)
//                      from 20 Hz, Lp(A) = magnitude at each microphone
//   speed_dependence   structural path amplitude (speed / speed_ref)^exponent (a power law, not dB per krpm)
//   mechanical_noise   crank-angle-locked decaying impacts (piston slap, valves) near fixed angles, the same
//                      in fired and motored runs; array-average Leq(A) = magnitude at mechanical_ref_rpm (the mean
//                      energy per impact fixed: +10 log10(rpm / ref) elsewhere); each impact jittered in angle from
//                      cycle to cycle (Gaussian, mechanical_jitter_deg rms) and in energy (log-normal,
//                      mechanical_energy_spread_db rms, mean energy kept)
//   block stop         (for cubic_stiffness) a symmetric piecewise-linear hardening of the block: beyond |z| = z0 a
//                      second spring of ratio * k1; made in the time domain (cell_block.hpp)
//   quadratic drag     (for cubic_damping) a damping force b2 z'|z'|, likewise in the time domain
//   transducer_noise   white noise per 0.2 deg sample added to pressure.csv on top of the record's own floor (which
//                      every run has, effect or not); the engine does not hear it
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace indep {

inline constexpr double kPi = std::numbers::pi;
constexpr double kRecordStepDeg = 0.2;
constexpr int kSamplesPerCycle = 3600;  // 720 deg / 0.2 deg
constexpr int kMics = 10;

// ------------------------------------------------------------------------------------------ the real records

// A cycle table: column 1 the crank angle (deg), then one column per cycle (bar). cycles_bar[c][row].
struct CycleTable {
  std::vector<double> crank_deg;
  std::vector<std::vector<double>> cycles_bar;
};

// Reads and checks a tab/space-separated table (same column count on every line, the angle increasing in
// 0.2 deg steps over exactly 720 deg). Throws std::runtime_error naming the file and line.
CycleTable read_cycle_table(const std::string& path);

struct Sources {
  CycleTable fired;    // yanmar_l100v_fired_18Nm.txt
  CycleTable motored;  // yanmar_l100v_motored.txt
};
Sources load_sources(const std::string& real_data_dir);

// ------------------------------------------------------------------------------------------ physics

// Eq. 4.1's form, Y/U in Pa per Pa: ka (j2pi f + wb) / ((j2pi f)^2 + 2 zeta wn j2pi f + wn^2).
struct Structure {
  double ka = 11.885, fb_hz = 100, zeta = 0.35, fn_hz = 5000;  // the thesis's constants (Table 4.1 linear)
};
// The cell's engine: other constants (a stiffer-damped, lower, quieter block than the thesis's).
constexpr Structure kCellStructure{7.4, 170, 0.24, 3900};
// The second cell's engine: a louder, lightly damped block resonating higher than either (issue 22's second cell).
constexpr Structure kSecondCellStructure{14.0, 90, 0.18, 6200};
std::complex<double> eq41(double f_hz, const Structure& s = Structure{});
std::complex<double> resonance(double f_hz, double f0_hz, double q);  // unit peak (1 at f0), band-pass
double a_weighting_db(double f_hz);                                   // IEC 61672-1, 0 dB at 1 kHz

const std::array<std::array<double, 3>, kMics>& mic_positions_m();  // thesis Table 3.1
const std::array<double, kMics>& directivity_db();                  // fixed, within +-1 dB

// Periodic band-limited synthesis: u holds one period (period_s) of a real signal sampled uniformly; returns
// n_out uniform samples over the same period of the signal filtered by `transfer` (a function of f in Hz,
// conjugate-symmetric by construction: only f >= 0 is asked). Frequencies at or above either Nyquist limit are
// dropped.
using Transfer = std::function<std::complex<double>(double)>;
std::vector<double> radiate(const std::vector<double>& u, std::size_t n_out, double period_s, const Transfer& transfer);

// Zero-phase periodic low-pass: cutoff in cycles per sample, raised-cosine edge from edge_lo to edge_hi times it.
std::vector<double> lowpass(const std::vector<double>& x, double cutoff_per_sample, double edge_lo = 0.8,
                            double edge_hi = 1.25);

// Bands in which the record's content above its floor is judged: the base-2 third octaves of IEC 61260-1, edges
// 1000 * 2^((2k - 1)/6) Hz for k = 1 ... 14 (1.12 ... 22.4 kHz; everything below the first edge in the first
// band, above the last in the last).
constexpr std::size_t kFloorBands = 15;

// Per band (kFloorBands) and crank angle (one cycle, 0.2 deg steps from -360 deg): the power of what the low-passed
// pressure leaves out of the record (the ensemble mean above 4 kHz, each cycle's deviation above 1 kHz), at
// speed_rpm, averaged over every cycle of the table and over +-10 deg, in dB above its 5th percentile over the cycle
// (the chain's floor in that band: its level where the record is quietest; what stands above it is pressure).
std::vector<std::vector<double>> excess_over_floor_db(const CycleTable& t, double speed_rpm);

// The chain's floor as a commissioning engineer would state it, bar rms per 0.2 deg sample: from the median absolute
// second difference along the crank angle over the compression stroke from -120 to -60 deg of every cycle (white
// noise's second difference is normal with variance 6 sigma^2; a median, unlike an rms, ignores the record's few
// bursts; the pressure's own curvature there is far below either). The data README gives 0.25 fired, 0.17 motored.
double median_second_difference_bar(const CycleTable& t);
double record_floor_bar(const CycleTable& t);

// A-weighted (or unweighted) level of a periodic record, dB re 20 uPa, from its spectrum.
double level_db(const std::vector<double>& x_pa, double fs_hz, bool a_weighted);

// ------------------------------------------------------------------------------------------ the cell

struct Condition {
  std::string name;
  double speed_rpm = 1800;  // nominal; the run uses a speed within 1 % of it (see Timing)
  double load_scale = 1.0;  // scale of the fired-minus-motored pressure
  bool motored = false;
  bool load_unknown = false;  // run.json "load_nm": null
  int first_cycle = 0;        // first record column used (0-based)
  int cycles = 16;
};

// Five fired conditions (1500 ... 2600 rpm, load scale 0.7 ... 1.3, the 1800 rpm one with load null) and two
// motored ones (1800, 2600 rpm), `cycles` cycles each from different parts of the records. `seed` picks the parts:
// seed 1 spreads them evenly over the records, every further seed moves each by 11 columns (wrapping), so that the
// engine's own cycle-to-cycle variation, the larger noise here, differs from seed to seed as the chain's does.
std::vector<Condition> default_conditions(int cycles = 16, std::uint64_t seed = 1);

// The second cell's campaign: six fired conditions at three speeds, two loads each (1400 rpm at 0.8 and 1.2,
// 2000 at 0.75 and 1.25, 2400 at 0.9 and 1.1: every speed holds a group), one motored run at 2000 rpm, `cycles`
// cycles each; `seed` moves the records' columns as in default_conditions.
std::vector<Condition> second_cell_conditions(int cycles = 24, std::uint64_t seed = 1);

// The block's nonlinearities (made in the time domain: cell_block.hpp).
struct Nonlinearity {
  double stop_at_m = 0;          // 0: no stop
  double stop_ratio = 0;         // the stop's stiffness over k1
  double quadratic_damping = 0;  // N s^2 / m^2 (per kg)
  [[nodiscard]] bool any() const { return (stop_at_m > 0 && stop_ratio > 0) || quadratic_damping > 0; }
};

struct Effects {
  Nonlinearity block;  // none: the block is eq. 4.1 exactly, synthesised in the frequency domain
  double transducer_noise_bar =
      0;  // white noise per 0.2 deg sample added to pressure.csv (the engine does not hear it)
  double second_mode_db = 0, second_mode_hz = 1600, second_mode_q = 5;
  double mic_gain_db = 0;
  int mic_gain_index = 3;                                            // 0-based: microphone 4
  double mic_gain_corner_hz = 600;                                   // the shelf's corner (0: a flat error)
  double background_dba = std::numeric_limits<double>::quiet_NaN();  // NaN: none
  double speed_exponent = 0, speed_ref_rpm = 1800;
  double mechanical_dba = std::numeric_limits<double>::quiet_NaN(), mechanical_ref_rpm = 1800;
  double mechanical_jitter_deg = 0;        // rms angle error of every impact, cycle to cycle
  double mechanical_energy_spread_db = 0;  // rms of every impact's energy, cycle to cycle (log-normal)
};

// The structural path's transfer at f (Pa per Pa, before directivity and delay): the structure, the second mode's
// panel beside it and the speed's gain.
std::complex<double> structural_transfer(double f_hz, double speed_rpm, const Structure& s, const Effects& fx);
// The speed's gain on the structural path, and the panel's own path (0 without a second mode), both in Pa per Pa.
double speed_gain(double speed_rpm, const Effects& fx);
std::complex<double> panel_transfer(double f_hz, double speed_rpm, const Structure& s, const Effects& fx);
// The microphone error's transfer at f (1 for every microphone but fx.mic_gain_index, or without the effect).
std::complex<double> mic_error(double f_hz, int mic, const Effects& fx);

struct Chain {
  Structure structure = kCellStructure;
  double fs_hz = 51200;
  double radius_m = 1.75;
  double sound_speed_m_per_s = 343;
  double self_noise_dba = 20;
  double pink_floor_db = 40;
  std::uint64_t seed = 1;  // noise realisations depend on (seed, condition index, microphone) only
  // A noisier pressure chain: white Gaussian noise of this rms per 0.2 deg sample added to pressure.csv (the engine
  // does not hear it), beside the record's own floor; not stated in run.json (the diagnosis must estimate it).
  double added_pressure_noise_bar = 0;
  // run.json states the chain's commissioned floor (pressure.noise_floor_bar): the record's own (record_floor_bar of
  // the run's table) with added_pressure_noise_bar in quadrature; never the effects' transducer noise.
  bool states_floor = false;
};

// The second cell's chain: its structure and a 0.05 bar floor added to the record's.
Chain second_cell_chain(std::uint64_t seed);

// The run's timing: the speed adjusted so that `cycles` cycles are n_out samples at fs, n_out 5-smooth.
struct Timing {
  double speed_rpm;
  double period_s;
  std::size_t n_out;
};
Timing timing(double nominal_rpm, int cycles, double fs_hz);

// One condition's pressure over [-360, 720 cycles - 360) deg in 0.2 deg steps, bar.
struct CellPressure {
  std::vector<double> recorded_bar;  // what pressure.csv gets
  std::vector<double> clean_bar;     // what the engine structure hears
};
CellPressure condition_pressure(const Sources& src, const Condition& c, double speed_rpm);

struct Run {
  Condition condition;
  Timing time;
  double fs_hz = 0;
  CellPressure pressure;
  std::vector<std::vector<double>> mics_pa;                            // [mic][sample], n_out each
  double stated_floor_bar = std::numeric_limits<double>::quiet_NaN();  // NaN: run.json states none
};

// What the structure is driven by: the clean pressure in Pa less its mean over the run.
std::vector<double> engine_input_pa(const std::vector<double>& clean_bar);

// condition_index picks the noise realisations (see Chain::seed).
Run synthesize(const Sources& src, const Condition& c, int condition_index, const Chain& chain, const Effects& fx);

// run.json, pressure.csv, mics.wav in dir (created).
void write_run_dir(const Run& run, const Chain& chain, const std::filesystem::path& dir);

// Every condition into dir/<name>/; returns the run directories.
std::vector<std::filesystem::path> write_campaign(const Sources& src, const std::vector<Condition>& conditions,
                                                  const Chain& chain, const Effects& fx,
                                                  const std::filesystem::path& dir);

}  // namespace indep
