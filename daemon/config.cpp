#include "daemon/config.hpp"

#include <sched.h>

#include <toml++/toml.h>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "daemon/background_run.hpp"
#include "drivers/mic_positions.hpp"
#include "dsp/sound_power.hpp"

namespace noisemon::daemon {
namespace {

// Reads known keys of one TOML table into fields, and reports the keys it never asked for.
class TableReader {
 public:
  TableReader(const toml::table* table, std::string path, std::string origin)
      : table_(table), path_(std::move(path)), origin_(std::move(origin)) {}

  void number(const char* key, double& out, double min, double max) {
    const toml::node* n = get(key);
    if (!n) return;
    std::optional<double> v = n->value<double>();
    if (!v || !n->is_number()) fail(key, "expected a number");
    if (!(*v >= min && *v <= max)) {
      std::ostringstream s;
      s << "value " << *v << " out of range [" << min << ", " << max << "]";
      fail(key, s.str());
    }
    out = *v;
  }
  void integer(const char* key, std::int64_t& out, std::int64_t min, std::int64_t max) {
    const toml::node* n = get(key);
    if (!n) return;
    if (!n->is_integer()) fail(key, "expected an integer");
    const std::int64_t v = *n->value<std::int64_t>();
    if (v < min || v > max)
      fail(key,
           "value " + std::to_string(v) + " out of range [" + std::to_string(min) + ", " + std::to_string(max) + "]");
    out = v;
  }
  void boolean(const char* key, bool& out) {
    const toml::node* n = get(key);
    if (!n) return;
    if (!n->is_boolean()) fail(key, "expected true or false");
    out = *n->value<bool>();
  }
  void string(const char* key, std::string& out) {
    const toml::node* n = get(key);
    if (!n) return;
    if (!n->is_string()) fail(key, "expected a string");
    out = *n->value<std::string>();
  }
  const toml::table* table(const char* key) {
    const toml::node* n = get(key);
    if (!n) return nullptr;
    if (!n->is_table()) fail(key, "expected a table");
    return n->as_table();
  }
  const toml::node* node(const char* key) { return get(key); }
  std::string key_path(const char* key) const { return path_.empty() ? key : path_ + "." + key; }
  [[noreturn]] void fail(const char* key, const std::string& what) const {
    throw ConfigError(origin_ + ": " + key_path(key) + ": " + what);
  }
  void reject_unknown() const {
    if (!table_) return;
    for (const auto& [k, v] : *table_) {
      const std::string name(k.str());
      if (!seen_.count(name)) {
        std::ostringstream s;
        s << origin_ << ":" << v.source().begin.line << ": unknown key '" << (path_.empty() ? name : path_ + "." + name)
          << "'";
        throw ConfigError(s.str());
      }
    }
  }

 private:
  const toml::node* get(const char* key) {
    seen_.insert(key);
    return table_ ? table_->get(key) : nullptr;
  }
  const toml::table* table_;
  std::string path_, origin_;
  std::set<std::string> seen_;
};

// An ADC resolution key: 0 (no converter) or 4 .. 32 bits.
void read_adc_bits(TableReader& r, const char* key, int& bits) {
  std::int64_t v = bits;
  r.integer(key, v, 0, 32);
  if (v > 0 && v < 4) r.fail(key, "expected 0 (no ADC) or 4 .. 32 bits");
  bits = static_cast<int>(v);
}

// The realistic test cell of [sim]: pressure chain, microphone chain, gas ringing (every key documented in
// systemd/noisemond.toml; each part has a value that switches it off).
void read_sim_cell(TableReader& sr, drivers::SimConfig& s) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  auto& p = s.pressure_chain;
  sr.number("pressure_noise_bar", p.noise_bar, 0, 100);
  sr.number("pressure_flicker_bar", p.flicker_bar, 0, 100);
  read_adc_bits(sr, "pressure_adc_bits", p.adc_bits);
  sr.number("pressure_adc_min_bar", p.adc_min_bar, -1e3, 1e4);
  sr.number("pressure_adc_max_bar", p.adc_max_bar, -1e3, 1e4);
  if (p.adc_bits > 0 && !(p.adc_max_bar > p.adc_min_bar))
    sr.fail("pressure_adc_max_bar", "must be above pressure_adc_min_bar");
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
void read_faults(TableReader& sr, const std::string& origin, drivers::SimConfig& s) {
  const toml::node* n = sr.node("faults");
  if (!n) return;
  const toml::array* list = n->as_array();
  if (!list || !list->is_array_of_tables()) sr.fail("faults", "expected an array of tables ([[sim.faults]])");
  for (std::size_t i = 0; i < list->size(); ++i) {
    TableReader r((*list)[i].as_table(), "sim.faults[" + std::to_string(i) + "]", origin);
    std::string kind_name, channel;
    r.string("kind", kind_name);
    const std::optional<drivers::SimFaultKind> kind = drivers::parse_fault_kind(kind_name);
    if (!kind)
      r.fail("kind", "unknown fault '" + kind_name +
                         "' (expected missing_edges, extra_edges, lost_index, reverse, flat, overload, nan, unplugged, "
                         "stall, overrun, fail)");
    drivers::SimFault f;
    f.kind = *kind;
    r.string("channel", channel);
    try {
      f.target = drivers::parse_fault_target(f.kind, channel, s.mic_count);
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
void read_effects(TableReader& sr, const std::string& origin, drivers::SimConfig& s) {
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
    drivers::ScheduledEffect e;
    r.number("onset_s", e.onset_s, 0, 1e9);
    r.number("ramp_s", e.ramp_s, 0, 1e9);
    r.reject_unknown();
    try {
      e.setting = model::parse_effect(text);
      model::Effects all = drivers::cumulative_effects(s.effects, s.scheduled_effects, s.scheduled_effects.size());
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
void read_schedule(TableReader& sr, const std::string& origin, drivers::SimConfig& s) {
  const toml::node* n = sr.node("schedule");
  if (!n) return;
  const toml::array* list = n->as_array();
  if (!list || !list->is_array_of_tables()) sr.fail("schedule", "expected an array of tables ([[sim.schedule]])");
  model::OperatingCondition previous{
      .speed_rpm = s.speed_rpm, .load_nm = s.load_nm, .soi_deg_btdc = s.soi_deg_btdc, .motored = s.motored};
  for (std::size_t i = 0; i < list->size(); ++i) {
    TableReader r((*list)[i].as_table(), "sim.schedule[" + std::to_string(i) + "]", origin);
    drivers::OperatingStep step;
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
  if (drivers::sized_by_operating_point(
          drivers::cumulative_effects(s.effects, s.scheduled_effects, s.scheduled_effects.size())))
    sr.fail("schedule",
            "cannot be combined with effects that depend on the operating point (speed_dependence, "
            "mechanical_noise): they would keep the first operating point's size");
}

// [model] or [sim.true_block]: a preset plus optional parameter overrides.
void read_block(TableReader& r, std::string& preset_name, model::BlockParams& p) {
  if (r.node("preset")) {
    r.string("preset", preset_name);
    try {
      p = model::preset(preset_name);
    } catch (const std::invalid_argument& e) {
      r.fail("preset", e.what());
    }
  }
  r.number("m", p.m, 1e-9, 1e9);
  r.number("k1", p.k1, 0, 1e20);
  r.number("k3", p.k3, 0, 1e30);
  r.number("b1", p.b1, 0, 1e15);
  r.number("b3", p.b3, 0, 1e20);
  r.number("c0", p.c0, -1e15, 1e15);
  r.number("c1", p.c1, -1e15, 1e15);
  r.reject_unknown();
}

// Microphone positions: an array of [x, y, z] (m), or a preset scaled to the hemisphere's radius: "iso3744" (ISO
// 3744:2010 Annex B's ten key positions) or "table3.1" (the thesis's Table 3.1, drawn at r = 1.75 m).
void read_positions(TableReader& r, const char* key, double radius_m, std::vector<std::array<double, 3>>& out) {
  const toml::node* n = r.node(key);
  if (!n) return;
  if (n->is_string()) {
    const std::string preset = *n->value<std::string>();
    if (preset == "iso3744")
      out = dsp::iso3744_key_positions(radius_m);
    else if (preset == "table3.1")
      out = drivers::thesis_mic_positions(radius_m / 1.75);
    else
      r.fail(key, "unknown preset '" + preset + "' (expected iso3744, table3.1 or an array of [x, y, z])");
    return;
  }
  const toml::array* a = n->as_array();
  if (!a) r.fail(key, "expected an array of [x, y, z] arrays (m), or \"iso3744\" or \"table3.1\"");
  out.clear();
  for (const toml::node& e : *a) {
    const toml::array* xyz = e.as_array();
    if (!xyz || xyz->size() != 3) r.fail(key, "each position must be [x, y, z] in metres");
    std::array<double, 3> p{};
    for (std::size_t i = 0; i < 3; ++i) {
      auto v = (*xyz)[i].value<double>();
      if (!v) r.fail(key, "each coordinate must be a number");
      p[i] = *v;
    }
    out.push_back(p);
  }
}

// [sound_power]: ISO 3744's corrections. A background run's path is relative to the configuration file.
void read_sound_power(TableReader& top, const std::string& origin, SoundPowerConfig& sp) {
  TableReader r(top.table("sound_power"), "sound_power", origin);
  r.number("k2_db", sp.k2_db, 0, 30);
  r.number("absorption_area_m2", sp.absorption_area_m2, 0, 1e6);
  r.number("no_correction_above_db", sp.no_correction_above_db, 6, 30);
  r.number("air_temperature_c", sp.air_temperature_c, -50, 60);
  r.number("air_pressure_kpa", sp.air_pressure_kpa, 50, 120);
  r.boolean("lw_full_range", sp.full_range);
  r.number("source_dimension_m", sp.source_dimension_m, 0, 100);
  if (r.node("background_db") && r.node("background_run"))
    r.fail("background_run", "give background_db or background_run, not both");
  if (const toml::node* n = r.node("background_db")) {
    const toml::array* a = n->as_array();
    if (!a || a->size() != kBackgroundBands)
      r.fail("background_db",
             "expected 31 band levels, 20 Hz ... 20 kHz (dB re 20 uPa, unweighted; nan: not measured)");
    for (const toml::node& v : *a) {
      if (!v.is_number()) r.fail("background_db", "expected numbers (dB re 20 uPa; nan for a band not measured)");
      sp.background_db.push_back(*v.value<double>());
    }
  }
  if (const toml::node* n = r.node("area_weights")) {
    if (n->is_string() && *n->value<std::string>() == "voronoi")
      sp.voronoi_area_weights = true;
    else if (n->is_string() && *n->value<std::string>() == "equal")
      sp.voronoi_area_weights = false;
    else if (const toml::array* a = n->as_array()) {
      for (const toml::node& v : *a) {
        if (!v.is_number() || !(*v.value<double>() > 0))
          r.fail("area_weights", "expected positive numbers, one per microphone");
        sp.area_weights.push_back(*v.value<double>());
      }
    } else {
      r.fail("area_weights", "expected \"equal\", \"voronoi\" or one positive share per microphone");
    }
  }
  std::string run;
  r.string("background_run", run);
  if (!run.empty()) {
    std::filesystem::path path(run);
    if (path.is_relative() && std::filesystem::path(origin).has_parent_path())
      path = std::filesystem::path(origin).parent_path() / path;
    try {
      sp.background_db = background_from_run_dir(path);
    } catch (const std::exception& e) {
      r.fail("background_run", e.what());
    }
  }
  r.reject_unknown();
}

// ---- [comedi] -----------------------------------------------------------------------------------------------

template <class T>
T pick(TableReader& r, const char* key, const std::string& value,
       std::initializer_list<std::pair<const char*, T>> choices) {
  std::string names;
  for (const auto& [name, v] : choices) {
    if (value == name) return v;
    names += (names.empty() ? "" : ", ") + std::string(name);
  }
  r.fail(key, "unknown value '" + value + "' (expected one of " + names + ")");
}

unsigned read_aref(TableReader& r, const char* key, const std::string& value) {
  return pick<unsigned>(r, key, value,
                        {{"ground", AREF_GROUND}, {"common", AREF_COMMON}, {"diff", AREF_DIFF}, {"other", AREF_OTHER}});
}

void read_aref_key(TableReader& r, const char* key, unsigned& out) {
  if (!r.node(key)) return;
  std::string name;
  r.string(key, name);
  out = read_aref(r, key, name);
}

void read_convert(TableReader& r, unsigned& out) {
  if (!r.node("convert")) return;
  std::string name;
  r.string("convert", name);
  out = pick<unsigned>(r, "convert", name, {{"timer", TRIG_TIMER}, {"now", TRIG_NOW}, {"follow", TRIG_FOLLOW}});
}

void read_unsigned(TableReader& r, const char* key, unsigned& out, std::int64_t max = 65535) {
  std::int64_t v = out;
  r.integer(key, v, 0, max);
  out = static_cast<unsigned>(v);
}

void read_int(TableReader& r, const char* key, int& out, std::int64_t min, std::int64_t max) {
  std::int64_t v = out;
  r.integer(key, v, min, max);
  out = static_cast<int>(v);
}

// buffer_bytes and wake_every_scan, the kernel buffer and wake-up of one acquisition ([comedi.pressure],
// [comedi.encoder], [comedi.mics]). 0 bytes leaves the driver's buffer; at most 1 GiB.
void read_kernel_buffer(TableReader& r, unsigned& buffer_bytes, bool& wake_every_scan) {
  read_unsigned(r, "buffer_bytes", buffer_bytes, std::int64_t{1} << 30);
  r.boolean("wake_every_scan", wake_every_scan);
}

// A key that is either one value for every microphone or an array of one per microphone.
template <class T, class Read>
std::vector<T> per_channel(TableReader& r, const char* key, std::size_t n, T fallback, Read read) {
  std::vector<T> out(n, fallback);
  const toml::node* node = r.node(key);
  if (!node) return out;
  if (const toml::array* a = node->as_array()) {
    if (a->size() != n)
      r.fail(key, "has " + std::to_string(a->size()) + " entries but there are " + std::to_string(n) + " channels");
    for (std::size_t i = 0; i < n; ++i) out[i] = read((*a)[i], key);
    return out;
  }
  const T v = read(*node, key);
  std::fill(out.begin(), out.end(), v);
  return out;
}

// [comedi.pressure]: the pressure (and cam) channel.
void read_comedi_pressure(TableReader& r, const std::string& origin, drivers::ComediSourceConfig::Pressure& p) {
  TableReader pr(r.table("pressure"), "comedi.pressure", origin);
  pr.string("device", p.device);
  read_int(pr, "subdevice", p.subdevice, -1, 255);
  read_unsigned(pr, "edge_trigger", p.edge_trigger, 1 << 30);
  read_int(pr, "start_trigger", p.start_trigger, -1, 1 << 30);
  read_convert(pr, p.convert_src);
  read_unsigned(pr, "channel", p.channel.channel);
  read_unsigned(pr, "range", p.channel.range, 255);
  read_aref_key(pr, "aref", p.channel.aref);
  pr.number("sensitivity_mv_per_bar", p.sensitivity_mv_per_bar, 0, 1e6);
  pr.number("sensitivity_pc_per_bar", p.sensitivity_pc_per_bar, 0, 1e6);
  pr.number("amplifier_mv_per_pc", p.amplifier_mv_per_pc, 0, 1e6);
  pr.number("peg_pa", p.peg_pa, 0, 1e8);
  pr.number("peg_angle_deg", p.peg_angle_deg, -360, 360);
  read_int(pr, "cam_channel", p.cam_channel, -1, 65535);
  read_unsigned(pr, "cam_range", p.cam_range, 255);
  read_aref_key(pr, "cam_aref", p.cam_aref);
  read_kernel_buffer(pr, p.buffer_bytes, p.wake_every_scan);
  pr.reject_unknown();
}

// [comedi.encoder]: the crank encoder's counters.
void read_comedi_encoder(TableReader& r, const std::string& origin, drivers::ComediSourceConfig::Encoder& e) {
  TableReader er(r.table("encoder"), "comedi.encoder", origin);
  er.string("device", e.device);
  read_int(er, "subdevice", e.subdevice, -1, 255);
  read_unsigned(er, "edge_trigger", e.edge_trigger, 1 << 30);
  read_int(er, "start_trigger", e.start_trigger, -1, 1 << 30);
  read_convert(er, e.convert_src);
  read_unsigned(er, "position_channel", e.position_channel);
  read_int(er, "position_counter_mode", e.position_counter_mode, -1, INT32_MAX);
  read_int(er, "timestamp_subdevice", e.timestamp_subdevice, -1, 255);
  read_unsigned(er, "timestamp_channel", e.timestamp_channel);
  read_int(er, "timestamp_counter_mode", e.timestamp_counter_mode, -1, INT32_MAX);
  if (er.node("timestamp_mode")) {
    std::string mode;
    er.string("timestamp_mode", mode);
    e.timestamp_mode = pick<drivers::TimestampMode>(
        er, "timestamp_mode", mode,
        {{"absolute", drivers::TimestampMode::kAbsolute}, {"period", drivers::TimestampMode::kPeriod}});
  }
  er.number("timebase_hz", e.timebase_hz, 1, 1e10);
  std::int64_t bits = e.timestamp_bits, cpr = e.counts_per_rev;
  er.integer("timestamp_bits", bits, 8, 32);
  er.integer("counts_per_rev", cpr, 4, 1 << 24);
  e.timestamp_bits = static_cast<std::uint32_t>(bits);
  e.counts_per_rev = static_cast<std::uint32_t>(cpr);
  er.number("index_angle_deg", e.index_angle_deg, -360, 360);
  er.boolean("index_resets_counter", e.index_resets_counter);
  std::int64_t per_edge = e.counts_per_edge;
  er.integer("counts_per_edge", per_edge, 1, 64);
  e.counts_per_edge = static_cast<std::uint32_t>(per_edge);
  er.number("max_rpm", e.max_rpm, 0, 100000);
  read_kernel_buffer(er, e.buffer_bytes, e.wake_every_scan);
  er.reject_unknown();
}

// comedi.mics.channels, and the per-channel range and aref (one value for all or one per channel).
void read_mic_channels(TableReader& mr, drivers::ComediSourceConfig::Mics& m) {
  if (const toml::node* n = mr.node("channels")) {
    const toml::array* a = n->as_array();
    if (!a || a->empty() || a->size() > drivers::SampleBlock::kMaxChannels)
      mr.fail("channels",
              "expected an array of 1.." + std::to_string(drivers::SampleBlock::kMaxChannels) + " channel numbers");
    m.channels.clear();
    for (const toml::node& ch : *a) {
      if (!ch.is_integer() || *ch.value<std::int64_t>() < 0 || *ch.value<std::int64_t>() > 65535)
        mr.fail("channels", "each channel must be an integer in [0, 65535]");
      m.channels.push_back({.channel = static_cast<unsigned>(*ch.value<std::int64_t>())});
    }
  }
  const std::size_t n = m.channels.size();
  const auto ranges = per_channel<unsigned>(mr, "range", n, 0u, [&](const toml::node& v, const char* key) {
    if (!v.is_integer() || *v.value<std::int64_t>() < 0 || *v.value<std::int64_t>() > 255)
      mr.fail(key, "expected integers in [0, 255]");
    return static_cast<unsigned>(*v.value<std::int64_t>());
  });
  const auto arefs = per_channel<unsigned>(mr, "aref", n, static_cast<unsigned>(AREF_GROUND),
                                           [&](const toml::node& v, const char* key) {
                                             if (!v.is_string())
                                               mr.fail(key, "expected \"ground\", \"common\", \"diff\" or \"other\"");
                                             return read_aref(mr, key, *v.value<std::string>());
                                           });
  for (std::size_t i = 0; i < n; ++i) {
    m.channels[i].range = ranges[i];
    m.channels[i].aref = arefs[i];
  }
}

// [comedi.mics]: the microphone channels, their sensitivities and positions.
void read_comedi_mics(TableReader& r, const std::string& origin, drivers::ComediSourceConfig::Mics& m) {
  TableReader mr(r.table("mics"), "comedi.mics", origin);
  mr.string("device", m.device);
  read_int(mr, "subdevice", m.subdevice, -1, 255);
  mr.number("scan_rate_hz", m.scan_rate_hz, 8000, 1e7);
  read_mic_channels(mr, m);
  const std::size_t n = m.channels.size();
  if (mr.node("sensitivity_mv_per_pa") || n != m.sensitivity_mv_per_pa.size())
    m.sensitivity_mv_per_pa =
        per_channel<double>(mr, "sensitivity_mv_per_pa", n, 0.0, [&](const toml::node& v, const char* key) {
          if (!v.is_number() || !(*v.value<double>() > 0.0)) mr.fail(key, "expected positive numbers (mV/Pa)");
          return *v.value<double>();
        });
  mr.number("radius_m", m.radius_m, 0.1, 100);
  read_positions(mr, "positions_m", m.radius_m, m.positions_m);
  if (!m.positions_m.empty() && m.positions_m.size() != n)
    mr.fail("positions_m", "has " + std::to_string(m.positions_m.size()) + " positions but there are " +
                               std::to_string(n) + " channels");
  mr.number("speed_of_sound_m_s", m.speed_of_sound_m_s, 100, 1000);
  read_kernel_buffer(mr, m.buffer_bytes, m.wake_every_scan);
  mr.reject_unknown();
}

void read_comedi(TableReader& top, const std::string& origin, drivers::ComediSourceConfig& c) {
  TableReader r(top.table("comedi"), "comedi", origin);
  if (r.node("phase")) {
    std::string phase;
    r.string("phase", phase);
    c.phase = pick<drivers::PhaseSource>(
        r, "phase", phase, {{"pressure", drivers::PhaseSource::kPressure}, {"cam", drivers::PhaseSource::kCam}});
  }
  r.number("cam_threshold_v", c.cam_threshold_v, -100, 100);
  r.number("cam_edge_deg", c.cam_edge_deg, -360, 360);
  double initial_ms = 1e-3 * static_cast<double>(c.initial_backoff.count());
  double max_ms = 1e-3 * static_cast<double>(c.max_backoff.count());
  r.number("backoff_initial_ms", initial_ms, 0.001, 60000);
  r.number("backoff_max_ms", max_ms, 0.001, 600000);
  if (max_ms < initial_ms) r.fail("backoff_max_ms", "must not be below backoff_initial_ms");
  c.initial_backoff = std::chrono::microseconds(std::llround(initial_ms * 1e3));
  c.max_backoff = std::chrono::microseconds(std::llround(max_ms * 1e3));
  read_unsigned(r, "max_consecutive_overruns", c.max_consecutive_overruns, 1000000);
  read_comedi_pressure(r, origin, c.pressure);
  read_comedi_encoder(r, origin, c.encoder);
  read_comedi_mics(r, origin, c.mics);
  r.reject_unknown();
}

// ---- [can] --------------------------------------------------------------------------------------------------

void read_can(TableReader& top, const toml::table& root, const std::string& origin, drivers::CanSourceConfig& c) {
  TableReader r(top.table("can"), "can", origin);
  r.string("interface", c.interface);
  r.string("candump", c.candump_path);
  if (r.node("pace")) {
    std::string pace;
    r.string("pace", pace);
    c.paced = pick<bool>(r, "pace", pace, {{"recorded", true}, {"fast", false}});
  }
  r.node("signal");  // read below, with its own strict checks
  r.reject_unknown();
  try {
    c.map = drivers::parse_can_signal_map(root, origin);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(e.what());
  }
  if (c.configured() && c.map.signals().empty())
    r.fail(c.candump_path.empty() ? "interface" : "candump", "no [[can.signal]] entries: nothing to decode");
  if (!c.configured() && !c.map.signals().empty())
    r.fail("signal", "[[can.signal]] given but neither can.interface nor can.candump to read them from");
}

// ---- [engine] -----------------------------------------------------------------------------------------------

// The measured engine's geometry, for the combustion metrics (IMEP, heat release).
void read_engine(TableReader& top, const std::string& origin, model::EngineGeometry& e) {
  TableReader r(top.table("engine"), "engine", origin);
  double bore_mm = e.bore_m * 1e3, stroke_mm = e.stroke_m * 1e3, rod_mm = e.conrod_m * 1e3;
  r.number("bore_mm", bore_mm, 1, 2000);
  r.number("stroke_mm", stroke_mm, 1, 5000);
  r.number("rod_mm", rod_mm, 1, 20000);
  r.number("compression_ratio", e.compression_ratio, 1.5, 100);
  r.reject_unknown();
  if (!(rod_mm > stroke_mm / 2))
    r.fail("rod_mm", "the connecting rod must be longer than the crank throw (half the stroke)");
  // Only what the file gives changes (mm to m by division: 86 mm is exactly the default 0.086 m).
  if (r.node("bore_mm")) e.bore_m = bore_mm / 1000.0;
  if (r.node("stroke_mm")) e.stroke_m = stroke_mm / 1000.0;
  if (r.node("rod_mm")) e.conrod_m = rod_mm / 1000.0;
}

// ---- [combustion] -------------------------------------------------------------------------------------------

// Pegging and the combustion window (model/combustion_metrics.hpp).
void read_combustion(TableReader& top, const std::string& origin, model::MetricsOptions& o, bool& tdc_configured) {
  TableReader r(top.table("combustion"), "combustion", origin);
  std::string pegging = "none";
  r.string("pegging", pegging);
  if (pegging == "intake")
    o.pegging = model::Pegging::kIntake;
  else if (pegging == "polytropic")
    o.pegging = model::Pegging::kPolytropic;
  else if (pegging != "none")
    r.fail("pegging", "expected \"none\", \"intake\" or \"polytropic\"");
  double intake_bar = o.peg_intake_pa / 1e5, exponent = 0.0;
  r.number("intake_pressure_bar", intake_bar, 0.1, 10);
  r.number("pegging_window_deg", o.peg_half_width_deg, 1, 90);
  r.number("polytropic_exponent", exponent, 0, 1.7);
  if (r.node("polytropic_exponent") && exponent != 0.0 && exponent < 1.0)
    r.fail("polytropic_exponent", "expected 1.0 ... 1.7, or 0 for a fitted exponent");
  r.number("polytropic_from_deg", o.peg_poly_from_deg, -180, 0);
  r.number("polytropic_to_deg", o.peg_poly_to_deg, -180, 0);
  if (!(o.peg_poly_from_deg < o.peg_poly_to_deg)) r.fail("polytropic_to_deg", "must lie after polytropic_from_deg");
  r.number("gamma", o.gamma, 1.1, 1.67);
  std::string gamma_model = o.gamma_of_temperature ? "temperature" : "constant";
  r.string("gamma_model", gamma_model);
  if (gamma_model != "constant" && gamma_model != "temperature")
    r.fail("gamma_model", "expected \"constant\" (gamma) or \"temperature\" (Brunt et al.'s gamma(T))");
  o.gamma_of_temperature = gamma_model == "temperature";
  r.number("tdc_deg", o.tdc_deg, -30, 30);
  tdc_configured = r.node("tdc_deg") != nullptr;
  r.number("rise_from_deg", o.rise_from_deg, -180, 180);
  r.number("rise_to_deg", o.rise_to_deg, -180, 360);
  r.number("mapo_low_hz", o.mapo_low_hz, 100, 100e3);
  r.number("mapo_high_hz", o.mapo_high_hz, 100, 200e3);
  if (!(o.mapo_low_hz < o.mapo_high_hz)) r.fail("mapo_high_hz", "must lie above mapo_low_hz");
  r.number("mapo_from_deg", o.mapo_from_deg, -180, 180);
  r.number("mapo_to_deg", o.mapo_to_deg, -180, 180);
  if (!(o.mapo_from_deg < o.mapo_to_deg)) r.fail("mapo_to_deg", "must lie after mapo_from_deg");
  r.reject_unknown();
  o.peg_intake_pa = intake_bar * 1e5;
  o.peg_exponent = exponent > 0 ? exponent : std::numeric_limits<double>::quiet_NaN();
}

// ---- [threads] ----------------------------------------------------------------------------------------------

// [threads.<name>]: priority = SCHED_FIFO priority (0: normal scheduling), cpu = CPU index (-1: any).
void read_thread_policy(TableReader& threads, const char* name, const std::string& origin,
                        drivers::ThreadPolicy& policy) {
  TableReader r(threads.table(name), threads.key_path(name), origin);
  std::int64_t priority = policy.fifo_priority, cpu = policy.cpu.value_or(-1);
  r.integer("priority", priority, 0, 99);  // 99: Linux's highest SCHED_FIFO priority
  r.integer("cpu", cpu, -1, CPU_SETSIZE - 1);
  r.reject_unknown();
  policy.fifo_priority = static_cast<int>(priority);
  policy.cpu = cpu < 0 ? std::nullopt : std::optional<int>(static_cast<int>(cpu));
}

void read_threads(TableReader& top, const std::string& origin, ThreadsConfig& t) {
  TableReader r(top.table("threads"), "threads", origin);
  r.boolean("lock_memory", t.lock_memory);
  const std::pair<const char*, drivers::ThreadPolicy*> policies[] = {{"pressure", &t.pressure},
                                                                     {"mics", &t.mics},
                                                                     {"operating_point", &t.operating_point},
                                                                     {"can", &t.can},
                                                                     {"lcm_receive", &t.lcm_receive},
                                                                     {"processing", &t.processing},
                                                                     {"publishing", &t.publishing}};
  for (const auto& [name, policy] : policies) read_thread_policy(r, name, origin, *policy);
  r.reject_unknown();
}

// [lcm]: the URL, the channel names and the cell id (which suffixes them).
void read_lcm(TableReader& top, const std::string& origin, LcmConfig& lcm) {
  TableReader l(top.table("lcm"), "lcm", origin);
  l.string("url", lcm.url);
  l.string("report_channel", lcm.report_channel);
  l.string("status_channel", lcm.status_channel);
  l.string("raw_channel", lcm.raw_channel);
  l.string("operating_point_channel", lcm.operating_point_channel);
  l.string("session_channel", lcm.session_channel);
  l.string("stats_channel", lcm.stats_channel);
  l.string("gap_event_channel", lcm.gap_event_channel);
  l.string("gap_status_channel", lcm.gap_status_channel);
  l.boolean("publish_raw", lcm.publish_raw);
  l.boolean("publish_operating_point", lcm.publish_operating_point);
  l.number("session_timeout_s", lcm.session_timeout_s, 0.01, 3600);
  std::string cell;
  l.string("cell", cell);
  try {
    set_cell(lcm, cell);
  } catch (const ConfigError& e) {
    l.fail("cell", e.what());
  }
  l.reject_unknown();
}

// [sim]: the virtual engine, its cell, faults, effects and operating-point schedule.
void read_sim(TableReader& top, const std::string& origin, drivers::SimConfig& s) {
  TableReader sr(top.table("sim"), "sim", origin);
  sr.boolean("paced", s.paced);
  sr.number("speed_rpm", s.speed_rpm, 100, 10000);
  sr.number("load_nm", s.load_nm, 0, 1e4);
  sr.number("full_load_nm", s.full_load_nm, 1e-3, 1e4);
  sr.number("soi_deg_btdc", s.soi_deg_btdc, -30, 60);
  sr.boolean("motored", s.motored);
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

Config parse_table(const toml::table& root, const std::string& origin) {
  Config c;
  TableReader top(&root, "", origin);

  TableReader d(top.table("daemon"), "daemon", origin);
  d.string("source", c.source);
  if (c.source != "sim" && c.source != "lcm" && c.source != "comedi")
    d.fail("source", "unknown source '" + c.source + "' (this build knows: sim, lcm, comedi)");
  d.integer("cycles", c.cycles, 0, INT64_MAX);
  d.string("log_level", c.log_level);
  static const std::set<std::string> levels{"trace", "debug", "info", "warn", "error", "critical", "off"};
  if (!levels.count(c.log_level)) d.fail("log_level", "expected one of trace, debug, info, warn, error, critical, off");
  d.boolean("live", c.live);
  d.reject_unknown();

  read_lcm(top, origin, c.lcm);

  read_engine(top, origin, c.engine);
  read_combustion(top, origin, c.combustion, c.tdc_deg_configured);

  TableReader st(top.table("statistics"), "statistics", origin);
  st.integer("window_cycles", c.stats_window_cycles, 0, 100000);
  st.reject_unknown();

  TableReader m(top.table("model"), "model", origin);
  read_block(m, c.model_name, c.model);

  read_sound_power(top, origin, c.sound_power);

  TableReader p(top.table("processing"), "processing", origin);
  p.number("acoustic_delay_s", c.acoustic_delay_s, -1, 1.0);
  p.number("ring_seconds", c.ring_seconds, 0.1, 60);
  p.number("mic_low_db", c.mic_low_db, 1, 200);
  std::string mic_average = c.mic_average_time ? "time" : "energy";
  p.string("mic_average", mic_average);
  if (mic_average != "energy" && mic_average != "time") p.fail("mic_average", "expected \"energy\" or \"time\"");
  c.mic_average_time = mic_average == "time";
  p.reject_unknown();

  read_sim(top, origin, c.sim);

  read_comedi(top, origin, c.comedi);
  read_can(top, root, origin, c.can);
  read_threads(top, origin, c.threads);

  top.reject_unknown();
  return c;
}

}  // namespace

void set_cell(LcmConfig& lcm, const std::string& cell) {
  for (const char ch : cell)
    if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '-')
      throw ConfigError("cell id '" + cell + "': only letters, digits and '-' are allowed");
  const std::string old_suffix = lcm.cell.empty() ? "" : "_" + lcm.cell;
  for (std::string* channel :
       {&lcm.report_channel, &lcm.status_channel, &lcm.raw_channel, &lcm.operating_point_channel, &lcm.session_channel,
        &lcm.stats_channel, &lcm.gap_event_channel, &lcm.gap_status_channel}) {
    if (!old_suffix.empty() && channel->ends_with(old_suffix)) channel->resize(channel->size() - old_suffix.size());
    if (!cell.empty()) *channel += "_" + cell;
  }
  lcm.cell = cell;
}

Config parse_config(const std::string& text, const std::string& origin) {
  toml::table root;
  try {
    root = toml::parse(text, origin);
  } catch (const toml::parse_error& e) {
    std::ostringstream s;
    s << origin << ":" << e.source().begin.line << ":" << e.source().begin.column << ": " << e.description();
    throw ConfigError(s.str());
  }
  return parse_table(root, origin);
}

Config load_config(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(path + ": cannot open configuration file");
  std::stringstream buf;
  buf << in.rdbuf();
  return parse_config(buf.str(), path);
}

}  // namespace noisemon::daemon
