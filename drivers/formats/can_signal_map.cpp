#include "drivers/formats/can_signal_map.hpp"

#include "drivers/formats/dbc.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <set>
#include <stdexcept>

namespace noisemon::drivers::formats {
namespace {

constexpr std::uint32_t kMaxStandardId = 0x7FF;
constexpr std::uint32_t kMaxExtendedId = 0x1FFFFFFF;

// Motorola bits counted from the frame's first transmitted bit: byte 0 bit 7 is 0, byte 0 bit 0 is 7, byte 1
// bit 7 is 8, ... In this numbering a big-endian signal is a contiguous run starting at its MSB.
std::uint32_t motorola_msb_index(std::uint32_t start_bit) { return (start_bit / 8) * 8 + (7 - start_bit % 8); }

std::uint64_t low_mask(std::uint32_t length) { return length >= 64 ? ~0ULL : ((1ULL << length) - 1); }

std::string hex_id(std::uint32_t id) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%X", id);
  return b;
}

}  // namespace

namespace {

void validate_layout(std::uint32_t start_bit, std::uint32_t length, CanByteOrder order, const std::string& what) {
  if (length < 1 || length > 64) throw std::invalid_argument(what + "length must be 1..64 bits");
  if (start_bit > 63) throw std::invalid_argument(what + "start_bit must be 0..63");
  const std::uint32_t first = order == CanByteOrder::kIntel ? start_bit : motorola_msb_index(start_bit);
  if (first + length > 64)
    throw std::invalid_argument(what + (order == CanByteOrder::kIntel ? "intel" : "motorola") + " signal (start_bit " +
                                std::to_string(start_bit) + ", length " + std::to_string(length) + ") runs past " +
                                (order == CanByteOrder::kIntel ? "bit 63" : "the last byte") + " of the 8-byte frame");
}

std::uint32_t min_dlc(std::uint32_t start_bit, std::uint32_t length, CanByteOrder order) {
  const std::uint32_t first = order == CanByteOrder::kIntel ? start_bit : motorola_msb_index(start_bit);
  return (first + length - 1) / 8 + 1;
}

}  // namespace

void validate_can_signal(const CanSignal& s) {
  const std::uint32_t max_id = s.extended ? kMaxExtendedId : kMaxStandardId;
  if (s.id > max_id) {
    throw std::invalid_argument(
        "id " + hex_id(s.id) +
        (s.extended ? " exceeds 29 bits" : " exceeds 11 bits (set extended = true for a 29-bit id)"));
  }
  validate_layout(s.start_bit, s.length, s.byte_order, "");
  for (const CanMuxCondition& m : s.multiplexors) {
    validate_layout(m.start_bit, m.length, m.byte_order, "multiplexor: ");
    if (m.length > 63 || m.ranges.empty()) throw std::invalid_argument("multiplexor: 1..63 bits and some values");
  }
  if (!(s.factor == s.factor) || !(s.offset == s.offset)) throw std::invalid_argument("factor/offset is NaN");
}

std::uint32_t can_signal_min_dlc(const CanSignal& s) {
  std::uint32_t bytes = min_dlc(s.start_bit, s.length, s.byte_order);
  for (const CanMuxCondition& m : s.multiplexors) bytes = std::max(bytes, min_dlc(m.start_bit, m.length, m.byte_order));
  return bytes;
}

std::uint64_t extract_can_raw(const std::uint8_t data[8], std::uint32_t start_bit, std::uint32_t length,
                              CanByteOrder order) {
  std::uint64_t word = 0;
  if (order == CanByteOrder::kIntel) {
    for (int i = 7; i >= 0; --i) word = (word << 8) | data[i];  // byte 0 least significant
    return (word >> start_bit) & low_mask(length);
  }
  for (int i = 0; i < 8; ++i) word = (word << 8) | data[i];  // byte 0 most significant
  const std::uint32_t shift = 64 - motorola_msb_index(start_bit) - length;
  return (word >> shift) & low_mask(length);
}

bool can_signal_present(const CanSignal& s, const std::uint8_t data[8]) {
  for (const CanMuxCondition& m : s.multiplexors) {
    const std::uint64_t v = extract_can_raw(data, m.start_bit, m.length, m.byte_order);
    if (std::none_of(m.ranges.begin(), m.ranges.end(), [v](const auto& r) { return v >= r.first && v <= r.second; }))
      return false;
  }
  return true;
}

double can_signal_value(const CanSignal& s, const std::uint8_t data[8]) {
  const std::uint64_t raw = extract_can_raw(data, s.start_bit, s.length, s.byte_order);
  double v;
  if (s.is_signed && s.length < 64 && (raw >> (s.length - 1)) & 1U) {
    v = static_cast<double>(static_cast<std::int64_t>(raw | ~low_mask(s.length)));
  } else if (s.is_signed) {
    v = static_cast<double>(static_cast<std::int64_t>(raw));
  } else {
    v = static_cast<double>(raw);
  }
  return v * s.factor + s.offset;
}

CanSignalMap::CanSignalMap(std::vector<CanSignal> signals) : signals_(std::move(signals)) {
  min_dlc_.reserve(signals_.size());
  for (const CanSignal& s : signals_) {
    validate_can_signal(s);
    min_dlc_.push_back(can_signal_min_dlc(s));
  }
}

int CanSignalMap::decode(const CanFrame& frame, OperatingPoint& op) const {
  int set = 0;
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    const CanSignal& s = signals_[i];
    if (((s.id ^ frame.id) & s.id_mask) != 0 || s.extended != frame.extended || frame.dlc < min_dlc_[i]) continue;
    if (!s.multiplexors.empty() && !can_signal_present(s, frame.data)) continue;
    const double v = can_signal_value(s, frame.data);
    switch (s.field) {
      case OperatingPointField::kSpeedRpm:
        op.speed_rpm = v;
        break;
      case OperatingPointField::kLoadNm:
        op.load_nm = v;
        break;
      case OperatingPointField::kSoiDegBtdc:
        op.soi_deg_btdc = v;
        break;
      case OperatingPointField::kRailPressureBar:
        op.rail_pressure_bar = v;
        break;
      case OperatingPointField::kMotored:
        op.motored = v != 0.0;
        break;
    }
    ++set;
  }
  return set;
}

const char* to_string(OperatingPointField f) {
  switch (f) {
    case OperatingPointField::kSpeedRpm:
      return "speed_rpm";
    case OperatingPointField::kLoadNm:
      return "load_nm";
    case OperatingPointField::kSoiDegBtdc:
      return "soi_deg_btdc";
    case OperatingPointField::kRailPressureBar:
      return "rail_pressure_bar";
    case OperatingPointField::kMotored:
      return "motored";
  }
  return "?";
}

namespace {

// Reads one [[can.signal]] entry, every error prefixed with its key path.
class SignalReader {
 public:
  SignalReader(const toml::table& t, std::string path) : t_(t), path_(std::move(path)) {}

  const toml::node* get(const char* key, bool required) {
    seen_.insert(key);
    const toml::node* n = t_.get(key);
    if (!n && required) fail(key, "missing (required)");
    return n;
  }
  std::optional<std::int64_t> integer(const char* key, bool required, std::int64_t min, std::int64_t max) {
    const toml::node* n = get(key, required);
    if (!n) return std::nullopt;
    if (!n->is_integer()) fail(key, "expected an integer");
    const std::int64_t v = *n->value<std::int64_t>();
    if (v < min || v > max)
      fail(key,
           "value " + std::to_string(v) + " out of range [" + std::to_string(min) + ", " + std::to_string(max) + "]");
    return v;
  }
  std::optional<double> number(const char* key) {
    const toml::node* n = get(key, false);
    if (!n) return std::nullopt;
    if (!n->is_number()) fail(key, "expected a number");
    return n->value<double>();
  }
  std::optional<bool> boolean(const char* key) {
    const toml::node* n = get(key, false);
    if (!n) return std::nullopt;
    if (!n->is_boolean()) fail(key, "expected true or false");
    return n->value<bool>();
  }
  std::optional<std::string> string(const char* key, bool required) {
    const toml::node* n = get(key, required);
    if (!n) return std::nullopt;
    if (!n->is_string()) fail(key, "expected a string");
    return n->value<std::string>();
  }
  void reject_unknown() const {
    for (const auto& [k, v] : t_) {
      const std::string name(k.str());
      if (!seen_.count(name)) fail(name.c_str(), "unknown key");
    }
  }
  [[noreturn]] void fail(const char* key, const std::string& what) const {
    throw std::invalid_argument(path_ + "." + key + ": " + what);
  }
  [[noreturn]] void fail(const std::string& what) const { throw std::invalid_argument(path_ + ": " + what); }

 private:
  const toml::table& t_;
  std::string path_;
  std::set<std::string> seen_;
};

OperatingPointField parse_field(SignalReader& r, const std::string& name) {
  for (auto f : {OperatingPointField::kSpeedRpm, OperatingPointField::kLoadNm, OperatingPointField::kSoiDegBtdc,
                 OperatingPointField::kRailPressureBar, OperatingPointField::kMotored})
    if (name == to_string(f)) return f;
  r.fail("field",
         "unknown field '" + name + "' (expected speed_rpm, load_nm, soi_deg_btdc, rail_pressure_bar or motored)");
}

}  // namespace

namespace {

CanByteOrder parse_byte_order(SignalReader& r) {
  const std::string order = *r.string("byte_order", true);
  if (order == "intel") return CanByteOrder::kIntel;
  if (order == "motorola") return CanByteOrder::kMotorola;
  r.fail("byte_order", "expected \"intel\" or \"motorola\", got '" + order + "'");
}

// An entry that gives the signal's layout itself.
CanSignal signal_laid_out(SignalReader& r, OperatingPointField field) {
  CanSignal s;
  s.field = field;
  s.id = static_cast<std::uint32_t>(*r.integer("id", true, 0, kMaxExtendedId));
  s.extended = r.boolean("extended").value_or(false);
  s.start_bit = static_cast<std::uint32_t>(*r.integer("start_bit", true, 0, 63));
  s.length = static_cast<std::uint32_t>(*r.integer("length", true, 1, 64));
  s.byte_order = parse_byte_order(r);
  s.is_signed = r.boolean("signed").value_or(false);
  s.factor = r.number("factor").value_or(1.0);
  s.offset = r.number("offset").value_or(0.0);
  s.unit = r.string("unit", false).value_or("");
  return s;
}

// An entry that names a signal of the DBC file: the file gives the layout, scale and add the unit.
CanSignal signal_from_dbc(SignalReader& r, const toml::table& t, const DbcFile* dbc, OperatingPointField field) {
  const std::string name = *r.string("dbc_signal", true);
  if (!dbc) r.fail("dbc_signal", "needs can.dbc, the DBC file to find '" + name + "' in");
  for (const char* layout : {"id", "extended", "start_bit", "length", "byte_order", "signed", "factor", "offset"})
    if (t.get(layout)) r.fail(layout, "not beside dbc_signal: " + dbc->path.string() + " gives the signal's layout");
  CanSignal s;
  try {
    s = dbc->can_signal(name, r.string("dbc_message", false).value_or(""), field);
  } catch (const std::invalid_argument& e) {
    r.fail("dbc_signal", e.what());
  }
  const double scale = r.number("scale").value_or(1.0), add = r.number("add").value_or(0.0);
  s.factor *= scale;
  s.offset = s.offset * scale + add;
  if (auto unit = r.string("unit", false)) s.unit = *unit;
  return s;
}

// can.dbc, relative to the configuration file's folder; none when the key is absent.
std::optional<DbcFile> read_configured_dbc(const toml::table& can, const std::string& origin) {
  const toml::node* n = can.get("dbc");
  if (!n) return std::nullopt;
  if (!n->is_string()) throw std::invalid_argument(origin + ": can.dbc: expected a path (string)");
  const std::filesystem::path path = std::filesystem::path(origin).parent_path() / *n->value<std::string>();
  try {
    return read_dbc(path);
  } catch (const std::exception& e) {
    throw std::invalid_argument(origin + ": can.dbc: " + e.what());
  }
}

}  // namespace

CanSignalMap parse_can_signal_map(const toml::table& root, const std::string& origin) {
  const toml::node* can = root.get("can");
  if (!can) return {};
  if (!can->is_table()) throw std::invalid_argument(origin + ": can: expected a table");
  const std::optional<DbcFile> dbc = read_configured_dbc(*can->as_table(), origin);
  const toml::node* list = can->as_table()->get("signal");
  if (!list) return {};
  const toml::array* arr = list->as_array();
  if (!arr) throw std::invalid_argument(origin + ": can.signal: expected an array of tables ([[can.signal]])");

  std::vector<CanSignal> signals;
  for (std::size_t i = 0; i < arr->size(); ++i) {
    const std::string path = origin + ": can.signal[" + std::to_string(i) + "]";
    const toml::table* t = (*arr)[i].as_table();
    if (!t) throw std::invalid_argument(path + ": expected a table");
    SignalReader r(*t, path);
    const OperatingPointField field = parse_field(r, *r.string("field", true));
    CanSignal s =
        t->get("dbc_signal") ? signal_from_dbc(r, *t, dbc ? &*dbc : nullptr, field) : signal_laid_out(r, field);
    r.reject_unknown();
    try {
      validate_can_signal(s);
    } catch (const std::invalid_argument& e) {
      r.fail(e.what());
    }
    signals.push_back(std::move(s));
  }
  return CanSignalMap(std::move(signals));
}

}  // namespace noisemon::drivers::formats
