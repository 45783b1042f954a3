#include "model/engine/effects.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <complex>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "dsp/levels.hpp"
#include "dsp/weighting.hpp"

namespace noisemon::model::engine {

namespace {

// Random stream identifiers: one per random quantity, so effects never share a realisation.
enum : std::uint64_t {
  kStreamImpactPhase = 0x1001,
  kStreamImpactGain = 0x1002,
  kStreamImpactJitter = 0x1003,
  kStreamTransducer = 0x2001,
};

constexpr std::array<EffectQualifierInfo, 3> kSecondModeQualifiers{{
    {"hz", "Hz", "frequency f2 of the mode", 2000.0, 50.0, 18000.0},
    {"q", "", "quality factor Q of the mode (bandwidth f2 / Q)", 5.0, 0.5, 50.0},
    {"phase", "deg",
     "the mode's phase against the block's output at f2 (0: in phase; a panel elsewhere: a peak beside a dip)", 0.0,
     -180.0, 180.0},
}};
constexpr std::array<EffectQualifierInfo, 1> kMicGainQualifiers{{
    {"mic", "", "the miscalibrated microphone, 1-based (Table 3.1 numbering)", 1.0, 1.0, 16.0},
}};

// Defaults are realistic magnitudes that leave a clear trace in the attenuation curves of the thesis
// conditions (see the table in docs/diagnosis.md, 'Proof on withheld effects': each one's measured gap).
const std::array<EffectInfo, 9> kCatalog{{
    {"cubic_damping",
     "N s^3/m^3",
     "cubic damper b3 added to the true block (eq. 4.13): damping grows with vibration velocity",
     "true block b3 += M; the resonance flattens at high amplitude (loud, early-injection cycles). Off: 0.",
     500.0,
     100.0,
     4.0e3,
     0.0,
     1.0e7,
     {},
     false},
    {"cubic_stiffness",
     "N/m^3",
     "cubic spring k3 added to the true block (eq. 4.13): stiffness grows with displacement",
     "true block k3 += M; the resonance rises with amplitude (tangent stiffness k1 + 3 k3 z^2). Off: 0.",
     5.0e12,
     1.0e12,
     2.0e13,
     0.0,
     1.0e16,
     {},
     false},
    {"second_mode", "dB", "a further structural resonance (cover panel): the structural response at f2 rises by M dB",
     "y += (10^(M/20) - 1) (cos(phase) R(y) - sin(phase) D(y)), R unit-peak resonance at f2 "
     "(default 2000 Hz, Q 5, phase 0), D its displacement-like partner; negative M: an absorber. Off: 0.",
     8.0, 3.0, 12.0, -20.0, 30.0, kSecondModeQualifiers, false},
    {"mechanical_noise",
     "dB(A)",
     "crank-angle-locked impacts (piston slap, valves, injector), Leq(A) at the microphones (energy mean) at 3050 rpm",
     "7 impacts per cycle at fixed crank angles (below), motored and fired alike (the injector is actuated in motored "
     "runs too); "
     "Leq +30 log10(n/3050 rpm). Off: not given.",
     85.0,
     75.0,
     95.0,
     0.0,
     160.0,
     {},
     false},
    // Against this engine (111 dB(A) at 1.75 m at idle) a stationary noise leaves a trace in the fired spectra above
    // the pressure chain's floor only when it is within about 10 dB of the engine: a dynamometer or a second engine in
    // the cell, not the ventilation of a hemi-anechoic room (tens of dB quieter, below every scored band).
    {"background_noise",
     "dB(A)",
     "stationary noise in the test cell (ventilation, dynamometer, a second engine), Lp(A) at each microphone (20 Hz - "
     "20 kHz)",
     "independent per microphone; white noise through a 200 Hz first-order low-pass. Off: not given.",
     105.0,
     95.0,
     110.0,
     0.0,
     160.0,
     {},
     false},
    // A worn or noisy chain: the real Yanmar records carry about 0.2 bar against a good chain's 0.02 bar.
    {"transducer_noise",
     "bar rms",
     "more pressure-chain floor than configured: extra white noise, rms per encoder sample",
     "added to the measured pressure only, in quadrature on top of the configured chain floor ([sim] "
     "pressure_noise_bar, "
     "sim --pressure-floor), before the ADC; not heard by the microphones. Off: 0.",
     0.05,
     0.02,
     0.3,
     0.0,
     10.0,
     {},
     false},
    {"mic_gain", "dB", "one microphone channel reads M dB high (wrong sensitivity at calibration)",
     "everything the chosen microphone (default 1) records is scaled by 10^(M/20). Off: 0.", 3.0, -6.0, 6.0, -40.0,
     40.0, kMicGainQualifiers, false},
    {"speed_dependence",
     "dB per 1000 rpm",
     "the structural transfer changes by M dB per 1000 rpm above 3050 rpm (below: the opposite)",
     "gain 10^(M (n - 3050) / 20000) on the radiated combustion noise (not on mechanical or background). Off: 0.",
     4.0,
     -8.0,
     8.0,
     -40.0,
     40.0,
     {},
     false},
    {"foreign_soi_gain",
     "dB per deg",
     "TEST ONLY, foreign to every diagnosis candidate: fired cycles louder by M dB per degree of SOI advance over 18",
     "gain 10^(M (SOI - 18) / 20) on the structural path of fired cycles; proves the `unexplained` verdict. Off: 0.",
     0.3,
     -1.0,
     1.0,
     -5.0,
     5.0,
     {},
     true},
}};

std::string trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return std::string(s);
}

double parse_number(std::string_view text, const std::string& what) {
  const std::string t = trim(text);
  double v = 0.0;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (t.empty() || r.ec != std::errc() || r.ptr != t.data() + t.size() || !std::isfinite(v))
    throw std::invalid_argument(what + ": \"" + t + "\" is not a finite number");
  return v;
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// Standard (one-sided) A-weighted power of a spectrum given as a function of frequency, over [f_lo, f_hi],
// trapezoid rule on a 1 Hz grid (every spectrum integrated here is smooth on that scale).
template <class Psd>
double a_weighted_integral(Psd psd, double f_lo, double f_hi) {
  const auto n = static_cast<std::size_t>(std::ceil(f_hi - f_lo));
  const double df = (f_hi - f_lo) / static_cast<double>(n);
  double sum = 0.0;
  for (std::size_t i = 0; i <= n; ++i) {
    const double f = f_lo + df * static_cast<double>(i);
    const double w = std::pow(10.0, dsp::a_weighting_db(f) / 10.0);
    sum += (i == 0 || i == n ? 0.5 : 1.0) * psd(f) * w;
  }
  return sum * df;
}

// Expected (over the random phase) A-weighted energy, Pa^2 s, of one unit-amplitude impact
//   s(t) = (e^{-a1 t} - e^{-a2 t}) sin(w0 t + phi),  t >= 0,   a1 = 1/decay, a2 = a1 + 1/rise,
// from its Fourier transform: E|S(w)|^2 = (|D(w - w0)|^2 + |D(w + w0)|^2) / 4, D(v) = 1/(a1 + jv) - 1/(a2 + jv),
// energy = 2 int_0^inf E|S(2 pi f)|^2 df.
double impact_a_weighted_energy(double ring_hz, double decay_s) {
  const double a1 = 1.0 / decay_s, a2 = a1 + 1.0 / kImpactRiseS, w0 = 2.0 * kPi * ring_hz;
  const auto d2 = [&](double v) { return (a2 - a1) * (a2 - a1) / ((a1 * a1 + v * v) * (a2 * a2 + v * v)); };
  return a_weighted_integral(
      [&](double f) {
        const double w = 2.0 * kPi * f;
        return 0.5 * (d2(w - w0) + d2(w + w0));
      },
      0.0, 20000.0);
}

constexpr std::array<ImpactEvent, 7> kEvents{{
    {"piston_slap_firing", 8.0, false, 0.0, 2000.0, 1.0e-3},
    {"piston_slap_gas_exchange", -352.0, false, -8.0, 2000.0, 1.0e-3},
    {"exhaust_valve_closing", -340.0, false, -3.0, 6300.0, 0.6e-3},
    {"intake_valve_closing", -150.0, false, -3.0, 6300.0, 0.6e-3},
    {"exhaust_valve_opening", 130.0, false, -10.0, 4000.0, 0.6e-3},
    {"intake_valve_opening", 340.0, false, -10.0, 4000.0, 0.6e-3},
    {"injector", 0.0, true, -6.0, 10000.0, 0.3e-3},
}};

}  // namespace

// ------------------------------------------------------------------------------------------ catalogue

std::span<const EffectInfo> effect_catalog() { return kCatalog; }

const EffectInfo* find_effect(std::string_view name) {
  for (const auto& e : kCatalog)
    if (e.name == name) return &e;
  return nullptr;
}

std::string valid_effect_names() {
  std::string out, test_only;
  for (const auto& e : kCatalog) {
    std::string& dst = e.test_only ? test_only : out;
    if (!dst.empty()) dst += ", ";
    dst += e.name;
  }
  return out + " (test only: " + test_only + ")";
}

std::string effect_help_text() {
  std::string out;
  // Appends pieces one by one (GCC 12 warns falsely about "literal" + std::string temporaries).
  const auto add = [&out](std::initializer_list<std::string_view> pieces) {
    for (auto p : pieces) out.append(p);
  };
  add({"Effects (--effect NAME[=MAGNITUDE][,key=value...]; NAME alone uses the default magnitude):\n"});
  for (const auto& e : kCatalog) {
    add({"\n  ", e.name, "  [", e.unit, "]", e.test_only ? "  (TEST ONLY)" : "", "\n"});
    add({"      ", e.meaning, "\n", "      ", e.how, "\n"});
    add({"      default ", fmt(e.default_magnitude), ", realistic ", fmt(e.realistic_min), " .. ", fmt(e.realistic_max),
         ", accepted ", fmt(e.min), " .. ", fmt(e.max), "\n"});
    for (const auto& q : e.qualifiers)
      add({"      ,", q.key, "=", fmt(q.default_value), q.unit.empty() ? "" : " ", q.unit, ": ", q.meaning, " (",
           fmt(q.min), " .. ", fmt(q.max), ")\n"});
  }
  out += "\n  mechanical_noise impacts (crank angle re firing TDC, level re the strongest, ringing mode, decay):\n";
  for (const auto& ev : kEvents) {
    char line[160];
    if (ev.at_soi)
      std::snprintf(line, sizeof line,
                    "      %-26s at SOI (the commanded start of injection)   %+5.1f dB  %6.0f Hz  %.1f ms\n",
                    std::string(ev.name).c_str(), ev.relative_db, ev.ring_hz, 1e3 * ev.decay_s);
    else
      std::snprintf(line, sizeof line,
                    "      %-26s %+7.1f deg                                %+5.1f dB  %6.0f Hz  %.1f ms\n",
                    std::string(ev.name).c_str(), ev.angle_deg, ev.relative_db, ev.ring_hz, 1e3 * ev.decay_s);
    out += line;
  }
  out += "      each impact: level scatter " + fmt(kImpactAmplitudeSigmaDb) + " dB, angle jitter " +
         fmt(kImpactJitterDeg) +
         " deg, random phase per cycle; heard r/c later at the microphones (5.1 ms at 1.75 m).\n";
  return out;
}

// ------------------------------------------------------------------------------------------ parsing

EffectSetting parse_effect(std::string_view text) {
  const std::string whole(text);
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = whole.find(',', start);
    parts.push_back(
        trim(std::string_view(whole).substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  EffectSetting s;
  const std::string& head = parts.front();
  const std::size_t eq = head.find('=');
  s.name = trim(std::string_view(head).substr(0, eq));
  const EffectInfo* info = find_effect(s.name);
  if (!info)
    throw std::invalid_argument("effect \"" + whole + "\": unknown effect \"" + s.name +
                                "\"; valid effects: " + valid_effect_names());
  const std::string where = "effect \"" + whole + "\"";
  s.magnitude = eq == std::string::npos ? info->default_magnitude
                                        : parse_number(std::string_view(head).substr(eq + 1), where + ": magnitude");
  if (s.magnitude < info->min || s.magnitude > info->max)
    throw std::invalid_argument(where + ": magnitude " + fmt(s.magnitude) + " " + std::string(info->unit) +
                                " is outside the accepted range " + fmt(info->min) + " .. " + fmt(info->max) +
                                " (realistic: " + fmt(info->realistic_min) + " .. " + fmt(info->realistic_max) + ")");
  for (std::size_t i = 1; i < parts.size(); ++i) {
    const std::size_t qeq = parts[i].find('=');
    const std::string key = trim(std::string_view(parts[i]).substr(0, qeq));
    const EffectQualifierInfo* q = nullptr;
    for (const auto& cand : info->qualifiers)
      if (cand.key == key) q = &cand;
    if (!q) {
      std::string valid;
      for (const auto& cand : info->qualifiers) valid += (valid.empty() ? "" : ", ") + std::string(cand.key);
      throw std::invalid_argument(where + ": unknown qualifier \"" + key + "\" (" + s.name + " takes " +
                                  (valid.empty() ? std::string("none") : valid) + ")");
    }
    if (qeq == std::string::npos) throw std::invalid_argument(where + ": qualifier \"" + key + "\" needs =VALUE");
    const double v = parse_number(std::string_view(parts[i]).substr(qeq + 1), where + ": " + key);
    if (v < q->min || v > q->max)
      throw std::invalid_argument(where + ": " + key + " = " + fmt(v) + " is outside " + fmt(q->min) + " .. " +
                                  fmt(q->max));
    for (const auto& [k, _] : s.qualifiers)
      if (k == key) throw std::invalid_argument(where + ": qualifier \"" + key + "\" given twice");
    s.qualifiers.emplace_back(key, v);
  }
  return s;
}

void Effects::add(const EffectSetting& setting) {
  const EffectInfo* info = find_effect(setting.name);
  if (!info)
    throw std::invalid_argument("unknown effect \"" + setting.name + "\"; valid effects: " + valid_effect_names());
  for (const auto& s : settings)
    if (s.name == setting.name) throw std::invalid_argument("effect " + setting.name + " given twice");
  if (!(setting.magnitude >= info->min && setting.magnitude <= info->max))
    throw std::invalid_argument("effect " + setting.name + ": magnitude " + fmt(setting.magnitude) + " outside " +
                                fmt(info->min) + " .. " + fmt(info->max));
  const auto qualifier = [&](std::string_view key) {
    for (const auto& q : info->qualifiers) {
      if (q.key != key) continue;
      for (const auto& [k, v] : setting.qualifiers)
        if (k == key) {
          if (!(v >= q.min && v <= q.max))
            throw std::invalid_argument("effect " + setting.name + ": " + k + " = " + fmt(v) + " outside " +
                                        fmt(q.min) + " .. " + fmt(q.max));
          return v;
        }
      return q.default_value;
    }
    throw std::logic_error("effect qualifier not in the catalogue");
  };
  for (const auto& [k, v] : setting.qualifiers) {
    bool known = false;
    for (const auto& q : info->qualifiers) known = known || q.key == k;
    if (!known) throw std::invalid_argument("effect " + setting.name + ": unknown qualifier \"" + k + "\"");
  }
  const double m = setting.magnitude;
  const std::string_view n = setting.name;
  if (n == "cubic_damping") {
    cubic_damping_n_s3_m3 = m;
  } else if (n == "cubic_stiffness") {
    cubic_stiffness_n_m3 = m;
  } else if (n == "second_mode") {
    second_mode_db = m;
    second_mode_hz = qualifier("hz");
    second_mode_q = qualifier("q");
    second_mode_phase_deg = qualifier("phase");
  } else if (n == "mechanical_noise") {
    mechanical_noise_dba = m;
  } else if (n == "background_noise") {
    background_noise_dba = m;
  } else if (n == "transducer_noise") {
    transducer_noise_bar = m;
  } else if (n == "mic_gain") {
    const double mic = qualifier("mic");
    if (mic != std::round(mic)) throw std::invalid_argument("effect mic_gain: mic must be a whole number");
    mic_gain_db = m;
    mic_gain_mic = static_cast<int>(mic);
  } else if (n == "speed_dependence") {
    speed_dependence_db_per_krpm = m;
  } else if (n == "foreign_soi_gain") {
    foreign_soi_gain_db_per_deg = m;
  } else {
    throw std::logic_error("effect in the catalogue without an implementation: " + setting.name);
  }
  settings.push_back(setting);
}

Effects parse_effects(const std::vector<std::string>& texts) {
  Effects e;
  for (const auto& t : texts) e.add(parse_effect(t));
  return e;
}

// ------------------------------------------------------------------------------------------ physics

BlockParams with_structural_effects(const BlockParams& true_block, const Effects& effects) {
  BlockParams p = true_block;
  p.b3 += effects.cubic_damping_n_s3_m3;
  p.k3 += effects.cubic_stiffness_n_m3;
  return p;
}

double structural_gain(const Effects& effects, double speed_rpm, double soi_deg_btdc, bool motored) {
  double db = effects.speed_dependence_db_per_krpm * (speed_rpm - kEffectReferenceSpeedRpm) / 1000.0;
  if (!motored) db += effects.foreign_soi_gain_db_per_deg * (soi_deg_btdc - kForeignReferenceSoiDeg);
  return db == 0.0 ? 1.0 : std::pow(10.0, db / 20.0);
}

SecondModeFilter::SecondModeFilter(const Effects& effects, double fs_hz) {
  if (effects.second_mode_db == 0.0) return;
  if (!(effects.second_mode_hz < 0.45 * fs_hz))
    throw std::invalid_argument("second_mode: f2 = " + fmt(effects.second_mode_hz) +
                                " Hz is too close to the Nyquist frequency of " + fmt(fs_hz) + " Hz");
  a_ = std::pow(10.0, effects.second_mode_db / 20.0) - 1.0;
  // Bilinear transform of (w/Q) s / (s^2 + (w/Q) s + w^2) pre-warped at f2 (RBJ constant-peak band-pass).
  const double w0 = 2.0 * kPi * effects.second_mode_hz / fs_hz;
  const double alpha = std::sin(w0) / (2.0 * effects.second_mode_q);
  const double a0 = 1.0 + alpha;
  b0_ = alpha / a0;
  b2_ = -alpha / a0;
  a1_ = -2.0 * std::cos(w0) / a0;
  a2_ = (1.0 - alpha) / a0;
  // RBJ low-pass (1 - cos w0)/2 (1 + 2 z^-1 + z^-2), divided by Q: the displacement-like partner, -j at f2.
  l0_ = (1.0 - std::cos(w0)) / 2.0 / a0 / effects.second_mode_q;
  l1_ = 2.0 * l0_;
  cos_ = std::cos(effects.second_mode_phase_deg * kPi / 180.0);
  sin_ = std::sin(effects.second_mode_phase_deg * kPi / 180.0);
}

void SecondModeFilter::process(double* y, std::size_t n) {
  if (a_ == 0.0) return;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = y[i];
    const double r = b0_ * x + b2_ * x2_ - a1_ * y1_ - a2_ * y2_;
    const double d = l0_ * x + l1_ * x1_ + l0_ * x2_ - a1_ * d1_ - a2_ * d2_;
    x2_ = x1_;
    x1_ = x;
    y2_ = y1_;
    y1_ = r;
    d2_ = d1_;
    d1_ = d;
    y[i] = x + a_ * (cos_ * r - sin_ * d);
  }
}

std::span<const ImpactEvent> mechanical_events() { return kEvents; }

MechanicalNoise::MechanicalNoise(double level_dba, double speed_rpm, double soi_deg_btdc, double fs_hz,
                                 std::uint64_t seed)
    : fs_(fs_hz), soi_(soi_deg_btdc), seed_(seed), active_(64) {
  if (!(speed_rpm > 0.0)) throw std::invalid_argument("mechanical_noise: the speed must be positive");
  // Amplitude at the reference speed from the Leq(A) over one cycle: sum of the events' A-weighted energies
  // = p_ref^2 10^(L/10) T_cycle; then amplitude proportional to speed (Leq +30 log10 n).
  double weighted = 0.0;
  std::vector<double> unit_energy(kEvents.size());
  for (std::size_t e = 0; e < kEvents.size(); ++e) {
    unit_energy[e] = impact_a_weighted_energy(kEvents[e].ring_hz, kEvents[e].decay_s);
    weighted += std::pow(10.0, kEvents[e].relative_db / 10.0) * unit_energy[e];
  }
  const double period_ref = 120.0 / kEffectReferenceSpeedRpm;
  const double a_ref = std::sqrt(dsp::mean_square_from_level(level_dba) * period_ref / weighted);
  for (const auto& ev : kEvents) {
    amp_.push_back(a_ref * std::pow(10.0, ev.relative_db / 20.0) * speed_rpm / kEffectReferenceSpeedRpm);
    angle_.push_back(ev.at_soi ? ev.angle_deg - soi_deg_btdc : ev.angle_deg);
  }
  for (std::size_t e = 0; e < kEvents.size(); ++e) order_.push_back(e);
  std::sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) { return angle_[a] < angle_[b]; });
}

// The jittered unwrapped angle of the event at order_[next_slot_] in cycle next_cycle_.
void MechanicalNoise::schedule_next() {
  const std::size_t e = order_[next_slot_];
  const std::uint64_t idx = static_cast<std::uint64_t>(next_cycle_) * 16 + e;
  next_angle_ = 720.0 * static_cast<double>(next_cycle_) + angle_[e] +
                kImpactJitterDeg * rnd::normal_at(seed_, kStreamImpactJitter, idx);
}

void MechanicalNoise::start(std::size_t event, double delay_s, std::int64_t cycle) {
  const ImpactEvent& ev = kEvents[event];
  const std::uint64_t idx = static_cast<std::uint64_t>(cycle) * 16 + event;
  const double phase = 2.0 * kPi * rnd::unit(rnd::key(seed_, kStreamImpactPhase, idx));
  // Log-normal level scatter with unit mean energy: ln g^2 ~ N(-s^2/2, s^2).
  const double s = kImpactAmplitudeSigmaDb * std::log(10.0) / 10.0;
  const double g = std::exp(0.5 * (-0.5 * s * s + s * rnd::normal_at(seed_, kStreamImpactGain, idx)));
  const double a = amp_[event] * g;
  const double a1 = 1.0 / ev.decay_s, a2 = a1 + 1.0 / kImpactRiseS, w0 = 2.0 * kPi * ev.ring_hz;
  const std::complex<double> e1 = a * std::exp(std::complex<double>(-a1 * delay_s, w0 * delay_s + phase));
  const std::complex<double> e2 = a * std::exp(std::complex<double>(-a2 * delay_s, w0 * delay_s + phase));
  const std::complex<double> r1 = std::exp(std::complex<double>(-a1, w0) / fs_);
  const std::complex<double> r2 = std::exp(std::complex<double>(-a2, w0) / fs_);
  // A free slot, or the one closest to its end (only when far more impacts overlap than any engine has).
  std::size_t slot = active_count_;
  if (slot == active_.size()) {
    slot = 0;
    for (std::size_t i = 1; i < active_.size(); ++i)
      if (std::norm(std::complex<double>(active_[i].re1, active_[i].im1)) <
          std::norm(std::complex<double>(active_[slot].re1, active_[slot].im1)))
        slot = i;
  } else {
    ++active_count_;
  }
  active_[slot] = {e1.real(), e1.imag(), e2.real(), e2.imag(), r1.real(), r1.imag(), r2.real(), r2.imag(), event};
}

void MechanicalNoise::add(const double* crank_deg, double* out, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const double theta = crank_deg[i];
    if (!started_) {
      started_ = true;
      prev_crank_ = theta;
      next_cycle_ = static_cast<std::int64_t>(std::floor((theta + 360.0) / 720.0));
      next_slot_ = 0;
      schedule_next();
      while (next_angle_ <= theta) {
        if (++next_slot_ == order_.size()) {
          next_slot_ = 0;
          ++next_cycle_;
        }
        schedule_next();
      }
    }
    while (next_angle_ <= theta) {
      const double alpha = theta > prev_crank_ ? (next_angle_ - prev_crank_) / (theta - prev_crank_) : 1.0;
      start(order_[next_slot_], (1.0 - std::clamp(alpha, 0.0, 1.0)) / fs_, next_cycle_);
      if (++next_slot_ == order_.size()) {
        next_slot_ = 0;
        ++next_cycle_;
      }
      schedule_next();
    }
    prev_crank_ = theta;
    double sum = 0.0;
    for (std::size_t k = 0; k < active_count_;) {
      Active& a = active_[k];
      sum += a.im1 - a.im2;
      const double r1 = a.re1 * a.rot1_re - a.im1 * a.rot1_im, i1 = a.re1 * a.rot1_im + a.im1 * a.rot1_re;
      const double r2 = a.re2 * a.rot2_re - a.im2 * a.rot2_im, i2 = a.re2 * a.rot2_im + a.im2 * a.rot2_re;
      a.re1 = r1;
      a.im1 = i1;
      a.re2 = r2;
      a.im2 = i2;
      // Done when decayed below 1e-7 of the event's nominal amplitude (-140 dB).
      if (r1 * r1 + i1 * i1 < 1e-14 * amp_[a.event] * amp_[a.event]) {
        a = active_[--active_count_];
        continue;
      }
      ++k;
    }
    out[i] += sum;
  }
}

BackgroundNoise::BackgroundNoise(double level_dba, double fs_hz, std::uint64_t seed)
    : normal_(seed), scale_(0.0), alpha_(1.0 - std::exp(-2.0 * kPi * kVentilationCornerHz / fs_hz)) {
  // y[n] = (1 - alpha) y[n-1] + alpha x[n], x unit white: one-sided PSD (2 / fs) |H|^2.
  const double c = 1.0 - alpha_;
  const auto psd = [&](double f) {
    return 2.0 / fs_hz * alpha_ * alpha_ / (1.0 + c * c - 2.0 * c * std::cos(2.0 * kPi * f / fs_hz));
  };
  const double unit_power = a_weighted_integral(psd, 20.0, std::min(20000.0, 0.5 * fs_hz));
  scale_ = std::sqrt(dsp::mean_square_from_level(level_dba) / unit_power);
  // Start in the stationary state (variance alpha^2 / (1 - c^2) for unit white input).
  state_ = normal_.next() * alpha_ / std::sqrt(1.0 - c * c);
}

BackgroundNoise::BackgroundNoise(const BackgroundNoise& shape, std::uint64_t seed)
    : normal_(seed), scale_(shape.scale_), alpha_(shape.alpha_) {
  const double c = 1.0 - alpha_;
  state_ = normal_.next() * alpha_ / std::sqrt(1.0 - c * c);
}

double BackgroundNoise::next() {
  state_ += alpha_ * (normal_.next() - state_);
  return scale_ * state_;
}

double transducer_noise_rms_pa(const Effects& effects) { return 1e5 * effects.transducer_noise_bar; }

void add_transducer_noise(const Effects& effects, std::uint64_t seed, std::int64_t first_index, double* pressure_pa,
                          std::size_t n) {
  const double sigma = transducer_noise_rms_pa(effects);
  if (sigma == 0.0) return;
  for (std::size_t i = 0; i < n; ++i)
    pressure_pa[i] += sigma * rnd::normal_at(seed, kStreamTransducer,
                                             static_cast<std::uint64_t>(first_index + static_cast<std::int64_t>(i)));
}

double mic_gain_factor(const Effects& effects, std::size_t mic) {
  if (effects.mic_gain_db == 0.0 || static_cast<int>(mic) != effects.mic_gain_mic - 1) return 1.0;
  return std::pow(10.0, effects.mic_gain_db / 20.0);
}

}  // namespace noisemon::model::engine
