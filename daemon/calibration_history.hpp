// The cell's calibration history: one CSV row per microphone calibration, appended by `noisemon calibrate` and read
// by the daemon, which publishes each microphone's calibration age (status counter calibration.mic<N>.age_days).
// The file sits beside the configuration: /etc/noisemon/noisemond.toml -> /etc/noisemon/noisemond.calibrations.csv.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace noisemon::daemon {

struct CalibrationRecord {
  std::int64_t utime = 0;  // when, us since 1970 (UTC, to the second in the file)
  int microphone = 0;      // 1-based
  std::string serial;      // no commas
  double sensitivity_mv_per_pa = 0.0;
  double change_db = 0.0;  // from the previous calibration (or the configured value, the first time)
  double level_db = 0.0;   // the calibrator's stated level
  double frequency_hz = 0.0;
};

std::string calibration_history_path(const std::string& config_path);

// Every well-formed row, in the file's order; a missing file has none. Rows that do not parse are counted in
// `skipped` (a hand-edited line), never fatal: the history informs, it does not stop the monitor.
std::vector<CalibrationRecord> read_calibration_history(const std::string& path, std::size_t* skipped = nullptr);

// Appends one row (the header first when the file is new). Throws naming the file when it cannot.
void append_calibration(const std::string& path, const CalibrationRecord& record);

// The latest calibration's utime of each of `mic_count` microphones (0: never calibrated).
std::vector<std::int64_t> last_calibrations(const std::vector<CalibrationRecord>& history, std::size_t mic_count);

}  // namespace noisemon::daemon
