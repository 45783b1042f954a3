#include "daemon/config.hpp"

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <toml++/toml.h>

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
    if (v < min || v > max) fail(key, "value " + std::to_string(v) + " out of range [" + std::to_string(min) + ", " + std::to_string(max) + "]");
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
        s << origin_ << ":" << v.source().begin.line << ": unknown key '" << (path_.empty() ? name : path_ + "." + name) << "'";
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

void read_positions(TableReader& r, const char* key, std::vector<std::array<double, 3>>& out) {
  const toml::node* n = r.node(key);
  if (!n) return;
  const toml::array* a = n->as_array();
  if (!a) r.fail(key, "expected an array of [x, y, z] arrays (m)");
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

Config parse_table(const toml::table& root, const std::string& origin) {
  Config c;
  TableReader top(&root, "", origin);

  TableReader d(top.table("daemon"), "daemon", origin);
  d.string("source", c.source);
  if (c.source != "sim" && c.source != "lcm") d.fail("source", "unknown source '" + c.source + "' (this build knows: sim, lcm)");
  d.integer("cycles", c.cycles, 0, INT64_MAX);
  d.string("log_level", c.log_level);
  static const std::set<std::string> levels{"trace", "debug", "info", "warn", "error", "critical", "off"};
  if (!levels.count(c.log_level)) d.fail("log_level", "expected one of trace, debug, info, warn, error, critical, off");
  d.boolean("live", c.live);
  d.reject_unknown();

  TableReader l(top.table("lcm"), "lcm", origin);
  l.string("url", c.lcm.url);
  l.string("report_channel", c.lcm.report_channel);
  l.string("status_channel", c.lcm.status_channel);
  l.string("raw_channel", c.lcm.raw_channel);
  l.string("operating_point_channel", c.lcm.operating_point_channel);
  l.string("session_channel", c.lcm.session_channel);
  l.boolean("publish_raw", c.lcm.publish_raw);
  l.boolean("publish_operating_point", c.lcm.publish_operating_point);
  l.reject_unknown();

  TableReader m(top.table("model"), "model", origin);
  read_block(m, c.model_name, c.model);

  TableReader p(top.table("processing"), "processing", origin);
  p.number("acoustic_delay_s", c.acoustic_delay_s, -1, 1.0);
  p.number("ring_seconds", c.ring_seconds, 0.1, 60);
  p.reject_unknown();

  drivers::SimConfig& s = c.sim;
  TableReader sr(top.table("sim"), "sim", origin);
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
  read_positions(sr, "mic_positions_m", s.mic_positions_m);
  if (!s.mic_positions_m.empty() && s.mic_positions_m.size() != s.mic_count)
    sr.fail("mic_positions_m", "has " + std::to_string(s.mic_positions_m.size()) + " positions but mic_count is " + std::to_string(s.mic_count));
  sr.number("radius_m", s.radius_m, 0.1, 100);
  sr.number("speed_of_sound_m_s", s.speed_of_sound_m_s, 100, 1000);
  sr.number("mic_rate_hz", s.mic_rate_hz, 40000, 1e6);
  sr.number("mic_gain_spread_db", s.mic_gain_spread_db, 0, 20);
  sr.number("background_noise_db", s.background_noise_db, -100, 200);
  std::int64_t seed = static_cast<std::int64_t>(s.seed);
  sr.integer("seed", seed, 0, INT64_MAX);
  s.seed = static_cast<std::uint64_t>(seed);
  std::string true_name = "linear";
  TableReader tb(sr.table("true_block"), "sim.true_block", origin);
  read_block(tb, true_name, s.true_block);
  sr.reject_unknown();

  top.reject_unknown();
  return c;
}

}  // namespace

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
