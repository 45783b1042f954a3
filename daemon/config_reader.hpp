// How the configuration file is read (config.cpp, config_sim.cpp, config_comedi.cpp): TableReader takes the known
// keys of one TOML table into fields, checks each value's type and range, and names the file, line and key of any
// problem (and of every key it never asked for); the readers of the tables kept in files of their own.
#pragma once

#include <toml++/toml.h>

#include <array>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "daemon/config.hpp"

namespace noisemon::daemon::config_detail {

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

// The value of `key` among named choices; fails naming them all.
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

// What every microphone front-end's table has for its n microphones: sensitivity_mv_per_pa (one for all or one
// each), radius_m, positions_m (none, or one each) and speed_of_sound_m_s.
struct MicChainFields {
  std::vector<double>& sensitivity_mv_per_pa;
  double& radius_m;
  std::vector<std::array<double, 3>>& positions_m;
  double& speed_of_sound_m_s;
};
void read_mic_chain(TableReader& r, std::size_t n, const MicChainFields& fields);

// A path given in the configuration file `origin`: relative ones are relative to the file's folder.
std::string beside_config(const std::string& origin, const std::string& path);

// An ADC resolution key: 0 (no converter) or 4 .. 32 bits.
void read_adc_bits(TableReader& r, const char* key, int& bits);
// A block-model table: a preset name and/or its parameters.
void read_block(TableReader& r, std::string& preset_name, model::BlockParams& p);
// Microphone positions (an array of [x, y, z] in m, each about radius_m from the origin).
void read_positions(TableReader& r, const char* key, double radius_m, std::vector<std::array<double, 3>>& out);

// [sim] (config_sim.cpp), [comedi] (config_comedi.cpp) and [alsa] (config_alsa.cpp).
void read_sim(TableReader& top, const std::string& origin, drivers::sim::SimConfig& s);
void read_comedi(TableReader& top, const std::string& origin, drivers::comedi::ComediSourceConfig& c);
void read_alsa(TableReader& top, const std::string& origin, drivers::alsa::AlsaSourceConfig& a);

}  // namespace noisemon::daemon::config_detail
