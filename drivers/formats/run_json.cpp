// run.json of a run directory: the reader (every field checked, errors naming the key and what was expected) and
// the writer.
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

#include "drivers/formats/run_dir.hpp"
#include "drivers/source.hpp"

namespace noisemon::drivers::formats {
namespace {

using nlohmann::json;

constexpr std::size_t kMaxMics = SampleBlock::kMaxChannels;

const char* json_type_name(const json& v) {
  switch (v.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return "a boolean";
    case json::value_t::string:
      return "a string";
    case json::value_t::array:
      return "an array";
    case json::value_t::object:
      return "an object";
    case json::value_t::discarded:
      return "nothing";
    default:
      return "a number";
  }
}

// Typed access to run.json with errors naming the file, the key path and what was expected.
class JsonFields {
 public:
  explicit JsonFields(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw RunDirError(file_ + ": key \"" + key + "\": " + what);
  }
  const json* find(const json& obj, const std::string& parent, const char* key, bool required,
                   const char* expected) const {
    const auto it = obj.find(key);
    if (it == obj.end()) {
      if (required) throw RunDirError(file_ + ": missing key \"" + join(parent, key) + "\" (" + expected + ")");
      return nullptr;
    }
    return &*it;
  }
  const json& object(const json& obj, const std::string& parent, const char* key) const {
    const json* v = find(obj, parent, key, true, "an object");
    if (!v->is_object()) fail(join(parent, key), std::string("expected an object, found ") + json_type_name(*v));
    return *v;
  }
  std::string string(const json& obj, const std::string& parent, const char* key, const char* meaning) const {
    const json* v = find(obj, parent, key, true, meaning);
    if (!v->is_string())
      fail(join(parent, key), std::string("expected a string (") + meaning + "), found " + json_type_name(*v));
    return v->get<std::string>();
  }
  double number(const json& v, const std::string& key, const char* meaning) const {
    if (!v.is_number()) fail(key, std::string("expected a number (") + meaning + "), found " + json_type_name(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(key, std::string("expected a finite number (") + meaning + ")");
    return x;
  }
  double number(const json& obj, const std::string& parent, const char* key, const char* meaning) const {
    return number(*find(obj, parent, key, true, meaning), join(parent, key), meaning);
  }
  // A required key whose value may be null (unknown, not applicable): NaN then.
  double number_or_null(const json& obj, const std::string& parent, const char* key, const char* meaning) const {
    const json* v = find(obj, parent, key, true, meaning);
    if (v->is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!v->is_number())
      fail(join(parent, key), std::string("expected a number or null (") + meaning + "), found " + json_type_name(*v));
    return number(*v, join(parent, key), meaning);
  }
  std::optional<bool> boolean_or_null(const json& obj, const std::string& parent, const char* key,
                                      const char* meaning) const {
    const json* v = find(obj, parent, key, true, meaning);
    if (v->is_null()) return std::nullopt;
    if (!v->is_boolean())
      fail(join(parent, key),
           std::string("expected true, false or null (") + meaning + "), found " + json_type_name(*v));
    return v->get<bool>();
  }
  static std::string join(const std::string& parent, const char* key) {
    return parent.empty() ? key : parent + "." + key;
  }

 private:
  std::string file_;
};

RunCondition parse_condition(const JsonFields& f, const json& c) {
  RunCondition r;
  r.name = f.string(c, "condition", "name", "the condition's name");
  r.speed_rpm = f.number_or_null(c, "condition", "speed_rpm", "engine speed, rpm");
  if (!std::isnan(r.speed_rpm) && !(r.speed_rpm > 0))
    f.fail("condition.speed_rpm", "expected a speed above 0 rpm (or null: measured from the encoder)");
  r.load_nm = f.number_or_null(c, "condition", "load_nm", "brake torque, N m");
  r.soi_deg_btdc = f.number_or_null(c, "condition", "soi_deg_btdc", "start of injection, degrees before firing TDC");
  if (const json* v = f.find(c, "condition", "rail_pressure_bar", false, ""); v && !v->is_null()) {
    r.rail_pressure_bar = f.number(*v, "condition.rail_pressure_bar", "rail pressure in bar, or null");
    if (*r.rail_pressure_bar < 0) f.fail("condition.rail_pressure_bar", "expected a pressure >= 0 bar or null");
  }
  const std::optional<bool> motored =
      f.boolean_or_null(c, "condition", "motored", "true when the engine was motored, without combustion");
  r.motored = motored.value_or(false);
  r.motored_known = motored.has_value();
  return r;
}

// An optional number above 0 (null or absent: not known).
std::optional<double> optional_positive(const JsonFields& f, const json& object, const std::string& where,
                                        const char* key, const std::string& what) {
  const json* v = f.find(object, where, key, false, "");
  if (!v || v->is_null()) return std::nullopt;
  const double x = f.number(*v, where + "." + key, (what + ", or null").c_str());
  if (!(x > 0)) f.fail(where + "." + key, "expected a value above 0 (" + what + "), or null (unknown)");
  return x;
}

void parse_pressure_entry(const JsonFields& f, const json& p, RunManifest& m) {
  m.pressure_file = f.string(p, "pressure", "file", "the pressure CSV's file name");
  const std::string units = f.string(p, "pressure", "units", "\"bar\" or \"Pa\"");
  if (units == "bar")
    m.pressure_to_pa = 1e5;
  else if (units == "Pa")
    m.pressure_to_pa = 1.0;
  else
    f.fail("pressure.units", "\"" + units + "\", expected \"bar\" or \"Pa\"");
  if (const json* v = f.find(p, "pressure", "noise_floor_bar", false, ""); v && !v->is_null()) {
    const double floor = f.number(*v, "pressure.noise_floor_bar", "noise floor, bar rms per encoder sample, or null");
    if (!(floor >= 0))
      f.fail("pressure.noise_floor_bar", "expected a noise floor >= 0 bar rms per encoder sample, or null (unknown)");
    m.pressure_noise_floor_bar = floor;
  }
  m.pressure_edges_per_rev =
      optional_positive(f, p, "pressure", "encoder_edges_per_rev", "encoder edges per revolution");
}

void parse_mics_entry(const JsonFields& f, const json& mics, RunManifest& m) {
  if (!mics.is_object()) f.fail("mics", std::string("expected an object, found ") + json_type_name(mics));
  m.has_mics = true;
  m.mics_file = f.string(mics, "mics", "file", "the microphones' WAV file name");
  if (const json* u = f.find(mics, "mics", "units", false, "")) {
    if (!u->is_string() || u->get<std::string>() != "Pa") f.fail("mics.units", "expected \"Pa\"");
  }
  const json* pos = f.find(mics, "mics", "positions_m", true, "one [x, y, z] per microphone, m");
  if (!pos->is_array() || pos->empty() || pos->size() > kMaxMics)
    f.fail("mics.positions_m", "expected an array of 1.." + std::to_string(kMaxMics) + " [x, y, z] positions in m");
  for (std::size_t i = 0; i < pos->size(); ++i) {
    const json& xyz = (*pos)[i];
    const std::string key = "mics.positions_m[" + std::to_string(i) + "]";
    if (!xyz.is_array() || xyz.size() != 3) f.fail(key, "expected [x, y, z] in m");
    m.mic_positions_m.push_back(
        {f.number(xyz[0], key, "x, m"), f.number(xyz[1], key, "y, m"), f.number(xyz[2], key, "z, m")});
  }
  if (const json* r = f.find(mics, "mics", "radius_m", false, "")) {
    m.radius_m = f.number(*r, "mics.radius_m", "measurement radius, m");
    if (!(m.radius_m > 0)) f.fail("mics.radius_m", "expected a radius above 0 m");
  }
  if (const json* d = f.find(mics, "mics", "acoustic_delay_s", false, "")) {
    m.acoustic_delay_s = f.number(*d, "mics.acoustic_delay_s", "engine-to-microphone delay, s");
    if (m.acoustic_delay_s < 0 || m.acoustic_delay_s > 1) f.fail("mics.acoustic_delay_s", "expected 0..1 s");
  }
  if (const json* fs = f.find(mics, "mics", "full_scale_pa", false, ""); fs && !fs->is_null()) {
    m.full_scale_pa = f.number(*fs, "mics.full_scale_pa", "Pa at PCM full scale");
    if (!(*m.full_scale_pa > 0)) f.fail("mics.full_scale_pa", "expected a value above 0 Pa");
  }
  m.mic_passband_hz = optional_positive(f, mics, "mics", "passband_hz", "upper edge of the converter's passband, Hz");
}

// Unknown (NaN) as null, as run.json spells it.
json number_or_null(double v) { return std::isnan(v) ? json(nullptr) : json(v); }

json run_json(const RunDir& run, const std::string& pressure_units) {
  const RunCondition& c = run.condition;
  json root;
  root["condition"] = {{"name", c.name},
                       {"speed_rpm", number_or_null(c.speed_rpm)},
                       {"load_nm", number_or_null(c.load_nm)},
                       {"soi_deg_btdc", number_or_null(c.soi_deg_btdc)},
                       {"rail_pressure_bar", c.rail_pressure_bar ? json(*c.rail_pressure_bar) : json(nullptr)},
                       {"motored", c.motored_known ? json(c.motored) : json(nullptr)}};
  root["pressure"] = {{"file", "pressure.csv"}, {"units", pressure_units}};
  if (run.pressure_noise_floor_bar) root["pressure"]["noise_floor_bar"] = *run.pressure_noise_floor_bar;
  if (run.pressure_edges_per_rev) root["pressure"]["encoder_edges_per_rev"] = *run.pressure_edges_per_rev;
  if (run.mic_count > 0) {
    json positions = json::array();
    for (const auto& p : run.mic_positions_m) positions.push_back({p[0], p[1], p[2]});
    root["mics"] = {{"file", "mics.wav"}, {"units", "Pa"}, {"positions_m", positions}, {"radius_m", run.radius_m}};
    if (run.acoustic_delay_s >= 0) root["mics"]["acoustic_delay_s"] = run.acoustic_delay_s;
    if (run.mic_passband_hz) root["mics"]["passband_hz"] = *run.mic_passband_hz;
  }
  return root;
}

}  // namespace

RunManifest parse_run_json(std::string_view text, const std::string& file) {
  json root;
  try {
    root = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number beyond double (1e999)
    throw RunDirError(file + ": not valid JSON: " + e.what());
  }
  const JsonFields f(file);
  if (!root.is_object()) throw RunDirError(file + ": expected a JSON object at the top, found " + json_type_name(root));
  RunManifest m;
  m.condition = parse_condition(f, f.object(root, "", "condition"));
  parse_pressure_entry(f, f.object(root, "", "pressure"), m);
  if (const json* mics = f.find(root, "", "mics", false, ""); mics && !mics->is_null()) parse_mics_entry(f, *mics, m);
  return m;
}

std::string run_json_text(const RunDir& run, const std::string& pressure_units) {
  return run_json(run, pressure_units).dump(2) + "\n";
}

}  // namespace noisemon::drivers::formats
