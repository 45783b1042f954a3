#include "drivers/formats/candump.hpp"

#include <stdexcept>

namespace noisemon::drivers {
namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool is_space(char c) { return c == ' ' || c == '\t'; }

}  // namespace

bool parse_candump_line(std::string_view line, std::size_t line_number, CandumpRecord& out, std::string& error) {
  auto fail = [&](const std::string& what) {
    error = "line " + std::to_string(line_number) + ": " + what;
    return false;
  };
  while (!line.empty() && (line.back() == '\r' || is_space(line.back()))) line.remove_suffix(1);
  std::size_t i = 0;
  auto skip_spaces = [&] {
    const std::size_t start = i;
    while (i < line.size() && is_space(line[i])) ++i;
    return i > start;
  };
  skip_spaces();

  // (seconds.fraction)
  if (i >= line.size() || line[i] != '(') return fail("expected '(' opening the timestamp");
  ++i;
  std::int64_t seconds = 0;
  std::size_t digits = 0;
  for (; i < line.size() && line[i] >= '0' && line[i] <= '9'; ++i, ++digits) {
    if (seconds > (INT64_MAX / 1000000 - 9) / 10) return fail("timestamp seconds out of range");
    seconds = seconds * 10 + (line[i] - '0');
  }
  if (digits == 0) return fail("expected timestamp seconds after '('");
  if (i >= line.size() || line[i] != '.') return fail("expected '.' and fractional seconds in the timestamp");
  ++i;
  std::int64_t micros = 0;
  digits = 0;
  for (; i < line.size() && line[i] >= '0' && line[i] <= '9'; ++i, ++digits)
    if (digits < 6) micros = micros * 10 + (line[i] - '0');  // finer than 1 us is truncated
  if (digits == 0) return fail("expected fractional seconds after '.' in the timestamp");
  for (std::size_t d = digits; d < 6; ++d) micros *= 10;
  if (i >= line.size() || line[i] != ')') return fail("expected ')' closing the timestamp");
  ++i;

  // interface
  if (!skip_spaces()) return fail("expected a space after the timestamp");
  const std::size_t if_start = i;
  while (i < line.size() && !is_space(line[i])) ++i;
  if (i == if_start) return fail("expected an interface name");
  std::string_view iface = line.substr(if_start, i - if_start);
  if (!skip_spaces()) return fail("expected '<id>#<data>' after the interface name");

  // <id>#
  const std::size_t id_start = i;
  std::uint32_t id = 0;
  while (i < line.size() && hex_value(line[i]) >= 0) id = (id << 4) | static_cast<std::uint32_t>(hex_value(line[i++]));
  const std::size_t id_digits = i - id_start;
  if (i >= line.size() || line[i] != '#')
    return fail("expected a hex CAN id (3 or 8 digits) followed by '#'");
  bool extended;
  if (id_digits == 3) {
    extended = false;
    if (id > 0x7FF) return fail("expected an 11-bit id (at most 7FF) with 3 hex digits");
  } else if (id_digits == 8) {
    extended = true;
    if (id > 0x1FFFFFFF) return fail("expected a 29-bit id (at most 1FFFFFFF) with 8 hex digits");
  } else {
    return fail("expected a CAN id of 3 hex digits (11-bit) or 8 hex digits (29-bit), got " + std::to_string(id_digits));
  }
  ++i;

  CandumpRecord r;
  r.frame.id = id;
  r.frame.extended = extended;
  if (i < line.size() && line[i] == '#') return fail("CAN FD frame ('##') not supported; expected classic CAN data");
  if (i < line.size() && (line[i] == 'R' || line[i] == 'r')) {
    ++i;
    r.remote = true;
    if (i < line.size()) {
      const int d = line[i] - '0';
      if (d < 0 || d > 8 || i + 1 != line.size()) return fail("expected nothing or a dlc digit 0..8 after 'R'");
      r.frame.dlc = static_cast<std::uint8_t>(d);
      ++i;
    }
  } else {
    std::uint8_t n = 0;
    while (i < line.size()) {
      if (line[i] == '.' && n > 0) { ++i; continue; }
      if (line[i] == '_') return fail("len8_dlc suffix ('_') not supported; expected at most 8 data bytes");
      if (i + 1 >= line.size() || hex_value(line[i]) < 0 || hex_value(line[i + 1]) < 0)
        return fail("expected data as pairs of hex digits after '#'");
      if (n == 8) return fail("expected at most 8 data bytes (classic CAN)");
      r.frame.data[n++] = static_cast<std::uint8_t>(hex_value(line[i]) << 4 | hex_value(line[i + 1]));
      i += 2;
    }
    r.frame.dlc = n;
  }
  r.utime = seconds * 1000000 + micros;
  r.interface.assign(iface);
  out = std::move(r);
  return true;
}

CandumpReader::CandumpReader(const std::string& path) : in_(path) {
  if (!in_) throw std::runtime_error("candump log '" + path + "': cannot open for reading");
}

bool CandumpReader::next(CandumpRecord& out) {
  while (std::getline(in_, line_)) {
    ++line_number_;
    if (line_.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (parse_candump_line(line_, line_number_, out, last_error_)) return true;
    ++bad_lines_;
  }
  return false;
}

}  // namespace noisemon::drivers
