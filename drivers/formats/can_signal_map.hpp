// The subset of DBC signal semantics a test cell needs to read the operating point off the engine
// controller's CAN bus: where each signal sits in which frame, how to scale it, and which OperatingPoint
// field it sets. Built once from the config; decoding a frame allocates nothing.
#pragma once

#include <toml++/toml.h>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "drivers/source.hpp"

namespace noisemon::drivers::formats {

// One classic CAN frame as received (id without flag bits).
struct CanFrame {
  std::uint32_t id = 0;
  bool extended = false;  // 29-bit identifier
  std::uint8_t dlc = 0;   // payload bytes, 0..8
  std::uint8_t data[8] = {};
};

enum class CanByteOrder : std::uint8_t {
  kIntel,     // little-endian; start_bit is the signal's least significant bit (bit i = byte i/8, bit i%8)
  kMotorola,  // big-endian; start_bit is the signal's most significant bit, same bit numbering (DBC "@0")
};

enum class OperatingPointField : std::uint8_t { kSpeedRpm, kLoadNm, kSoiDegBtdc, kRailPressureBar, kMotored };

// A multiplexor a signal depends on (DBC multiplexing): the frame carries the signal only while this field's raw
// value lies in one of the ranges. Cascaded multiplexing gives a signal several, all of which must hold.
struct CanMuxCondition {
  std::uint32_t start_bit = 0;
  std::uint32_t length = 1;
  CanByteOrder byte_order = CanByteOrder::kIntel;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> ranges;  // inclusive
};

struct CanSignal {
  OperatingPointField field = OperatingPointField::kSpeedRpm;
  std::uint32_t id = 0;
  bool extended = false;
  std::uint32_t start_bit = 0;  // 0..63, DBC convention for the byte order
  std::uint32_t length = 1;     // 1..64
  CanByteOrder byte_order = CanByteOrder::kIntel;
  bool is_signed = false;  // two's complement
  double factor = 1.0;
  double offset = 0.0;
  std::string unit;
  std::vector<CanMuxCondition> multiplexors;  // empty: in every frame of its id
  std::uint32_t id_mask = 0x1FFFFFFF;         // the id's bits a frame must match (J1939: its PGN's)
};

// Throws std::invalid_argument when the signal is malformed: id out of range for its width, length outside
// 1..64, or bits running past the 8-byte frame.
void validate_can_signal(const CanSignal& s);

// Number of payload bytes a frame must carry for the signal and its multiplexors (1..8). Assumes a valid signal.
std::uint32_t can_signal_min_dlc(const CanSignal& s);

// The signal's raw bits, right-aligned (no sign extension). Assumes a valid signal.
std::uint64_t extract_can_raw(const std::uint8_t data[8], std::uint32_t start_bit, std::uint32_t length,
                              CanByteOrder order);

// Whether the frame carries the signal: every multiplexor's value in its ranges. Assumes a valid signal.
bool can_signal_present(const CanSignal& s, const std::uint8_t data[8]);

// Physical value: raw (sign-extended when signed) * factor + offset.
double can_signal_value(const CanSignal& s, const std::uint8_t data[8]);

class CanSignalMap {
 public:
  CanSignalMap() = default;
  explicit CanSignalMap(std::vector<CanSignal> signals);  // validates each; throws std::invalid_argument

  // Applies every signal carried by this frame to op (utime untouched). Signals whose bytes the frame's
  // dlc does not cover are skipped. Returns the number of fields set.
  int decode(const CanFrame& frame, OperatingPoint& op) const;

  const std::vector<CanSignal>& signals() const { return signals_; }

 private:
  std::vector<CanSignal> signals_;
  std::vector<std::uint32_t> min_dlc_;
};

// Reads the [[can.signal]] array of a config root table, each entry laid out by hand:
//   [[can.signal]]
//   field = "speed_rpm"  id = 0x0CF00400  extended = true  start_bit = 24  length = 16
//   byte_order = "intel"  signed = false  factor = 0.125  offset = 0  unit = "rpm"
// Required: field, id, start_bit, length, byte_order. Defaults: extended = false, signed = false, factor = 1,
// offset = 0, unit = "". Or picked by name from the DBC file can.dbc (a path relative to origin's folder):
//   [[can.signal]]
//   field = "load_nm"  dbc_signal = "ActualEnginePercentTorque"  dbc_message = "EEC1"  scale = 25.0  add = 0
// dbc_message only where the name is in several messages; scale and add (default 1 and 0) turn the DBC's
// physical value into the field's unit (a percentage of the reference torque into N m, say).
// Throws std::invalid_argument naming origin, signal index and key ("cfg.toml: can.signal[1].length: ..."); unknown
// keys are errors, and so are layout keys beside dbc_signal. No [can] table gives an empty map.
CanSignalMap parse_can_signal_map(const toml::table& root, const std::string& origin);

const char* to_string(OperatingPointField f);

}  // namespace noisemon::drivers::formats
