#include "cli/formats/cycle_table.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "drivers/formats/number_field.hpp"
#include "drivers/formats/text_lines.hpp"

namespace noisemon::cli::formats {
namespace {

bool is_blank(char c) { return c == ' ' || c == '\t'; }

// Splits a line into fields. A line with tabs or semicolons is separated by them (and by blanks, with tabs) and a
// ',' inside a field is a decimal comma (*decimal_comma is set): the spreadsheet exports of comma-decimal
// locales. Otherwise blanks and commas separate ("-180.0, 0.969, 0.97"). Fields are trimmed of blanks.
void split(std::string_view line, std::vector<std::string_view>& fields, bool* decimal_comma) {
  fields.clear();
  const bool semicolons = line.find(';') != std::string_view::npos;
  const bool tabs = !semicolons && line.find('\t') != std::string_view::npos;
  *decimal_comma = semicolons || tabs;
  if (semicolons) {
    std::size_t i = 0;
    while (i <= line.size()) {
      std::size_t j = line.find(';', i);
      if (j == std::string_view::npos) j = line.size();
      std::string_view f = line.substr(i, j - i);
      while (!f.empty() && is_blank(f.front())) f.remove_prefix(1);
      while (!f.empty() && is_blank(f.back())) f.remove_suffix(1);
      if (!(f.empty() && j == line.size())) fields.push_back(f);  // a trailing ';' adds no field
      i = j + 1;
    }
    return;
  }
  const auto is_sep = [&](char c) { return is_blank(c) || (!tabs && c == ','); };
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_sep(line[i])) ++i;
    if (i == line.size()) break;
    std::size_t j = i;
    while (j < line.size() && !is_sep(line[j])) ++j;
    fields.push_back(line.substr(i, j - i));
    i = j;
  }
}

// Header lines (column names, units, a title) allowed before the first row of numbers.
constexpr std::size_t kMaxHeaderLines = 20;

// Beyond any engine: a crank angle this large is a corrupted file, and a pressure this large would overflow
// (or silently lose its meaning) once converted to Pa.
constexpr double kMaxAbsCrankDeg = 1e6;
constexpr double kMaxAbsPressureBar = 1e5;

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

CycleTable read_cycle_table(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in)
    throw drivers::formats::RunDirError(file.string() + ": cannot open cycle table (" + std::strerror(errno) + ")");
  std::ostringstream s;
  s << in.rdbuf();
  return parse_cycle_table(s.str(), file.string());
}

CycleTable parse_cycle_table(std::string_view text, const std::string& file) {
  CycleTable t;
  std::vector<std::string_view> fields;
  std::size_t columns = 0;  // including the crank column
  std::size_t line_no = 0, blank_line = 0;
  std::size_t header_lines = 0;
  const auto at = [&](std::size_t line) { return file + ": line " + std::to_string(line) + ": "; };
  drivers::formats::TextLines lines(text);
  for (std::string_view line; lines.next(line);) {
    line_no = lines.number();
    bool decimal_comma = false;
    split(line, fields, &decimal_comma);
    if (fields.empty() || (fields.size() == 1 && fields[0].empty())) {
      if (blank_line == 0 && columns > 0) blank_line = line_no;
      continue;
    }
    if (!fields[0].empty() && fields[0].front() == '#') continue;
    if (blank_line != 0) throw drivers::formats::RunDirError(at(blank_line) + "empty line inside the table");
    double crank;
    if (!drivers::formats::parse_number_field(fields[0], crank, decimal_comma)) {
      if (columns == 0 && header_lines < kMaxHeaderLines) {  // header lines: names, units, a title
        ++header_lines;
        continue;
      }
      throw drivers::formats::RunDirError(at(line_no) + "column 1 (crank angle) is \"" + std::string(fields[0]) +
                                          "\", expected a number");
    }
    if (std::abs(crank) > kMaxAbsCrankDeg)
      throw drivers::formats::RunDirError(at(line_no) + "crank angle " + fmt(crank) +
                                          " deg, expected a crank angle within +-" + fmt(kMaxAbsCrankDeg) + " deg");
    if (columns == 0) {
      columns = fields.size();
      if (columns < 2)
        throw drivers::formats::RunDirError(
            at(line_no) + "1 column, expected the crank angle followed by one pressure column per cycle");
      t.cycles_bar.assign(columns - 1, {});
      t.first_data_line = line_no;
    } else if (fields.size() != columns) {
      throw drivers::formats::RunDirError(at(line_no) + std::to_string(fields.size()) + " columns, expected " +
                                          std::to_string(columns) + " like line " + std::to_string(t.first_data_line));
    }
    if (!t.crank_deg.empty() && !(crank > t.crank_deg.back()))
      throw drivers::formats::RunDirError(at(line_no) + "crank angle " + fmt(crank) +
                                          " does not increase (previous row " + fmt(t.crank_deg.back()) + ")");
    t.crank_deg.push_back(crank);
    for (std::size_t c = 1; c < columns; ++c) {
      double p;
      if (!drivers::formats::parse_number_field(fields[c], p, decimal_comma) || std::abs(p) > kMaxAbsPressureBar)
        throw drivers::formats::RunDirError(at(line_no) + "column " + std::to_string(c + 1) + " is \"" +
                                            std::string(fields[c]) + "\", expected a pressure in bar (within +-" +
                                            fmt(kMaxAbsPressureBar) + ")");
      t.cycles_bar[c - 1].push_back(p);
    }
  }
  const std::size_t n = t.crank_deg.size();
  if (n < 8)
    throw drivers::formats::RunDirError(file + ": " + std::to_string(n) +
                                        " rows of data, expected a table over one 720-degree cycle");
  // A uniform step over exactly one four-stroke cycle: the columns then join end to end.
  const double step = (t.crank_deg.back() - t.crank_deg.front()) / static_cast<double>(n - 1);
  for (std::size_t i = 1; i < n; ++i) {
    const double d = t.crank_deg[i] - t.crank_deg[i - 1];
    if (std::abs(d - step) > 0.01 * step)
      throw drivers::formats::RunDirError(at(t.first_data_line + i) + "crank angle " + fmt(t.crank_deg[i]) + " after " +
                                          fmt(t.crank_deg[i - 1]) + ", expected a uniform step of " + fmt(step) +
                                          " deg (line numbers count data rows from line " +
                                          std::to_string(t.first_data_line) + ")");
  }
  const double span = step * static_cast<double>(n);
  if (std::abs(span - 720.0) > 0.5 * step)
    throw drivers::formats::RunDirError(file + ": the crank column covers " + fmt(span) + " deg (" + std::to_string(n) +
                                        " rows of " + fmt(step) +
                                        " deg), expected 720 deg: one four-stroke cycle per column");
  return t;
}

bool drops_pegging_row(const CycleTable& table, PeggingRow pegging) {
  if (pegging != PeggingRow::kAuto || table.cycles_bar.size() < 2) return pegging == PeggingRow::kFirstRow;
  for (const auto& c : table.cycles_bar)
    if (c.front() != table.cycles_bar.front().front()) return false;
  return true;
}

CycleTableConversion cycle_table_to_run(const CycleTable& table, const CycleTableOptions& o, const std::string& file) {
  if (!(o.speed_rpm > 0) || !std::isfinite(o.speed_rpm))
    throw drivers::formats::RunDirError(file +
                                        ": the engine speed must be given (rpm > 0): a cycle table holds no time");
  const std::size_t rows = table.crank_deg.size(), cycles = table.cycles_bar.size();
  if (rows < 2 || cycles == 0) throw drivers::formats::RunDirError(file + ": empty cycle table");
  CycleTableConversion out;
  out.cycles = cycles;
  const bool drop = drops_pegging_row(table, o.pegging);
  out.pegging_row_dropped = drop;
  drivers::formats::RunDir& run = out.run;
  run.condition = o.condition;
  run.condition.speed_rpm = o.speed_rpm;
  const std::size_t first_row = drop ? 1 : 0;
  const std::size_t per_cycle = rows - first_row;
  run.time_s.reserve(per_cycle * cycles);
  run.crank_deg.reserve(per_cycle * cycles);
  run.pressure_pa.reserve(per_cycle * cycles);
  // Each column is one recorded cycle with its own pegging offset: it becomes the pipeline's cycle j, [720 j - 360,
  // 720 j + 360) about its firing TDC, whole. The part of the column past +360 (the next intake, same recording) is
  // rotated to the front, so the seams between recordings fall on the cycle boundaries (gas-exchange TDC, where
  // dV/dtheta = 0 and no window of a cycle crosses them), never inside a cycle.
  std::vector<std::size_t> order(per_cycle);
  for (std::size_t i = 0; i < per_cycle; ++i) order[i] = first_row + i;
  const auto wrapped = [&](std::size_t r) {
    const double a = table.crank_deg[r] - o.tdc_deg;
    return a >= 360.0 ? a - 720.0 : a < -360.0 ? a + 720.0 : a;
  };
  std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return wrapped(x) < wrapped(y); });
  const double theta0 = wrapped(order.front());
  const double deg_per_s = 6.0 * o.speed_rpm;
  for (std::size_t j = 0; j < cycles; ++j) {
    for (std::size_t r : order) {
      const double theta = 720.0 * static_cast<double>(j) + wrapped(r);
      run.crank_deg.push_back(theta);
      run.time_s.push_back((theta - theta0) / deg_per_s);
      run.pressure_pa.push_back(table.cycles_bar[j][r] * 1e5);
    }
  }
  return out;
}

}  // namespace noisemon::cli::formats
