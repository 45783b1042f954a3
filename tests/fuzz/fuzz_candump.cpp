// libFuzzer target: the candump log parser (parse_candump_line) and the skip-and-count file reader
// (CandumpReader). Accepted lines must survive a round trip through the candump text format; rejected lines
// must say which line; the reader must agree line by line with the parser.
#include <cinttypes>
#include <cstdio>
#include <string>
#include <vector>

#include "drivers/formats/candump.hpp"
#include "fuzz_util.hpp"

using noisemon::drivers::formats::CandumpRecord;

namespace {

// The record written back in candump's `(sec.usec) iface ID#DATA` form.
std::string format_candump(const CandumpRecord& r) {
  char head[64];
  std::snprintf(head, sizeof head, "(%" PRId64 ".%06" PRId64 ") ", r.utime / 1000000, r.utime % 1000000);
  char id[16];
  std::snprintf(id, sizeof id, r.frame.extended ? "%08" PRIX32 "#" : "%03" PRIX32 "#", r.frame.id);
  std::string line = head + r.interface + " " + id;
  if (r.remote) {
    line += 'R';
    if (r.frame.dlc > 0) line += static_cast<char>('0' + r.frame.dlc);
  } else {
    for (int i = 0; i < r.frame.dlc; ++i) {
      char byte[3];
      std::snprintf(byte, sizeof byte, "%02X", r.frame.data[i]);
      line += byte;
    }
  }
  return line;
}

bool same(const CandumpRecord& a, const CandumpRecord& b) {
  if (a.utime != b.utime || a.interface != b.interface || a.remote != b.remote || a.frame.id != b.frame.id ||
      a.frame.extended != b.frame.extended || a.frame.dlc != b.frame.dlc)
    return false;
  for (int i = 0; i < a.frame.dlc && !a.remote; ++i)
    if (a.frame.data[i] != b.frame.data[i]) return false;
  return true;
}

void check_accepted(const CandumpRecord& r) {
  if (r.frame.dlc > 8) noisemon::fuzz::fail("dlc above 8");
  if (r.frame.id > (r.frame.extended ? 0x1FFFFFFFU : 0x7FFU)) noisemon::fuzz::fail("id out of range");
  if (r.utime < 0) noisemon::fuzz::fail("negative timestamp");
  if (r.interface.empty()) noisemon::fuzz::fail("empty interface");
  CandumpRecord again;
  std::string error;
  if (!noisemon::drivers::formats::parse_candump_line(format_candump(r), 1, again, error) || !same(r, again))
    noisemon::fuzz::fail("accepted record does not survive a round trip through the candump format");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);

  // The parser, line by line as std::getline splits them.
  std::vector<CandumpRecord> expected;
  std::size_t bad = 0, line_number = 0;
  for (std::size_t start = 0; start < text.size();) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(start, end - start);
    start = end + 1;
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    CandumpRecord r;
    std::string error;
    if (noisemon::drivers::formats::parse_candump_line(line, line_number, r, error)) {
      check_accepted(r);
      expected.push_back(std::move(r));
    } else {
      noisemon::fuzz::require_names(error, "line " + std::to_string(line_number) + ": ");
      ++bad;
    }
  }

  // The reader on the same bytes as a file.
  const auto path = noisemon::fuzz::scratch_dir() / "input.candump";
  noisemon::fuzz::write_file(path, data, size);
  noisemon::drivers::formats::CandumpReader reader(path.string());
  CandumpRecord r;
  std::size_t good = 0;
  while (reader.next(r)) {
    if (good >= expected.size() || !same(r, expected[good])) noisemon::fuzz::fail("reader and parser disagree");
    ++good;
  }
  if (good != expected.size() || reader.bad_lines() != bad) noisemon::fuzz::fail("reader miscounts lines");
  return 0;
}
