// The withheld-effect family on the independent cell (see withheld.hpp).
#include "withheld.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "cell_block.hpp"

namespace indep {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kCyclesPerCondition = 16;
constexpr int kSecondCellCycles = 24;
constexpr double kThirdOctave = 1.2599210498948732;  // 2^(1/3)

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[96];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

double num(const json& j) { return j.is_number() ? j.get<double>() : std::nan(""); }

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

const json* candidate(const json& report, const std::string& effect) {
  for (const json& c : report["candidates"])
    if (c.value("effect", "") == effect) return &c;
  return nullptr;
}

// The truth's speed slope at 2000 rpm, dB per 1000 rpm: d/dn of 20 p log10(n / ref).
double true_speed_slope(const Effects& fx) { return 20.0 * fx.speed_exponent / std::log(10.0) * 1000.0 / 2000.0; }

// The added transducer noise's one-sided amplitude density at 2000 rpm (0.2 deg samples at 60 kHz), Pa/sqrt(Hz).
double added_noise_density(const Effects& fx) {
  return fx.transducer_noise_bar * 1e5 * std::sqrt(2.0 / (30.0 * 2000.0));
}

// The fitted parameters of the expected effect's candidate against the truth (see withheld.hpp).
void check_params(const Case& c, const json& report, Outcome& o) {
  const json* cand = candidate(report, c.expect);
  if (!cand || !cand->contains("params")) return;
  const json& p = (*cand)["params"];
  if (c.expect == "second_mode") {
    // Before the phase was fitted (mode_rise_db absent) the coupling's own dB was the rise.
    const double hz = num(p["mode_hz"]), rise = num(p.contains("mode_rise_db") ? p["mode_rise_db"] : p["mode_db"]);
    o.params_checked = true;
    o.params_right = hz > c.fx.second_mode_hz / kThirdOctave && hz < c.fx.second_mode_hz * kThirdOctave && rise > 0;
    o.params = fmt("mode %.0f Hz %+.1f dB Q %.1f", hz, rise, num(p["mode_q"]));
  } else if (c.expect == "mic_gain" && p.contains("mic_gain_db")) {
    const json& g = p["mic_gain_db"];
    std::size_t worst = 0;
    for (std::size_t m = 0; m < g.size(); ++m)
      if (std::abs(num(g[m])) > std::abs(num(g[worst]))) worst = m;
    o.params_checked = true;
    o.params_right = !g.empty() && static_cast<int>(worst) == c.fx.mic_gain_index && num(g[worst]) > 0;
    o.params = fmt("mic%.0f %+.1f dB", static_cast<double>(worst + 1), g.empty() ? NAN : num(g[worst]));
  } else if (c.expect == "cubic_stiffness" || c.expect == "cubic_damping") {
    const bool stiffness = c.expect == "cubic_stiffness";
    const double k = num(p[stiffness ? "k3_n_per_m3" : "b3_n_s3_per_m3"]);
    o.params_checked = true;
    o.params_right = k > 0;  // hardening, or damping that grows with the velocity
    o.params = fmt(stiffness ? "k3 %.3g N/m^3" : "b3 %.3g N s^3/m^3", k);
  } else if (c.expect == "transducer_noise") {
    const double got = num(p["transducer_noise_pa_per_rthz_at_1khz"]), added = added_noise_density(c.fx);
    o.params_checked = true;
    o.params_right = got >= added / 2;
    o.params = fmt("%.0f Pa/rtHz at 1 kHz, slope %+.1f (added %.0f)", got, num(p["transducer_slope"]), added);
  } else if (c.expect == "speed_dependence") {
    const double slope = num(p["speed_gain_db_per_krpm"]), truth = true_speed_slope(c.fx);
    o.params_checked = true;
    o.params_right = slope > truth / 2 && slope < truth * 2;
    o.params = fmt("%+.2f dB/krpm (truth %+.2f)", slope, truth);
  }
}

// With the floor unstated, the diagnosis's estimate (the fired runs' median) within the case's bounds, give or take
// 10 % (the estimate's own error).
void check_estimated_floor(const Case& c, const json& report, Outcome& o) {
  const json& floors = report["where"]["floors"];
  const json& conditions = report["where"]["conditions"];
  std::vector<double> fired;
  for (std::size_t k = 0; k < floors["pressure_estimated_bar"].size() && k < conditions.size(); ++k)
    if (!conditions[k].value("motored", false)) fired.push_back(num(floors["pressure_estimated_bar"][k]));
  if (fired.empty()) return;
  std::sort(fired.begin(), fired.end());
  const double median = fired[fired.size() / 2];
  o.params_checked = true;
  o.params_right = median >= 0.9 * c.floor_at_least_bar && median <= 1.1 * c.floor_at_most_bar;
  o.params = fmt("floor estimated %.3f bar (%.3f ... %.3f)", median, c.floor_at_least_bar, c.floor_at_most_bar);
}

// The best candidate other than the verdict's effect, with its held-out gap.
std::string runner_up(const json& report, const std::string& verdict) {
  for (const json& c : report["candidates"]) {
    const std::string e = c.value("effect", "");
    if (e != verdict) return e + fmt(" %.2f dB", num(c["heldout_rms_db"]));
  }
  return "";
}

Outcome score(const Case& c, const json& report) {
  Outcome o;
  const json& v = report["verdict"];
  o.effect = v.value("effect", "");
  for (const json& a : v.value("also", json::array())) o.also.push_back(a.get<std::string>());
  if (v.contains("below_tolerance") && v["below_tolerance"].is_string()) o.below_tolerance = v["below_tolerance"];
  o.before_db = num(v["heldout_rms_before_db"]);
  o.after_db = num(v["heldout_rms_after_db"]);
  o.closed = num(v["gap_closed_fraction"]);
  o.verdict_right = o.effect == c.expect;
  if (c.expect != "none") check_params(c, report, o);
  if (std::isfinite(c.floor_at_least_bar)) check_estimated_floor(c, report, o);
  o.runner_up = runner_up(report, o.effect);
  return o;
}

}  // namespace

Condition reference_condition() { return {"level", 1800, 1.0, false, false, 5, kCyclesPerCondition}; }

ReferenceMotion reference_motion(const Sources& src, const Chain& chain) {
  const Condition c = reference_condition();
  const Timing t = timing(c.speed_rpm, c.cycles, chain.fs_hz);
  const BlockMotion m = block_motion(engine_input_pa(condition_pressure(src, c, t.speed_rpm).clean_bar), t.period_s,
                                     chain.structure, Nonlinearity{});
  ReferenceMotion ref;
  for (std::size_t i = 0; i < m.z_m.size(); ++i) {
    ref.z_peak_m = std::max(ref.z_peak_m, std::abs(m.z_m[i]));
    ref.v_peak_m_per_s = std::max(ref.v_peak_m_per_s, std::abs(m.v_m_per_s[i]));
  }
  ref.b1_per_kg = linear_damping_per_kg(chain.structure);
  return ref;
}

double engine_level_dba(const Sources& src, const Chain& chain) {
  const Condition c = reference_condition();
  const Run r = synthesize(src, c, 0, chain, Effects{});
  double e = 0;
  for (const auto& y : r.mics_pa) e += std::pow(10.0, level_db(y, chain.fs_hz, true) / 10.0) / kMics;
  return 10.0 * std::log10(e);
}

std::vector<Case> withheld_cases(double engine_dba) {
  std::vector<Case> out{{"null", "none", {}}};
  struct Mode {
    double hz, q;
  };
  for (const Mode m : {Mode{400, 3}, Mode{1600, 8}, Mode{5000, 12}})
    for (const double db : {6.0, 10.0}) {
      Effects fx;
      fx.second_mode_hz = m.hz, fx.second_mode_q = m.q, fx.second_mode_db = db;
      out.push_back({fmt("second_mode_%.0fdb_%.0fhz_q%.0f", db, m.hz, m.q), "second_mode", fx});
    }
  // A sensitivity error rising above 600 Hz: 3 dB on microphone 4, 6 dB on microphone 7.
  for (const auto& [db, mic] : {std::pair{3.0, 3}, std::pair{6.0, 6}}) {
    Effects fx;
    fx.mic_gain_db = db, fx.mic_gain_index = mic, fx.mic_gain_corner_hz = 600;
    out.push_back({fmt("mic_gain_%.0fdb_mic%.0f", db, mic + 1.0), "mic_gain", fx});
  }
  for (const double below : {15.0, 9.0}) {
    Effects fx;
    fx.background_dba = engine_dba - below;
    out.push_back({fmt("background_noise_engine_minus_%.0fdb", below), "background_noise", fx});
  }
  // Louder with speed by 3 and 6 dB from 1500 to 2600 rpm (the cell's fired range).
  for (const double db : {3.0, 6.0}) {
    Effects fx;
    fx.speed_exponent = db / (20.0 * std::log10(2600.0 / 1500.0));
    out.push_back({fmt("speed_dependence_%.0fdb_1500_to_2600", db), "speed_dependence", fx});
  }
  for (const double below : {12.0, 6.0}) {
    Effects fx;
    fx.mechanical_dba = engine_dba - below, fx.mechanical_jitter_deg = 3, fx.mechanical_energy_spread_db = 4;
    out.push_back({fmt("mechanical_noise_engine_minus_%.0fdb", below), "mechanical_noise", fx});
  }
  return out;
}

// The block's nonlinearities and the pressure chain's noise (magnitudes fixed with the rest, before any diagnosis).
std::vector<Case> block_and_chain_cases(const ReferenceMotion& ref, int cell, const std::string& prefix,
                                        const std::vector<double>& stop_ratios, const std::vector<double>& drags,
                                        const std::vector<double>& noises_bar, double chain_floor_bar) {
  std::vector<Case> out;
  Case stated_null{prefix + "null_floor_stated", "none", {}, cell};
  stated_null.states_floor = true;
  out.push_back(stated_null);
  // A stop at half the reference's peak displacement: the restoring force there is 1 + ratio / 2 times the linear.
  for (const double ratio : stop_ratios) {
    Effects fx;
    fx.block.stop_at_m = 0.5 * ref.z_peak_m, fx.block.stop_ratio = ratio;
    out.push_back({prefix + fmt("block_stop_%.0fpct_at_peak", 50 * ratio), "cubic_stiffness", fx, cell});
  }
  // Quadratic drag: at the reference's peak velocity it adds `ratio` times the linear damping force.
  for (const double ratio : drags) {
    Effects fx;
    fx.block.quadratic_damping = ratio * ref.b1_per_kg / ref.v_peak_m_per_s;
    out.push_back({prefix + fmt("quadratic_drag_%.0fx_at_peak", ratio), "cubic_damping", fx, cell});
  }
  for (const double bar : noises_bar) {
    Effects fx;
    fx.transducer_noise_bar = bar;
    Case over{prefix + fmt("transducer_noise_%.2fbar_over_stated", bar), "transducer_noise", fx, cell};
    over.states_floor = true;
    out.push_back(over);
    Case unstated{prefix + fmt("transducer_noise_%.2fbar_unstated", bar), "none", fx, cell};
    unstated.floor_at_least_bar = bar;
    unstated.floor_at_most_bar = std::hypot(chain_floor_bar, bar);
    out.push_back(unstated);
  }
  return out;
}

std::vector<Case> second_cell_cases(double engine_dba) {
  std::vector<Case> out{{"cell2_null", "none", {}, 2}};
  for (const auto& [hz, q] : {std::pair{800.0, 5.0}, std::pair{2500.0, 10.0}}) {
    Effects fx;
    fx.second_mode_hz = hz, fx.second_mode_q = q, fx.second_mode_db = 8;
    out.push_back({fmt("cell2_second_mode_8db_%.0fhz_q%.0f", hz, q), "second_mode", fx, 2});
  }
  Effects gain;
  gain.mic_gain_db = 6, gain.mic_gain_index = 1, gain.mic_gain_corner_hz = 600;
  out.push_back({"cell2_mic_gain_6db_mic2", "mic_gain", gain, 2});
  Effects background;
  background.background_dba = engine_dba - 9;
  out.push_back({"cell2_background_noise_engine_minus_9db", "background_noise", background, 2});
  Effects speed;
  speed.speed_exponent = 6.0 / (20.0 * std::log10(2400.0 / 1400.0));
  out.push_back({"cell2_speed_dependence_6db_1400_to_2400", "speed_dependence", speed, 2});
  Effects impacts;
  impacts.mechanical_dba = engine_dba - 6, impacts.mechanical_jitter_deg = 3, impacts.mechanical_energy_spread_db = 4;
  out.push_back({"cell2_mechanical_noise_engine_minus_6db", "mechanical_noise", impacts, 2});
  return out;
}

std::vector<Case> cell_catalogue(const Sources& src, int cell) {
  const Chain chain = cell == 2 ? second_cell_chain(1) : Chain{};
  const double engine = engine_level_dba(src, chain);
  const ReferenceMotion ref = reference_motion(src, chain);
  std::vector<Case> out = cell == 2 ? second_cell_cases(engine) : withheld_cases(engine);
  const double floor = std::hypot(record_floor_bar(src.fired), chain.added_pressure_noise_bar);
  const std::vector<Case> more = cell == 2
                                     ? block_and_chain_cases(ref, 2, "cell2_", {1.0}, {3.0}, {0.3}, floor)
                                     : block_and_chain_cases(ref, 1, "", {0.4, 1.0}, {1.0, 3.0}, {0.2, 0.4}, floor);
  out.insert(out.end(), more.begin(), more.end());
  return out;
}

Outcome diagnose_case(const Sources& src, const Case& c, std::uint64_t seed, const fs::path& dir,
                      const std::string& noisemon_path) {
  Chain chain = c.cell == 2 ? second_cell_chain(seed) : Chain{};
  chain.seed = seed;
  chain.states_floor = c.states_floor;
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::vector<Condition> conditions =
      c.cell == 2 ? second_cell_conditions(kSecondCellCycles, seed) : default_conditions(kCyclesPerCondition, seed);
  write_campaign(src, conditions, chain, c.fx, dir / "runs");
  const std::string cmd = quote(noisemon_path) + " diagnose " + quote((dir / "runs").string()) + " -o " +
                          quote((dir / "diag").string()) + " --bootstrap 100 --no-progress --force > " +
                          quote((dir / "diagnose.log").string()) + " 2>&1";
  const auto t0 = std::chrono::steady_clock::now();
  const int status = std::system(cmd.c_str());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::ifstream in(dir / "diag" / "report.json");
  if (status != 0 || !in) {
    Outcome o;
    const std::string log = slurp(dir / "diagnose.log");
    o.error = "exit status " + std::to_string(status) + ": " + log.substr(log.size() > 2000 ? log.size() - 2000 : 0);
    o.seconds = seconds;
    return o;
  }
  Outcome o = score(c, json::parse(in));
  o.seconds = seconds;
  return o;
}

std::string table_header() {
  return "| case | seed | expected | verdict (also) [below the tolerance] | held-out gap before → after, dB | closed | "
         "fitted | runner-up |\n"
         "|---|---|---|---|---|---|---|---|\n";
}

std::string table_row(const Case& c, std::uint64_t seed, const Outcome& o) {
  if (!o.error.empty())
    return "| " + c.label + " | " + std::to_string(seed) + " | " + c.expect + " | FAILED TO RUN | | | | |\n";
  std::string also;
  for (const std::string& a : o.also) also += (also.empty() ? " (" : ", ") + a;
  if (!also.empty()) also += ")";
  if (!o.below_tolerance.empty()) also += " [below the tolerance: " + o.below_tolerance + "]";
  const std::string mark = o.verdict_right ? "✓ " : "✗ ";
  const std::string fitted = !o.params_checked ? "—" : (o.params_right ? "✓ " : "✗ ") + o.params;
  return "| " + c.label + " | " + std::to_string(seed) + " | " + c.expect + " | " + mark + o.effect + also + " | " +
         fmt("%.2f → %.2f", o.before_db, o.after_db) + " | " + fmt("%.0f %%", 100 * o.closed) + " | " + fitted + " | " +
         o.runner_up + " |\n";
}

}  // namespace indep
