#include "daemon/calibration_history.hpp"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace noisemon::daemon {
namespace {

constexpr const char* kHeader =
    "utc,channel,serial,sensitivity,change_db,level_db,frequency_hz,reference_bar,offset_bar";
constexpr const char* kMicrophonesOnlyHeader =
    "utc,microphone,serial,sensitivity_mv_per_pa,change_db,level_db,frequency_hz";  // before the pressure rows
constexpr const char* kPressureChannel = "pressure-";                               // + the step

std::string utc_text(std::int64_t utime, const char* format = "%Y-%m-%dT%H:%M:%SZ") {
  const std::time_t t = static_cast<std::time_t>(utime / 1000000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, format, &tm);
  return text;
}

bool parse_utc(const std::string& text, std::int64_t& utime) {
  std::tm tm{};
  char zone = 0;
  if (std::sscanf(text.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d%c", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
                  &tm.tm_min, &tm.tm_sec, &zone) != 7 ||
      zone != 'Z')
    return false;
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  utime = static_cast<std::int64_t>(timegm(&tm)) * 1000000;
  return true;
}

// The channel's own columns: a microphone's calibrator (5, 6), or the pressure chain's reference and offset (7, 8).
void parse_channel_fields(const std::string (&f)[9], CalibrationRecord& r) {
  if (f[1].starts_with(kPressureChannel)) {
    r.pressure_step = f[1].substr(std::string(kPressureChannel).size());
    if (r.pressure_step != "zero" && r.pressure_step != "gain") throw std::invalid_argument("step");
    r.reference_bar = std::stod(f[7]);
    r.offset_bar = std::stod(f[8]);
    return;
  }
  std::size_t used = 0;
  r.microphone = std::stoi(f[1], &used);
  if (used != f[1].size() || r.microphone < 1) throw std::invalid_argument("microphone");
  r.level_db = std::stod(f[5]);
  r.frequency_hz = std::stod(f[6]);
}

bool parse_row(const std::string& line, CalibrationRecord& r) {
  std::istringstream in(line);
  std::string f[9];
  for (int i = 0; i < 9; ++i)
    if (!std::getline(in, f[i], ',') && i < 7) return false;  // seven columns before the pressure rows
  try {
    r.serial = f[2];
    r.sensitivity = std::stod(f[3]);
    r.change_db = std::stod(f[4]);
    parse_channel_fields(f, r);
  } catch (const std::exception&) {
    return false;
  }
  return parse_utc(f[0], r.utime) && r.sensitivity > 0;
}

}  // namespace

std::string calibration_date(std::int64_t utime) { return utc_text(utime, "%Y-%m-%d %H:%M UTC"); }

std::string calibration_history_path(const std::string& config_path) {
  return std::filesystem::path(config_path).replace_extension(".calibrations.csv").string();
}

std::vector<CalibrationRecord> read_calibration_history(const std::string& path, std::size_t* skipped) {
  std::vector<CalibrationRecord> rows;
  std::ifstream in(path);
  std::string line;
  std::size_t bad = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line == kHeader || line == kMicrophonesOnlyHeader) continue;
    CalibrationRecord r;
    if (parse_row(line, r))
      rows.push_back(r);
    else
      ++bad;
  }
  if (skipped) *skipped = bad;
  return rows;
}

void append_calibration(const std::string& path, const CalibrationRecord& r) {
  if (r.serial.find_first_of(",\n") != std::string::npos)
    throw std::invalid_argument("calibration history: a serial number may not hold a comma or a line break");
  const bool is_new = !std::filesystem::exists(path);
  std::ofstream out(path, std::ios::app);
  if (is_new) out << kHeader << "\n";
  char row[256];
  if (r.microphone == 0)
    std::snprintf(row, sizeof row, "%s,%s%s,%s,%.4f,%.3f,,,%.4f,%.5f\n", utc_text(r.utime).c_str(), kPressureChannel,
                  r.pressure_step.c_str(), r.serial.c_str(), r.sensitivity, r.change_db, r.reference_bar, r.offset_bar);
  else
    std::snprintf(row, sizeof row, "%s,%d,%s,%.4f,%.3f,%.2f,%.2f,,\n", utc_text(r.utime).c_str(), r.microphone,
                  r.serial.c_str(), r.sensitivity, r.change_db, r.level_db, r.frequency_hz);
  out << row;
  out.flush();
  if (!out) throw std::runtime_error("calibration history: cannot append to " + path);
}

const CalibrationRecord* last_pressure_calibration(const std::vector<CalibrationRecord>& history,
                                                   const std::string& step) {
  const CalibrationRecord* last = nullptr;
  for (const CalibrationRecord& r : history)
    if (r.microphone == 0 && r.pressure_step == step && (!last || r.utime >= last->utime)) last = &r;
  return last;
}

std::vector<std::int64_t> last_calibrations(const std::vector<CalibrationRecord>& history, std::size_t mic_count) {
  std::vector<std::int64_t> last(mic_count, 0);
  for (const CalibrationRecord& r : history)
    if (r.microphone >= 1 && static_cast<std::size_t>(r.microphone) <= mic_count)
      last[static_cast<std::size_t>(r.microphone) - 1] =
          std::max(last[static_cast<std::size_t>(r.microphone) - 1], r.utime);
  return last;
}

}  // namespace noisemon::daemon
