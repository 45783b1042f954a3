#include "drivers/formats/pressure_csv.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <vector>

#include "drivers/formats/number_field.hpp"
#include "drivers/formats/run_both.hpp"
#include "drivers/formats/text_lines.hpp"

namespace noisemon::drivers::formats {
namespace {

std::string quoted(std::string_view s) {
  if (s.size() > 40) return "\"" + std::string(s.substr(0, 40)) + "...\"";
  return "\"" + std::string(s) + "\"";
}

std::string at_line(const std::string& file, std::uint32_t line) {
  return file + ": line " + std::to_string(line) + ": ";
}

// The three numbers of the data row on line line_no.
void parse_csv_row(std::string_view line, const std::string& file, std::uint32_t line_no, double (&v)[3]) {
  std::size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const std::size_t comma = i < 2 ? line.find(',', start) : line.size();
    if (comma == std::string_view::npos)
      throw RunDirError(at_line(file, line_no) + std::to_string(i + 1) +
                        " field(s), expected 3 (time_s,crank_deg,pressure)");
    const std::string_view field = line.substr(start, comma - start);
    if (i == 2 && field.find(',') != std::string_view::npos)
      throw RunDirError(at_line(file, line_no) + "more than 3 fields, expected 3 (time_s,crank_deg,pressure)");
    if (!parse_number_field(field, v[i])) {
      static const char* names[3] = {"time_s", "crank_deg", "pressure"};
      throw RunDirError(at_line(file, line_no) + "field " + names[i] + " is " + quoted(field) +
                        ", expected a finite number");
    }
    start = comma + 1;
  }
}

// Appends a row (pressure converted to Pa) after checking it against the previous one and the plausible range.
// The rules every row meets, shared by the line-by-line reading and the fast path: time and crank angle increase
// from row to row, and the pressure is within +-1e5 bar (beyond any cylinder: a corrupted field, which would also
// overflow once converted to Pa).
bool time_increases(double t, double previous_t) { return t > previous_t; }
bool crank_increases(double crank, double previous_crank) { return crank > previous_crank; }
bool pressure_in_range(double pa) { return std::abs(pa) <= 1e10; }

void append_row(RunDir& run, const double (&v)[3], double to_pa, std::string_view line, const std::string& file,
                std::uint32_t line_no) {
  if (!run.time_s.empty()) {
    if (!time_increases(v[0], run.time_s.back()))
      throw RunDirError(at_line(file, line_no) + "time_s " + std::to_string(v[0]) +
                        " s does not increase (previous row " + std::to_string(run.time_s.back()) +
                        " s): rows out of order or repeated");
    if (!crank_increases(v[1], run.crank_deg.back()))
      throw RunDirError(at_line(file, line_no) + "crank_deg " + std::to_string(v[1]) +
                        " does not increase (previous row " + std::to_string(run.crank_deg.back()) +
                        "): crank_deg must be unwrapped and increasing");
  }
  if (!pressure_in_range(v[2] * to_pa))
    throw RunDirError(at_line(file, line_no) + "field pressure is " + quoted(line.substr(line.rfind(',') + 1)) +
                      ", expected a cylinder pressure within +-1e5 bar");
  run.time_s.push_back(v[0]);
  run.crank_deg.push_back(v[1]);
  run.pressure_pa.push_back(v[2] * to_pa);
}

// Gaps: a crank step far above the encoder's (the median step) means lost samples; so does a sudden change of the
// speed the rows imply (time jumping while the crank does not). Row i is on line i + 2: the header is line 1, and a
// blank line is only allowed after the last row.
void check_crank_gaps(const RunDir& run, const std::string& file) {
  const std::size_t n = run.time_s.size();
  const auto line_of = [](std::size_t row) { return static_cast<std::uint32_t>(row + 2); };
  const double step = crank_step_deg(run.crank_deg);
  double before = 0;  // the previous row's speed
  for (std::size_t i = 1; i < n; ++i) {
    const double d = run.crank_deg[i] - run.crank_deg[i - 1];
    if (d > (kMaxCrankGapSteps + 0.5) * step) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "crank_deg jumps by %.6g deg from %.6g to %.6g (%.1f encoder steps of %.6g deg); at most %.0f "
                    "steps expected (a few missing encoder samples are interpolated, more are lost data)",
                    d, run.crank_deg[i - 1], run.crank_deg[i], d / step, step, kMaxCrankGapSteps);
      throw RunDirError(at_line(file, line_of(i)) + buf);
    }
    const double speed = d / (run.time_s[i] - run.time_s[i - 1]);
    if (i >= 2 && (speed < before / kMaxCrankGapSteps || speed > before * kMaxCrankGapSteps)) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "time_s jumps from %.9g to %.9g s while crank_deg moves %.6g deg: the speed changes %.1f-fold "
                    "from the previous row (at most %.0f-fold expected: lost samples or a time error)",
                    run.time_s[i - 1], run.time_s[i], d, std::max(speed / before, before / speed), kMaxCrankGapSteps);
      throw RunDirError(at_line(file, line_of(i)) + buf);
    }
    before = speed;
  }
}

// The file line by line: every problem is reported at the first line that has one. The fast path below hands
// every file it does not take as it is to this.
void parse_rows_sequential(std::string_view text, const std::string& file, double to_pa, RunDir& run) {
  run.time_s.clear();
  run.crank_deg.clear();
  run.pressure_pa.clear();
  std::uint32_t line_no = 0;
  std::uint32_t blank_line = 0;  // first blank line seen (only trailing blank lines are allowed)
  TextLines lines(text);
  for (std::string_view line; lines.next(line);) {
    line_no = static_cast<std::uint32_t>(lines.number());
    if (line_no == 1) {
      if (line != kPressureCsvHeader)
        throw RunDirError(at_line(file, 1) + "header " + quoted(line) + ", expected \"" + kPressureCsvHeader + "\"");
      continue;
    }
    if (line.find_first_not_of(" \t") == std::string_view::npos) {
      if (blank_line == 0) blank_line = line_no;
      continue;
    }
    if (blank_line != 0) throw RunDirError(at_line(file, blank_line) + "empty line inside the data");
    double v[3];
    parse_csv_row(line, file, line_no, v);
    append_row(run, v, to_pa, line, file, line_no);
  }
  if (line_no == 0)
    throw RunDirError(file + ": empty file, expected the header \"" + kPressureCsvHeader + "\" and rows");
  if (run.time_s.size() < 2)
    throw RunDirError(file + ": " + std::to_string(run.time_s.size()) + " data rows, expected at least 2");
}

// ------------------------------------------------------------------------------------------------ CSV fast path
// Most files are plain: three numbers a line, no blanks, no '+'. Their rows are parsed without per-line work
// beyond the numbers, the two halves of a large file on two threads, each into its own columns. A line that is
// not plain (a problem, or only unusual) makes parse_rows_fast give up: the file is then read sequentially,
// which reports the first problem exactly as it always has. What the fast path accepts, it reads to the same
// numbers as the sequential reading.

constexpr std::size_t kParallelCsvBytes = std::size_t{1} << 20;  // smaller files: one thread
constexpr std::size_t kReleaseBytes = std::size_t{8} << 20;      // mapped pages handed back every this many bytes

struct CsvPart {
  std::string_view text;  // whole lines of the data
  std::vector<double> t, crank, p;
  bool plain = true;       // every line was a plain row, or only blank lines follow the last row
  bool blank_end = false;  // stopped at a blank line (only blank lines follow in this part)

  void reserve(std::size_t rows) {
    for (std::vector<double>* column : {&t, &crank, &p}) {
      column->reserve(rows);
      prefer_huge_pages(*column);
    }
  }
};

// Every line of text blank as the sequential reading sees it (one trailing '\r' dropped, then only ' ' and '\t').
bool only_blank_lines(std::string_view text) {
  TextLines lines(text);
  for (std::string_view line; lines.next(line);)
    if (line.find_first_not_of(" \t") != std::string_view::npos) return false;
  return true;
}

// A plain row at p: "a,b,c" ending at '\n', "\r\n" or the end, each number finite and nothing else in the line.
// Moves p past the line; false (p anywhere) for any other line.
bool plain_row(const char*& p, const char* end, double (&v)[3]) {
  for (int i = 0; i < 3; ++i) {
    const auto [q, ec] = std::from_chars(p, end, v[i]);
    if (ec != std::errc() || !std::isfinite(v[i])) return false;
    p = q;
    if (i < 2) {
      if (p == end || *p != ',') return false;
      ++p;
    }
  }
  if (p != end && *p == '\r') ++p;
  if (p == end) return true;
  if (*p != '\n') return false;
  ++p;
  return true;
}

// The part's rows, checked as append_row checks them; stops at the first line the fast path does not take.
void parse_part(CsvPart& part, double to_pa, const MappedFile* map) {
  const char* p = part.text.data();
  const char* const end = p + part.text.size();
  const char* released = p;
  double v[3];
  while (p < end) {
    const char* const line = p;
    if (!plain_row(p, end, v)) {
      part.blank_end = only_blank_lines(std::string_view(line, static_cast<std::size_t>(end - line)));
      part.plain = part.blank_end;
      return;
    }
    const double pa = v[2] * to_pa;
    const bool follows =
        part.t.empty() || (time_increases(v[0], part.t.back()) && crank_increases(v[1], part.crank.back()));
    if (!follows || !pressure_in_range(pa)) {
      part.plain = false;
      return;
    }
    part.t.push_back(v[0]);
    part.crank.push_back(v[1]);
    part.p.push_back(pa);
    if (map && static_cast<std::size_t>(p - released) >= kReleaseBytes) {
      map->release(released, p);
      released = p;
    }
  }
}

// Rows a stretch of data holds: its length over the shortest mean line length of windows of 64 lines spread
// across it, and a little more (an estimate that falls short costs a reallocation, nothing else).
std::size_t estimated_rows(std::string_view data) {
  double bytes_per_row = 0;
  for (std::size_t w = 0; w < 4; ++w) {
    std::size_t pos = w == 0 ? 0 : data.find('\n', data.size() / 4 * w);
    if (pos == std::string_view::npos) break;
    pos += w == 0 ? 0 : 1;
    const std::size_t start = pos;
    std::size_t lines = 0;
    for (std::size_t nl; lines < 64 && (nl = data.find('\n', pos)) != std::string_view::npos; ++lines) pos = nl + 1;
    const double b = lines > 0 ? static_cast<double>(pos - start) / static_cast<double>(lines) : 0.0;
    if (b > 0 && (bytes_per_row == 0 || b < bytes_per_row)) bytes_per_row = b;
  }
  if (bytes_per_row == 0) return 16;
  return static_cast<std::size_t>(static_cast<double>(data.size()) / bytes_per_row * 1.05) + 64;
}

// Appends b's rows to a's: false when the two do not join into plain rows (b's first row must follow a's last,
// and nothing but blank lines may follow a blank line).
bool join_parts(CsvPart& a, const CsvPart& b) {
  if (!a.plain || !b.plain) return false;
  if (b.t.empty()) return true;
  if (a.blank_end) return false;
  if (!a.t.empty() && !(time_increases(b.t.front(), a.t.back()) && crank_increases(b.crank.front(), a.crank.back())))
    return false;
  a.t.insert(a.t.end(), b.t.begin(), b.t.end());
  a.crank.insert(a.crank.end(), b.crank.begin(), b.crank.end());
  a.p.insert(a.p.end(), b.p.begin(), b.p.end());
  return true;
}

// The fast path (text without its byte-order mark): fills run's columns and returns true when the header is
// right and every line is a plain row or a trailing blank line; false otherwise (run's columns unspecified).
bool parse_rows_fast(std::string_view text, double to_pa, RunDir& run, const MappedFile* map) {
  const std::size_t nl = text.find('\n');
  std::string_view header = text.substr(0, nl);
  if (!header.empty() && header.back() == '\r') header.remove_suffix(1);
  if (nl == std::string_view::npos || header != kPressureCsvHeader) return false;
  const std::string_view data = text.substr(nl + 1);
  CsvPart first, second;
  first.text = data;
  const std::size_t cut = data.size() >= kParallelCsvBytes ? data.find('\n', data.size() / 2) : std::string_view::npos;
  if (cut == std::string_view::npos || cut + 1 >= data.size()) {
    first.reserve(estimated_rows(data));
    parse_part(first, to_pa, map);
  } else {
    first.text = data.substr(0, cut + 1);
    second.text = data.substr(cut + 1);
    run_both(
        [&] {
          first.reserve(estimated_rows(data));  // room for both parts: joining them moves no row twice
          parse_part(first, to_pa, map);
        },
        [&] {
          second.reserve(estimated_rows(second.text));
          parse_part(second, to_pa, map);
        });
  }
  if (!join_parts(first, second) || first.t.size() < 2) return false;
  run.time_s = std::move(first.t);
  run.crank_deg = std::move(first.crank);
  run.pressure_pa = std::move(first.p);
  return true;
}

}  // namespace

void parse_pressure_text(std::string_view text, const std::string& file, double to_pa, RunDir& run,
                         const MappedFile* map) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 byte-order mark
  if (!parse_rows_fast(text, to_pa, run, map)) parse_rows_sequential(text, file, to_pa, run);
  check_crank_gaps(run, file);
}

double crank_step_deg(const std::vector<double>& crank_deg) {
  if (crank_deg.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t n = crank_deg.size() - 1;  // steps
  const std::size_t k = n / 2;
  const auto step = [&crank_deg](std::size_t i) { return crank_deg[i + 1] - crank_deg[i]; };
  // A sorted sample of the steps brackets the median; one pass counts the steps below and within the bracket.
  constexpr std::size_t kSample = 4096, kMargin = 128;  // the median is within +-4 sigma of the sample's
  if (n >= 16 * kSample) {
    std::vector<double> sample(kSample);
    for (std::size_t j = 0; j < kSample; ++j) sample[j] = step(j * n / kSample);
    std::sort(sample.begin(), sample.end());
    const double lo = sample[kSample / 2 - kMargin], hi = sample[kSample / 2 + kMargin];
    std::size_t below = 0, within = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = step(i);
      below += d < lo;
      within += d <= hi;
    }
    within -= below;
    if (below <= k && k < below + within) {
      if (lo == hi) return lo;
      std::vector<double> mid;
      mid.reserve(within);
      for (std::size_t i = 0; i < n; ++i)
        if (const double d = step(i); d >= lo && d <= hi) mid.push_back(d);
      std::nth_element(mid.begin(), mid.begin() + static_cast<std::ptrdiff_t>(k - below), mid.end());
      return mid[k - below];
    }
  }
  std::vector<double> steps(n);  // small, or a bracket that missed: every step
  for (std::size_t i = 0; i < n; ++i) steps[i] = step(i);
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(k), steps.end());
  return steps[k];
}

void parse_pressure_csv(std::string_view text, const std::string& file, double to_pa, RunDir& run) {
  parse_pressure_text(text, file, to_pa, run, nullptr);
}

void write_pressure_csv(const std::filesystem::path& path, const RunDir& run, double from_pa) {
  const std::size_t n = run.time_s.size();
  std::ofstream out(path, std::ios::binary);
  if (!out) throw RunDirError(path.string() + ": cannot write");
  std::string buf;
  buf.reserve(1 << 20);
  buf += kPressureCsvHeader;
  buf += '\n';
  char num[64];
  const auto put = [&](double v, char sep) {  // shortest text that reads back to the same double
    const auto r = std::to_chars(num, num + sizeof num, v);
    buf.append(num, r.ptr);
    buf += sep;
  };
  for (std::size_t i = 0; i < n; ++i) {
    put(run.time_s[i], ',');
    put(run.crank_deg[i], ',');
    put(run.pressure_pa[i] * from_pa, '\n');
    if (buf.size() > (1 << 20) - 256) {
      out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
      buf.clear();
    }
  }
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  if (!out) throw RunDirError(path.string() + ": cannot write");
}

}  // namespace noisemon::drivers::formats
