#include "cli/formats/waveform_csv.hpp"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "drivers/formats/number_field.hpp"
#include "drivers/formats/text_lines.hpp"

namespace noisemon::cli::formats {
namespace {

enum class Separator { unknown, comma, tab, spaces };

const char* separator_name(Separator s) {
  switch (s) {
    case Separator::comma:
      return "comma";
    case Separator::tab:
      return "tab";
    case Separator::spaces:
      return "spaces";
    default:
      return "unknown";
  }
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

Separator separator_of(std::string_view line) {
  if (line.find(',') != std::string_view::npos) return Separator::comma;
  if (line.find('\t') != std::string_view::npos) return Separator::tab;
  return Separator::spaces;
}

std::vector<std::string_view> split(std::string_view line, Separator sep) {
  std::vector<std::string_view> out;
  if (sep == Separator::spaces) {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
      if (i == line.size()) break;
      const std::size_t start = i;
      while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
      out.push_back(line.substr(start, i - start));
    }
    return out;
  }
  const char c = sep == Separator::comma ? ',' : '\t';
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = line.find(c, start);
    out.push_back(trim(line.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start)));
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return out;
}

}  // namespace

Waveform parse_waveform_csv(std::string_view text, const std::string& file) {
  Waveform w;
  Separator sep = Separator::unknown;
  bool first_content = true;
  drivers::formats::TextLines lines(text);
  for (std::string_view raw; lines.next(raw);) {
    const std::size_t line_no = lines.number();
    const std::string_view line = trim(raw);
    if (line.empty() || line.front() == '#') continue;
    const std::string where = file + ":" + std::to_string(line_no) + ": ";

    const Separator this_sep = separator_of(line);
    const auto fields = split(line, this_sep);
    double u = 0.0, y = 0.0;
    const bool numeric = fields.size() == 2 && drivers::formats::parse_number_field(fields[0], u) &&
                         drivers::formats::parse_number_field(fields[1], y);
    if (first_content) {
      first_content = false;
      if (!numeric && fields.size() == 2) {  // a header such as `u,y`
        w.header = std::string(line);
        continue;
      }
    }
    if (sep == Separator::unknown) sep = this_sep;
    if (this_sep != sep)
      throw WaveformCsvError(where + "separated by " + separator_name(this_sep) + ", but the first data row by " +
                             separator_name(sep));
    if (fields.size() != 2)
      throw WaveformCsvError(where + "expected 2 columns (u, y), found " + std::to_string(fields.size()));
    if (!numeric) {
      const int bad = [&] {
        double dummy;
        return drivers::formats::parse_number_field(fields[0], dummy) ? 1 : 0;
      }();
      throw WaveformCsvError(where + "column " + std::to_string(bad + 1) + (bad == 0 ? " (u)" : " (y)") + ": '" +
                             std::string(fields[static_cast<std::size_t>(bad)]) + "' is not a finite number");
    }
    w.u.push_back(u);
    w.y.push_back(y);
  }
  if (w.u.empty()) throw WaveformCsvError(file + ": no data rows (expected lines of `u,y`)");
  return w;
}

Waveform read_waveform_csv(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw WaveformCsvError(path + ": cannot open waveform file");
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad()) throw WaveformCsvError(path + ": read error");
  return parse_waveform_csv(ss.str(), path);
}

}  // namespace noisemon::cli::formats
