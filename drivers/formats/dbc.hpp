// DBC files, the CAN databases engine controllers ship with: the messages (BO_), their signals (SG_: bit layout,
// byte order, sign, factor, offset, unit, multiplexing), extended multiplexing (SG_MUL_VAL_), floating-point
// signals (SIG_VALTYPE_) and which messages are J1939 parameter groups (the VFrameFormat attribute). Everything else
// in a DBC file (comments, other attributes, value tables, nodes) is skipped.
// A signal picked by name becomes a CanSignal of the operating-point map (can_signal_map.hpp).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "drivers/formats/can_signal_map.hpp"

namespace noisemon::drivers::formats {

struct DbcSignal {
  std::string name;
  std::uint32_t start_bit = 0;  // as the file gives it: Intel the LSB, Motorola the MSB (CanByteOrder's convention)
  std::uint32_t length = 1;
  CanByteOrder byte_order = CanByteOrder::kIntel;
  bool is_signed = false;
  double factor = 1.0, offset = 0.0;
  double minimum = 0.0, maximum = 0.0;
  std::string unit;
  int float_bits = 0;           // 32 or 64 for an IEEE float signal (SIG_VALTYPE_), else 0
  bool multiplexor = false;     // "M" (or "mNM"): its value selects the multiplexed signals
  bool multiplexed = false;     // "mN" (or "mNM")
  std::uint64_t mux_value = 0;  // the N of "mN"
  std::string mux_switch;       // SG_MUL_VAL_: the multiplexor it depends on (empty: the message's "M" signal)
  std::vector<std::pair<std::uint64_t, std::uint64_t>> mux_ranges;  // SG_MUL_VAL_: the values it is present for
  int line = 0;                                                     // where the file declares it, for messages
};

struct DbcMessage {
  std::string name;
  std::uint32_t id = 0;  // without the extended flag
  bool extended = false;
  std::uint32_t dlc = 0;
  bool j1939 = false;  // a J1939 parameter group (the VFrameFormat attribute J1939PG): matched by its PGN
  std::vector<DbcSignal> signals;
  const DbcSignal* signal(const std::string& name) const;
};

struct DbcFile {
  std::filesystem::path path;
  std::vector<DbcMessage> messages;

  // The signal `name` as a CanSignal (its multiplexors' conditions included; a J1939 message's id matched by its
  // PGN alone, whatever the priority and source address, and for PDU1 the destination) setting `field`; message empty:
  // whichever message holds it. Throws std::invalid_argument naming the file when the signal is unknown, in
  // several messages (name one), an IEEE float, or multiplexed by a multiplexor the message does not have.
  CanSignal can_signal(const std::string& name, const std::string& message, OperatingPointField field) const;
};

// The bits of a J1939 29-bit id its parameter group number covers: data page, PDU format and, for PDU2 (format 240
// and above), the group extension; not the priority, the source address or a PDU1 destination. PGN = (id & mask) >> 8.
std::uint32_t j1939_pgn_mask(std::uint32_t id);

// Reads a DBC file. Throws std::runtime_error naming the file when it cannot be read, and file:line for a
// BO_, SG_, SG_MUL_VAL_ or SIG_VALTYPE_ statement it cannot parse.
DbcFile read_dbc(const std::filesystem::path& path);

// The same from text (origin names it in errors).
DbcFile parse_dbc(const std::string& text, const std::string& origin);

}  // namespace noisemon::drivers::formats
