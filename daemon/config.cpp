#include "daemon/config.hpp"

#include <sched.h>

#include <toml++/toml.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "daemon/background_run.hpp"
#include "daemon/calibration_history.hpp"
#include "daemon/config_reader.hpp"
#include "daemon/record_files.hpp"
#include "daemon/sources.hpp"
#include "drivers/mic_positions.hpp"
#include "dsp/sound_power.hpp"

namespace noisemon::daemon {
namespace config_detail {

// An ADC resolution key: 0 (no converter) or 4 .. 32 bits.
void read_adc_bits(TableReader& r, const char* key, int& bits) {
  std::int64_t v = bits;
  r.integer(key, v, 0, 32);
  if (v > 0 && v < 4) r.fail(key, "expected 0 (no ADC) or 4 .. 32 bits");
  bits = static_cast<int>(v);
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

void read_mic_chain(TableReader& r, std::size_t n, const MicChainFields& f) {
  if (r.node("sensitivity_mv_per_pa") || n != f.sensitivity_mv_per_pa.size())
    f.sensitivity_mv_per_pa =
        per_channel<double>(r, "sensitivity_mv_per_pa", n, 0.0, [&](const toml::node& v, const char* key) {
          if (!v.is_number() || !(*v.value<double>() > 0.0)) r.fail(key, "expected positive numbers (mV/Pa)");
          return *v.value<double>();
        });
  r.number("radius_m", f.radius_m, 0.1, 100);
  read_positions(r, "positions_m", f.radius_m, f.positions_m);
  if (!f.positions_m.empty() && f.positions_m.size() != n)
    r.fail("positions_m", "has " + std::to_string(f.positions_m.size()) + " positions but there are " +
                              std::to_string(n) + " channels");
  r.number("speed_of_sound_m_s", f.speed_of_sound_m_s, 100, 1000);
}

std::string beside_config(const std::string& origin, const std::string& path) {
  std::filesystem::path p(path);
  if (p.is_relative() && std::filesystem::path(origin).has_parent_path())
    p = std::filesystem::path(origin).parent_path() / p;
  return p.string();
}

}  // namespace config_detail

namespace {

using namespace config_detail;

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
    try {
      sp.background_db = background_from_run_dir(beside_config(origin, run));
    } catch (const std::exception& e) {
      r.fail("background_run", e.what());
    }
  }
  r.reject_unknown();
}

// ---- [can] --------------------------------------------------------------------------------------------------

void read_can(TableReader& top, const toml::table& root, const std::string& origin, drivers::can::CanSourceConfig& c) {
  TableReader r(top.table("can"), "can", origin);
  r.string("interface", c.interface);
  r.string("candump", c.candump_path);
  if (r.node("pace")) {
    std::string pace;
    r.string("pace", pace);
    c.paced = pick<bool>(r, "pace", pace, {{"recorded", true}, {"fast", false}});
  }
  r.node("dbc");     // read below with the signals it names
  r.node("signal");  // read below, with its own strict checks
  r.reject_unknown();
  try {
    c.map = drivers::formats::parse_can_signal_map(root, origin);
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
                                                                     {"publishing", &t.publishing},
                                                                     {"recording", &t.recording}};
  for (const auto& [name, policy] : policies) read_thread_policy(r, name, origin, *policy);
  r.reject_unknown();
}

// [lcm]: the URL, the channel names and the cell id (which suffixes them).
void read_lcm(TableReader& top, const std::string& origin, LcmConfig& lcm) {
  TableReader l(top.table("lcm"), "lcm", origin);
  l.string("url", lcm.url);
  for (const auto& [key, channel] : lcm.channels()) l.string(key, *channel);
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

// [record]: the recorder. Its folder is made and tried when the daemon starts it (recorder.hpp), not here: a
// configuration is also read where it never records (replay, the tool's commands).
void read_record(TableReader& top, const std::string& origin, RecordConfig& rec) {
  TableReader r(top.table("record"), "record", origin);
  r.boolean("enabled", rec.enabled);
  r.boolean("autostart", rec.autostart);
  r.string("dir", rec.dir);
  if (rec.enabled && rec.dir.empty()) r.fail("dir", "required when the recorder is enabled: the folder of its files");
  if (!rec.dir.empty()) rec.dir = beside_config(origin, rec.dir);
  r.number("buffer_mb", rec.buffer_mb, 1, 65536);
  r.number("rotate_mb", rec.rotate_mb, 1, 1 << 30);
  r.number("rotate_s", rec.rotate_s, 0, 366 * 86400.0);
  if (rec.rotate_s > 0 && rec.rotate_s < 1) r.fail("rotate_s", "expected 0 (no rotation by time) or at least 1 s");
  if (r.node("fsync")) {
    std::string fsync;
    r.string("fsync", fsync);
    rec.fsync = pick<RecordFsync>(
        r, "fsync", fsync,
        {{"none", RecordFsync::kNone}, {"rotate", RecordFsync::kRotate}, {"interval", RecordFsync::kInterval}});
  }
  r.number("fsync_interval_s", rec.fsync_interval_s, 0.1, 86400);
  r.string("test_point", rec.test_point);
  if (!valid_test_point(rec.test_point)) r.fail("test_point", "'" + rec.test_point + "': " + kTestPointRule);
  r.reject_unknown();
}

Config parse_table(const toml::table& root, const std::string& origin) {
  Config c;
  TableReader top(&root, "", origin);

  TableReader d(top.table("daemon"), "daemon", origin);
  d.string("source", c.source);
  if (!find_stream_source(c.source))
    d.fail("source", "unknown source '" + c.source + "' (this build knows: " + stream_source_names() + ")");
  d.string("microphones", c.microphones);
  if (!c.microphones.empty() && !find_mic_source(c.microphones))
    d.fail("microphones", "unknown microphone source '" + c.microphones + "' (this build knows: " + mic_source_names() +
                              "; leave it out for the source's own)");
  d.integer("cycles", c.cycles, 0, INT64_MAX);
  d.string("log_level", c.log_level);
  static const std::set<std::string> levels{"trace", "debug", "info", "warn", "error", "critical", "off"};
  if (!levels.count(c.log_level)) d.fail("log_level", "expected one of trace, debug, info, warn, error, critical, off");
  d.boolean("live", c.live);
  d.reject_unknown();

  read_lcm(top, origin, c.lcm);
  read_record(top, origin, c.record);

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
  read_alsa(top, origin, c.alsa);
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
  for (const auto& [key, channel] : lcm.channels()) {
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
  Config c = parse_config(buf.str(), path);
  c.calibration_history = calibration_history_path(path);
  return c;
}

}  // namespace noisemon::daemon
