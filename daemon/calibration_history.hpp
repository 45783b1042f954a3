// The cell's calibration history: one CSV row per calibration, appended by `noisemon calibrate` (a microphone's,
// or the pressure chain's zero or gain) and read by the daemon, which publishes each microphone's calibration age
// (status counter calibration.mic<N>.age_days). The file sits beside the configuration:
// /etc/noisemon/noisemond.toml -> /etc/noisemon/noisemond.calibrations.csv. Its columns:
//   utc,channel,serial,sensitivity,change_db,level_db,frequency_hz,reference_bar,offset_bar
// channel is the microphone's number or pressure-zero / pressure-gain; a microphone's row leaves the last two empty,
// the pressure chain's the calibrator's two. (Files from before the pressure rows, seven columns, read the same.)
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace noisemon::daemon {

struct CalibrationRecord {
  std::int64_t utime = 0;      // when, us since 1970 (UTC, to the second in the file)
  int microphone = 0;          // 1-based; 0: the pressure chain
  std::string serial;          // no commas
  double sensitivity = 0.0;    // a microphone's mV/Pa; the pressure chain's mV/bar or pC/bar
  double change_db = 0.0;      // from the previous calibration (or the configured value, the first time)
  double level_db = 0.0;       // a microphone's: the calibrator's stated level ...
  double frequency_hz = 0.0;   // ... and the tone's measured frequency
  std::string pressure_step;   // the pressure chain's: "zero" or "gain"
  double reference_bar = 0.0;  // the reference it was given (ambient, or a dead-weight tester's)
  double offset_bar = 0.0;     // the offset written with it
};

std::string calibration_history_path(const std::string& config_path);

// A calibration's date for a message: "2026-05-04 09:30 UTC".
std::string calibration_date(std::int64_t utime);

// Every well-formed row, in the file's order; a missing file has none. Rows that do not parse are counted in
// `skipped` (a hand-edited line), never fatal: the history informs, it does not stop the monitor.
std::vector<CalibrationRecord> read_calibration_history(const std::string& path, std::size_t* skipped = nullptr);

// Appends one row (the header first when the file is new). Throws naming the file when it cannot.
void append_calibration(const std::string& path, const CalibrationRecord& record);

// The latest pressure-chain row of that step ("zero" or "gain") in the history, or nullptr.
const CalibrationRecord* last_pressure_calibration(const std::vector<CalibrationRecord>& history,
                                                   const std::string& step);

// The latest calibration's utime of each of `mic_count` microphones (0: never calibrated).
std::vector<std::int64_t> last_calibrations(const std::vector<CalibrationRecord>& history, std::size_t mic_count);

}  // namespace noisemon::daemon
