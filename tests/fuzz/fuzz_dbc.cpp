// libFuzzer target: the DBC reader (parse_dbc) and the signal it hands the CAN map (DbcFile::can_signal). A text
// the reader accepts must give, for every signal it holds, either a CanSignal the map validates and decodes or a
// clear std::invalid_argument; a text it rejects must be rejected with a std::runtime_error naming file and line.
#include <cstdint>
#include <stdexcept>
#include <string>

#include "drivers/formats/dbc.hpp"

using namespace noisemon::drivers::formats;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  DbcFile file;
  try {
    file = parse_dbc(text, "fuzz.dbc");
  } catch (const std::runtime_error& e) {
    if (std::string(e.what()).rfind("fuzz.dbc:", 0) != 0) __builtin_trap();  // must say where
    return 0;
  }
  const std::uint8_t payload[8] = {0xA5, 0x5A, 0xFF, 0x00, 0x81, 0x7E, 0x01, 0x80};
  for (const DbcMessage& m : file.messages) {
    for (const DbcSignal& s : m.signals) {
      CanSignal picked;
      try {
        picked = file.can_signal(s.name, m.name, OperatingPointField::kSpeedRpm);
        validate_can_signal(picked);
      } catch (const std::invalid_argument&) {
        continue;  // a signal the map cannot take (a float, a layout past the frame, a missing multiplexor)
      }
      noisemon::drivers::OperatingPoint op;
      CanFrame frame{picked.id, picked.extended, 8, {}};
      for (int i = 0; i < 8; ++i) frame.data[i] = payload[i];
      (void)CanSignalMap({picked}).decode(frame, op);
    }
  }
  return 0;
}
