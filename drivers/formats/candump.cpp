#include "drivers/formats/candump.hpp"

#include <stdexcept>

namespace noisemon::drivers::formats {
namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool is_space(char c) { return c == ' ' || c == '\t'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

// A cursor over one candump line: each reader below consumes its part or records what it expected instead.
struct LineCursor {
  explicit LineCursor(std::string_view text) : line(text) {}
  std::string_view line;
  std::size_t i = 0;
  std::string error;

  bool at(char c) const { return i < line.size() && line[i] == c; }
  bool fail(std::string what) {
    error = std::move(what);
    return false;
  }
  bool skip_spaces() {  // true when there was at least one
    const std::size_t start = i;
    while (i < line.size() && is_space(line[i])) ++i;
    return i > start;
  }
};

// (seconds.fraction): microseconds since the epoch (finer than 1 us is truncated).
bool read_timestamp(LineCursor& c, std::int64_t& utime) {
  const std::string_view line = c.line;
  if (!c.at('(')) return c.fail("expected '(' opening the timestamp");
  ++c.i;
  std::int64_t seconds = 0;
  std::size_t digits = 0;
  for (; c.i < line.size() && is_digit(line[c.i]); ++c.i, ++digits) {
    if (seconds > (INT64_MAX / 1000000 - 9) / 10) return c.fail("timestamp seconds out of range");
    seconds = seconds * 10 + (line[c.i] - '0');
  }
  if (digits == 0) return c.fail("expected timestamp seconds after '('");
  if (!c.at('.')) return c.fail("expected '.' and fractional seconds in the timestamp");
  ++c.i;
  std::int64_t micros = 0;
  digits = 0;
  for (; c.i < line.size() && is_digit(line[c.i]); ++c.i, ++digits)
    if (digits < 6) micros = micros * 10 + (line[c.i] - '0');
  if (digits == 0) return c.fail("expected fractional seconds after '.' in the timestamp");
  for (std::size_t d = digits; d < 6; ++d) micros *= 10;
  if (!c.at(')')) return c.fail("expected ')' closing the timestamp");
  ++c.i;
  utime = seconds * 1000000 + micros;
  return true;
}

// The interface name between spaces.
bool read_interface(LineCursor& c, std::string_view& iface) {
  if (!c.skip_spaces()) return c.fail("expected a space after the timestamp");
  const std::size_t start = c.i;
  while (c.i < c.line.size() && !is_space(c.line[c.i])) ++c.i;
  if (c.i == start) return c.fail("expected an interface name");
  iface = c.line.substr(start, c.i - start);
  if (!c.skip_spaces()) return c.fail("expected '<id>#<data>' after the interface name");
  return true;
}

// <id>#: 3 hex digits an 11-bit id, 8 a 29-bit (extended) id.
bool read_can_id(LineCursor& c, CanFrame& frame) {
  const std::size_t start = c.i;
  std::uint32_t id = 0;
  while (c.i < c.line.size() && hex_value(c.line[c.i]) >= 0)
    id = (id << 4) | static_cast<std::uint32_t>(hex_value(c.line[c.i++]));
  const std::size_t id_digits = c.i - start;
  if (!c.at('#')) return c.fail("expected a hex CAN id (3 or 8 digits) followed by '#'");
  if (id_digits == 3) {
    frame.extended = false;
    if (id > 0x7FF) return c.fail("expected an 11-bit id (at most 7FF) with 3 hex digits");
  } else if (id_digits == 8) {
    frame.extended = true;
    if (id > 0x1FFFFFFF) return c.fail("expected a 29-bit id (at most 1FFFFFFF) with 8 hex digits");
  } else {
    return c.fail("expected a CAN id of 3 hex digits (11-bit) or 8 hex digits (29-bit), got " +
                  std::to_string(id_digits));
  }
  frame.id = id;
  ++c.i;
  return true;
}

// After '#': R with an optional dlc digit (a remote frame), or up to 8 data bytes as hex pairs ('.' between them).
bool read_payload(LineCursor& c, CandumpRecord& r) {
  const std::string_view line = c.line;
  if (c.at('#')) return c.fail("CAN FD frame ('##') not supported; expected classic CAN data");
  if (c.at('R') || c.at('r')) {
    ++c.i;
    r.remote = true;
    if (c.i < line.size()) {
      const int d = line[c.i] - '0';
      if (d < 0 || d > 8 || c.i + 1 != line.size()) return c.fail("expected nothing or a dlc digit 0..8 after 'R'");
      r.frame.dlc = static_cast<std::uint8_t>(d);
      ++c.i;
    }
    return true;
  }
  std::uint8_t n = 0;
  while (c.i < line.size()) {
    if (line[c.i] == '.' && n > 0) {
      ++c.i;
      continue;
    }
    if (line[c.i] == '_') return c.fail("len8_dlc suffix ('_') not supported; expected at most 8 data bytes");
    if (c.i + 1 >= line.size() || hex_value(line[c.i]) < 0 || hex_value(line[c.i + 1]) < 0)
      return c.fail("expected data as pairs of hex digits after '#'");
    if (n == 8) return c.fail("expected at most 8 data bytes (classic CAN)");
    r.frame.data[n++] = static_cast<std::uint8_t>(hex_value(line[c.i]) << 4 | hex_value(line[c.i + 1]));
    c.i += 2;
  }
  r.frame.dlc = n;
  return true;
}

}  // namespace

bool parse_candump_line(std::string_view line, std::size_t line_number, CandumpRecord& out, std::string& error) {
  while (!line.empty() && (line.back() == '\r' || is_space(line.back()))) line.remove_suffix(1);
  LineCursor c(line);
  c.skip_spaces();
  CandumpRecord r;
  std::string_view iface;
  if (!read_timestamp(c, r.utime) || !read_interface(c, iface) || !read_can_id(c, r.frame) || !read_payload(c, r)) {
    error = "line " + std::to_string(line_number) + ": " + c.error;
    return false;
  }
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

}  // namespace noisemon::drivers::formats
