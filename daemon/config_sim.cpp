// [sim] of the configuration: the virtual engine, its test cell, faults, effects and operating-point schedule.
#include <string>

#include "daemon/config_reader.hpp"
#include "drivers/mic_positions.hpp"

namespace noisemon::daemon::config_detail {
namespace {

// The realistic test cell of [sim]: pressure chain, microphone chain, gas ringing (every key documented in
// systemd/noisemond.toml; each part has a value that switches it off).
void read_sim_cell(TableReader& sr, drivers::sim::SimConfig& s) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  auto& p = s.pressure_chain;
  sr.number("pressure_noise_bar", p.noise_bar, 0, 100);
  sr.number("pressure_flicker_bar", p.flicker_bar, 0, 100);
  read_adc_bits(sr, "pressure_adc_bits", p.adc_bits);
  sr.number("pressure_adc_min_bar", p.adc_min_bar, -1e3, 1e4);
  sr.number("pressure_adc_max_bar", p.adc_max_bar, -1e3, 1e4);
  if (p.adc_bits > 0 && !(p.adc_max_bar > p.adc_min_bar))
    sr.fail("pressure_adc_max_bar", "must be above pressure_adc_min_bar");
  sr.number("pressure_offset_bar", p.offset_bar, -100, 100);
  sr.number("pressure_gain_error", p.gain_error, -0.49, 0.49);
  sr.number("pressure_nominal_mv_per_bar", s.pressure_readout.nominal_mv_per_bar, 0, 1e6);
  auto& m = s.mic_chain;
  sr.number("mic_self_noise_dba", m.self_noise_dba, -kInf, 120);
  sr.number("mic_directivity_db", m.directivity_db, 0, 6);
  read_adc_bits(sr, "mic_adc_bits", m.adc_bits);
  sr.number("mic_adc_range_pa", m.adc_range_pa, 1e-3, 1e6);
  // Given in us and ms; divided by the exact powers of ten (the result is the literal's double).
  double gain_us = -1.0, decay_ms = -1.0;  // -1: not given
  sr.number("gas_ringing_us", gain_us, 0, 1000);
  if (gain_us >= 0.0) s.gas_ringing.gain_s = gain_us / 1e6;
  sr.number("gas_ringing_decay_ms", decay_ms, 0.01, 100);
  if (decay_ms >= 0.0) s.gas_ringing.decay_s = decay_ms / 1e3;
}

// [[sim.faults]]: faults the virtual engine injects (drivers/sim/sim_faults.hpp; documented in systemd/noisemond.toml).
void read_faults(TableReader& sr, const std::string& origin, drivers::sim::SimConfig& s) {
  const toml::node* n = sr.node("faults");
  if (!n) return;
  const toml::array* list = n->as_array();
  if (!list || !list->is_array_of_tables()) sr.fail("faults", "expected an array of tables ([[sim.faults]])");
  for (std::size_t i = 0; i < list->size(); ++i) {
    TableReader r((*list)[i].as_table(), "sim.faults[" + std::to_string(i) + "]", origin);
    std::string kind_name, channel;
    r.string("kind", kind_name);
    const std::optional<drivers::sim::SimFaultKind> kind = drivers::sim::parse_fault_kind(kind_name);
    if (!kind)
      r.fail("kind", "unknown fault '" + kind_name +
                         "' (expected missing_edges, extra_edges, lost_index, reverse, flat, overload, nan, unplugged, "
                         "stall, overrun, fail)");
    drivers::sim::SimFault f;
    f.kind = *kind;
    r.string("channel", channel);
    try {
      f.target = drivers::sim::parse_fault_target(f.kind, channel, s.mic_count);
    } catch (const std::invalid_argument& e) {
      r.fail("channel", e.what());
    }
    r.number("at_s", f.at_s, 0, 1e9);
    r.number("duration_s", f.duration_s, 1e-3, 1e9);
    r.number("per_rev", f.per_rev, 1, 100);
    r.number("gain", f.gain, 1.000001, 1e6);
    r.reject_unknown();
    s.faults.push_back(f);
  }
}

// [[sim.effects]]: effects of the virtual engine (model/engine/effects.hpp), each from onset_s on, as a step or a ramp
// (drivers/sim/sim_effect_schedule.hpp). One on from the start with no ramp is simply part of the engine.
void read_effects(TableReader& sr, const std::string& origin, drivers::sim::SimConfig& s) {
  const toml::node* n = sr.node("effects");
  if (!n) return;
  const toml::array* list = n->as_array();
  if (!list || !list->is_array_of_tables()) sr.fail("effects", "expected an array of tables ([[sim.effects]])");
  for (std::size_t i = 0; i < list->size(); ++i) {
    TableReader r((*list)[i].as_table(), "sim.effects[" + std::to_string(i) + "]", origin);
    std::string text;
    r.string("effect", text);
    if (text.empty())
      r.fail("effect", "missing: the effect as `noisemon sim --effect` spells it, e.g. \"mic_gain=3,mic=4\"");
    drivers::sim::ScheduledEffect e;
    r.number("onset_s", e.onset_s, 0, 1e9);
    r.number("ramp_s", e.ramp_s, 0, 1e9);
    r.reject_unknown();
    try {
      e.setting = model::engine::parse_effect(text);
      model::engine::Effects all =
          drivers::sim::cumulative_effects(s.effects, s.scheduled_effects, s.scheduled_effects.size());
      all.add(e.setting);  // validates magnitude and qualifiers, and an effect given twice
      if (e.setting.name == "mic_gain" && (all.mic_gain_mic < 1 || all.mic_gain_mic > static_cast<int>(s.mic_count)))
        throw std::invalid_argument("microphone " + std::to_string(all.mic_gain_mic) +
                                    " does not exist (mic_count is " + std::to_string(s.mic_count) + ")");
    } catch (const std::invalid_argument& err) {
      r.fail("effect", err.what());
    }
    if (e.onset_s == 0.0 && e.ramp_s == 0.0)
      s.effects.add(e.setting);
    else
      s.scheduled_effects.push_back(e);
  }
}

// [[sim.schedule]]: the operating point's changes over the run (drivers/sim/sim_operating_schedule.hpp); a key not
// given keeps the previous step's value.
void read_schedule(TableReader& sr, const std::string& origin, drivers::sim::SimConfig& s) {
  const toml::node* n = sr.node("schedule");
  if (!n) return;
  const toml::array* list = n->as_array();
  if (!list || !list->is_array_of_tables()) sr.fail("schedule", "expected an array of tables ([[sim.schedule]])");
  model::engine::OperatingCondition previous{
      .speed_rpm = s.speed_rpm, .load_nm = s.load_nm, .soi_deg_btdc = s.soi_deg_btdc, .motored = s.motored};
  for (std::size_t i = 0; i < list->size(); ++i) {
    TableReader r((*list)[i].as_table(), "sim.schedule[" + std::to_string(i) + "]", origin);
    drivers::sim::OperatingStep step;
    step.condition = previous;
    if (!r.node("at_s")) r.fail("at_s", "missing: the step's instant, engine seconds after the start");
    r.number("at_s", step.at_s, 0, 1e9);
    r.number("ramp_s", step.ramp_s, 0, 1e6);
    r.number("speed_rpm", step.condition.speed_rpm, 100, 10000);
    r.number("load_nm", step.condition.load_nm, 0, 1e4);
    r.number("soi_deg_btdc", step.condition.soi_deg_btdc, 0, 60);
    r.boolean("motored", step.condition.motored);
    r.reject_unknown();
    if (i > 0 && !(step.at_s > s.operating_schedule.back().at_s + s.operating_schedule.back().ramp_s))
      r.fail("at_s", "must come after the previous step's at_s + ramp_s");
    s.operating_schedule.push_back(step);
    previous = step.condition;
  }
  if (drivers::sim::sized_by_operating_point(
          drivers::sim::cumulative_effects(s.effects, s.scheduled_effects, s.scheduled_effects.size())))
    sr.fail("schedule",
            "cannot be combined with effects that depend on the operating point (speed_dependence, "
            "mechanical_noise): they would keep the first operating point's size");
}

}  // namespace

// [sim]: the virtual engine, its cell, faults, effects and operating-point schedule.
void read_sim(TableReader& top, const std::string& origin, drivers::sim::SimConfig& s) {
  TableReader sr(top.table("sim"), "sim", origin);
  sr.boolean("paced", s.paced);
  sr.number("speed_rpm", s.speed_rpm, 100, 10000);
  sr.number("load_nm", s.load_nm, 0, 1e4);
  sr.number("full_load_nm", s.full_load_nm, 1e-3, 1e4);
  sr.number("soi_deg_btdc", s.soi_deg_btdc, -30, 60);
  sr.boolean("motored", s.motored);
  sr.boolean("stopped", s.stopped);
  sr.number("static_pressure_bar", s.static_pressure_bar, 0, 1000);
  sr.number("speed_fluctuation", s.speed_fluctuation, 0, 0.2);
  sr.number("cycle_variation", s.cycle_variation, 0, 0.5);
  sr.number("encoder_resolution_deg", s.encoder_resolution_deg, 0.01, 6);
  std::int64_t mic_count = s.mic_count;
  sr.integer("mic_count", mic_count, 1, static_cast<std::int64_t>(drivers::SampleBlock::kMaxChannels));
  s.mic_count = static_cast<std::uint32_t>(mic_count);
  sr.number("radius_m", s.radius_m, 0.1, 100);
  read_positions(sr, "mic_positions_m", s.radius_m, s.mic_positions_m);
  if (!s.mic_positions_m.empty() && s.mic_positions_m.size() != s.mic_count)
    sr.fail("mic_positions_m", "has " + std::to_string(s.mic_positions_m.size()) + " positions but mic_count is " +
                                   std::to_string(s.mic_count));
  sr.number("speed_of_sound_m_s", s.speed_of_sound_m_s, 100, 1000);
  sr.number("mic_rate_hz", s.mic_rate_hz, 40000, 1e6);
  sr.number("mic_gain_spread_db", s.mic_gain_spread_db, 0, 20);
  sr.number("background_noise_db", s.background_noise_db, -100, 200);
  read_sim_cell(sr, s);
  read_faults(sr, origin, s);
  read_effects(sr, origin, s);
  read_schedule(sr, origin, s);
  std::int64_t seed = static_cast<std::int64_t>(s.seed);
  sr.integer("seed", seed, 0, INT64_MAX);
  s.seed = static_cast<std::uint64_t>(seed);
  std::string true_name = "linear";
  TableReader tb(sr.table("true_block"), "sim.true_block", origin);
  read_block(tb, true_name, s.true_block);
  sr.reject_unknown();
}

}  // namespace noisemon::daemon::config_detail
