// The effect library of the virtual engine: physical effects a real engine and test cell have and the block
// model (eq. 4.13 with its parameters) may lack. `noisemon sim --effect NAME=MAGNITUDE` injects them into the
// "true" engine so the diagnosis can be proven on data whose effect is known (the effect list: docs/diagnosis.md).
//
// Each effect has ONE magnitude with a physical unit; `NAME` alone takes the documented default (the
// realistic magnitude the withheld-effect tests use). A few effects take optional qualifiers after the
// magnitude, `NAME=MAGNITUDE,key=value,...` (e.g. `second_mode=6,hz=3150`), each with a documented default.
// The catalogue (effect_catalog()) holds the authoritative text: unit, meaning, default, realistic range.
//
// How each is injected (VirtualEngine applies them; the functions below are the physics):
//  cubic_damping     b3 (N s^3/m^3) added to the true block's cubic damper (eq. 4.13).
//  cubic_stiffness   k3 (N/m^3) added to the true block's cubic spring (eq. 4.13).
//  second_mode       a further structural resonance (a cover panel driven by the block, radiating in parallel):
//                    y -> y + a R(y), R(s) = (w2/Q) s / (s^2 + (w2/Q) s + w2^2) unit-peak band-pass at f2
//                    (default 2 kHz, Q 5), a = 10^(M/20) - 1, so the structural response at f2 is M dB above
//                    the main path alone (and unchanged far from f2).
//  mechanical_noise  crank-angle-locked impacts (piston slap, valve seating and lash, injector), the same in
//                    motored and fired cycles: Leq(A) M dB re 20 uPa at each microphone at 3050 rpm, scaled
//                    +30 log10(n / 3050 rpm) with speed (impact amplitude proportional to speed). Radiated by
//                    the engine: it reaches the microphones with the acoustic delay and per-microphone spread.
//  background_noise  stationary test-cell ventilation noise, independent at each microphone, Lp(A) M dB.
//  transducer_noise  more floor than configured: white Gaussian noise of M bar rms per encoder sample added to
//                    the MEASURED pressure only (the engine and the microphones hear the true pressure), on top
//                    of (in quadrature with) the chain's configured floor (model/engine/pressure_chain.hpp), before its
//                    ADC. The configured floor is what a run directory records (pressure.noise_floor_bar); this
//                    effect is the unknown a diagnosis must find.
//  mic_gain          one microphone channel (default microphone 1 of Table 3.1) reads M dB high: everything it
//                    records is scaled by 10^(M/20) (a wrong sensitivity entered at calibration).
//  speed_dependence  the structural transfer (block + second mode) changes by M dB per 1000 rpm relative to
//                    3050 rpm: gain 10^(M (n - 3050) / 1000 / 20) on the radiated combustion noise.
//  foreign_soi_gain  TEST-ONLY "foreign" effect, outside the effect list and outside every diagnosis
//                    candidate: the structural transfer of FIRED cycles changes by M dB per degree of injection
//                    advance relative to 18 deg BTDC (earlier injection -> louder than any block predicts).
//                    Used to prove the `unexplained` verdict; never a diagnosis answer.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "model/block_params.hpp"
#include "model/engine/random.hpp"

namespace noisemon::model::engine {

// Reference values the effects are defined against.
inline constexpr double kEffectReferenceSpeedRpm = 3050.0;  // thesis idle: speed-scaled effects are exact here
inline constexpr double kForeignReferenceSoiDeg = 18.0;     // foreign_soi_gain is zero at this SOI

// ------------------------------------------------------------------------------------------ catalogue

struct EffectQualifierInfo {
  std::string_view key;
  std::string_view unit;
  std::string_view meaning;
  double default_value;
  double min, max;  // accepted
};

struct EffectInfo {
  std::string_view name;
  std::string_view unit;     // of the magnitude
  std::string_view meaning;  // what the magnitude is, physically (one line)
  std::string_view how;      // how it is injected, where, and what "off" is (one or two lines)
  double default_magnitude;  // realistic; used by the withheld-effect tests
  double realistic_min, realistic_max;
  double min, max;  // accepted by the parser
  std::span<const EffectQualifierInfo> qualifiers;
  bool test_only;  // not one of the listed effects (the foreign effect)
};

// The eight effects of docs/diagnosis.md in its order, then the test-only foreign effect.
std::span<const EffectInfo> effect_catalog();
// nullptr when unknown.
const EffectInfo* find_effect(std::string_view name);
// Comma-separated names, the listed ones first, then "(test only: foreign_soi_gain)".
std::string valid_effect_names();
// Human-readable table of every effect (name, unit, meaning, default, realistic range, qualifiers): the text of
// `noisemon sim --list-effects` and of its --help.
std::string effect_help_text();

// ------------------------------------------------------------------------------------------ parsing

// One `NAME[=MAGNITUDE][,key=value...]` as given.
struct EffectSetting {
  std::string name;
  double magnitude = 0.0;
  std::vector<std::pair<std::string, double>> qualifiers;  // only those given
};

// Throws std::invalid_argument naming the text and what is wrong (unknown names list the valid ones).
EffectSetting parse_effect(std::string_view text);

// The effects injected into the true engine. Default-constructed: none.
struct Effects {
  double cubic_damping_n_s3_m3 = 0.0;
  double cubic_stiffness_n_m3 = 0.0;
  double second_mode_db = 0.0;
  double second_mode_hz = 2000.0;
  double second_mode_q = 5.0;
  double second_mode_phase_deg = 0.0;  // the mode's phase against the block's output at f2 (the diagnosis fits it)
  std::optional<double> mechanical_noise_dba;  // nullopt: off
  std::optional<double> background_noise_dba;  // nullopt: off
  double transducer_noise_bar = 0.0;           // rms per encoder sample
  double mic_gain_db = 0.0;
  int mic_gain_mic = 1;  // 1-based (Table 3.1 numbering)
  double speed_dependence_db_per_krpm = 0.0;
  double foreign_soi_gain_db_per_deg = 0.0;

  std::vector<EffectSetting> settings;  // what was added, in order (for truth.json and logs)

  // Adds one effect; throws std::invalid_argument for an effect given twice or a bad qualifier.
  void add(const EffectSetting& setting);
  bool empty() const { return settings.empty(); }
};

// Parses every text with parse_effect and adds it.
Effects parse_effects(const std::vector<std::string>& texts);

// ------------------------------------------------------------------------------------------ physics

// The true block with the cubic effects added (b3 += cubic_damping, k3 += cubic_stiffness).
BlockParams with_structural_effects(const BlockParams& true_block, const Effects& effects);

// Linear gain on the structural (combustion) noise path: speed_dependence and the foreign effect.
double structural_gain(const Effects& effects, double speed_rpm, double soi_deg_btdc, bool motored);

// second_mode: y + a (cos(phi) R(y) - sin(phi) D(y)), R the unit-peak resonance at f2 (velocity-like: 1 at f2) and D
// its displacement-like partner (-j at f2), both discretised by the bilinear transform pre-warped at f2, so the
// mode's contribution at f2 is exactly a e^(j phi), a = 10^(M/20) - 1. phi = 0 (the simulator's effect): a mode in
// phase with the block's output, the gain at f2 exactly 10^(M/20); another phase is a mode radiating with its own
// phase (a panel elsewhere on the engine), a peak beside a dip. Streaming, no allocation. Inactive (exact
// pass-through) for M = 0.
class SecondModeFilter {
 public:
  SecondModeFilter(const Effects& effects, double fs_hz);
  bool active() const { return a_ != 0.0; }
  void process(double* y, std::size_t n);

 private:
  double a_ = 0.0, cos_ = 1.0, sin_ = 0.0;
  double b0_ = 0, b2_ = 0, a1_ = 0, a2_ = 0;  // normalised band-pass biquad (b1 = 0)
  double l0_ = 0, l1_ = 0;                    // the low-pass partner's numerator (l2 = l0), over Q; same poles
  double x1_ = 0, x2_ = 0, y1_ = 0, y2_ = 0, d1_ = 0, d2_ = 0;
};

// One crank-angle-locked impact source of mechanical_noise.
struct ImpactEvent {
  std::string_view name;
  double angle_deg;    // cycle angle, 0 = firing TDC; for the injector: added to -SOI
  bool at_soi;         // angle is relative to the start of injection
  double relative_db;  // A-weighted impact energy relative to the strongest event
  double ring_hz;      // the structural mode the impact rings
  double decay_s;      // its exponential decay time constant
};
std::span<const ImpactEvent> mechanical_events();
inline constexpr double kImpactRiseS = 50e-6;           // onset time constant of every impact
inline constexpr double kImpactAmplitudeSigmaDb = 1.5;  // cycle-to-cycle scatter of each impact's level
inline constexpr double kImpactJitterDeg = 0.3;         // cycle-to-cycle scatter of each impact's angle

// mechanical_noise: the impacts of every event in every cycle, added to a signal sampled at fs whose crank
// angle (unwrapped, increasing) is given per sample. Deterministic in (seed, cycle, event): chunking does not
// change the result. Streaming, no allocation after construction.
class MechanicalNoise {
 public:
  MechanicalNoise(double level_dba, double speed_rpm, double soi_deg_btdc, double fs_hz, std::uint64_t seed);
  void add(const double* crank_deg, double* out, std::size_t n);
  // Peak amplitude (Pa) of an event's impact before the random scatter, at this speed.
  double amplitude_pa(std::size_t event) const { return amp_[event]; }

 private:
  struct Active {
    double re1, im1, re2, im2;  // the two complex exponentials (decay; decay + rise)
    double rot1_re, rot1_im, rot2_re, rot2_im;
    std::size_t event;
  };
  void schedule_next();
  void start(std::size_t event, double delay_s, std::int64_t cycle);

  double fs_, soi_;
  std::uint64_t seed_;
  std::vector<double> amp_, angle_;
  std::vector<std::size_t> order_;  // events by cycle angle
  std::vector<Active> active_;      // fixed capacity
  std::size_t active_count_ = 0;
  bool started_ = false;
  double prev_crank_ = 0.0;
  std::int64_t next_cycle_ = 0;
  std::size_t next_slot_ = 0;  // index into order_
  double next_angle_ = 0.0;    // unwrapped, jittered
};

// background_noise at one microphone: white Gaussian noise through a first-order low-pass at
// kVentilationCornerHz (power spectral density flat below, falling 6 dB per octave above; 1/3-octave band
// levels peak near the corner and fall 3 dB per octave above it), scaled so its A-weighted level over
// 20 Hz - 20 kHz is the magnitude. Sequential, from its seed.
inline constexpr double kVentilationCornerHz = 200.0;
class BackgroundNoise {
 public:
  BackgroundNoise(double level_dba, double fs_hz, std::uint64_t seed);
  // The same level and spectrum with another seed (skips the level integral: for many microphones).
  BackgroundNoise(const BackgroundNoise& shape, std::uint64_t seed);
  double next();

 private:
  rnd::Normal normal_;
  double scale_, alpha_, state_ = 0.0;
};

// transducer_noise: rms per encoder sample (Pa) of the added white noise, whatever the sample rate; 0 when off.
double transducer_noise_rms_pa(const Effects& effects);
// Adds the transducer noise to n pressure samples whose global sample indices start at first_index
// (counter-based: the noise of sample i depends only on seed and i; independent of the chain's own floor).
void add_transducer_noise(const Effects& effects, std::uint64_t seed, std::int64_t first_index, double* pressure_pa,
                          std::size_t n);

// mic_gain: the linear factor of microphone `mic` (0-based) — 10^(M/20) for the chosen one, 1 otherwise.
double mic_gain_factor(const Effects& effects, std::size_t mic);

}  // namespace noisemon::model::engine
