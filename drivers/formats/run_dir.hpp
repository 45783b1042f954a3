// The run directory: the interchange format of docs/sources-and-formats.md for recordings from other systems.
//
//   run.json      condition (name, speed_rpm, load_nm, soi_deg_btdc, rail_pressure_bar, motored; each may be
//                 null: unknown), pressure {file, units: bar|Pa, noise_floor_bar}, mics {file, units: Pa,
//                 positions_m[M][3], radius_m}
//   pressure.csv  header `time_s,crank_deg,pressure`; one row per encoder sample, crank_deg unwrapped,
//                 0 = firing TDC of the first cycle (cycle k spans [720k - 360, 720k + 360))
//   mics.wav      M-channel IEEE-float WAV in Pa; its t = 0 is pressure.csv's time_s = 0
//
// Reading checks everything a recording from another system can get wrong and throws RunDirError naming the
// file, the position (line, key, channel) and what was expected. Unknown JSON keys are ignored.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace noisemon::drivers::formats {

// A run's operating point. A value that is unknown or not applicable (null in run.json) is NaN, never a
// made-up number: a motored run's SOI (no injection), a load that was not recorded, a speed that is to be
// measured from the encoder (encoder_speed_rpm). Code that needs an unknown value names the run and the key.
struct RunCondition {
  std::string name;                         // e.g. "idle_mi12"
  double speed_rpm = 0.0;                   // NaN: unknown (measured from the encoder where a number is needed)
  double load_nm = 0.0;                     // NaN: unknown
  double soi_deg_btdc = 0.0;                // NaN: unknown or not applicable (motored: no injection)
  std::optional<double> rail_pressure_bar;  // null in run.json when unknown
  bool motored = false;                     // false when unknown (motored_known false): what a message publishes
  bool motored_known = true;                // false: run.json's "motored" is null; ask before using `motored`
};

struct RunDir {
  RunCondition condition;
  // Pressure on the encoder's samples (uneven in time), converted to Pa on reading.
  std::vector<double> time_s;
  std::vector<double> crank_deg;  // unwrapped, strictly increasing
  std::vector<double> pressure_pa;
  // Microphones (absent: mic_count == 0 and the run has no "mics" entry).
  double mic_rate_hz = 0.0;
  std::uint32_t mic_count = 0;
  std::vector<float> mic_pa;  // frame-major: mic_pa[frame * mic_count + mic]
  std::vector<std::array<double, 3>> mic_positions_m;
  double radius_m = 1.75;
  double acoustic_delay_s = -1.0;  // engine-to-microphone delay; < 0: radius_m / 343 m/s
  // The pressure chain's commissioned noise floor, bar rms per encoder sample (run.json
  // "pressure.noise_floor_bar"); nullopt when absent or null: the diagnosis then estimates it from the data.
  std::optional<double> pressure_noise_floor_bar;
  // What the recording carries, when its samples do not say (already on the 40 kHz grid, as export writes them):
  // run.json "pressure.encoder_edges_per_rev" and "mics.passband_hz" (band validity flags; docs: Run directory).
  std::optional<double> pressure_edges_per_rev;
  std::optional<double> mic_passband_hz;
};

// The contents of run.json, checked (what parse_run_json returns).
struct RunManifest {
  RunCondition condition;
  std::string pressure_file;    // relative to the run directory (or absolute)
  double pressure_to_pa = 1e5;  // 1e5 for "bar", 1 for "Pa"
  bool has_mics = false;
  std::string mics_file;
  std::vector<std::array<double, 3>> mic_positions_m;
  double radius_m = 1.75;
  double acoustic_delay_s = -1.0;
  std::optional<double> full_scale_pa;             // PCM WAVs only: the Pa of digital full scale
  std::optional<double> pressure_noise_floor_bar;  // "pressure.noise_floor_bar" (see RunDir)
  std::optional<double> pressure_edges_per_rev;    // "pressure.encoder_edges_per_rev" (see RunDir)
  std::optional<double> mic_passband_hz;           // "mics.passband_hz" (see RunDir)
};

struct RunDirError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Reads DIR/run.json and the files it names (paths relative to DIR). The pressure file is mapped, not copied,
// and the WAV is read on a second thread meanwhile; errors come as from a reading one file after the other
// (the pressure file's first).
RunDir read_run_dir(const std::filesystem::path& dir);

// DIR/run.json alone, checked (a background run needs only its microphones).
RunManifest read_run_manifest(const std::filesystem::path& dir);

// The pieces of read_run_dir, callable on bytes (`file` is the name used in messages):
RunManifest parse_run_json(std::string_view text, const std::string& file);
// The run.json text write_run_dir writes for run (pressure in pressure_units).
std::string run_json_text(const RunDir& run, const std::string& pressure_units);
// Fills run.time_s, crank_deg, pressure_pa (pressure column times to_pa). Over 1 MiB of plain rows (three numbers,
// no blanks or '+') is parsed in two halves on two threads; anything else is read line by line. The numbers
// and every error (its line) are those of the line-by-line reading.
void parse_pressure_csv(std::string_view text, const std::string& file, double to_pa, RunDir& run);
// Fills run.mic_rate_hz, mic_count, mic_pa. The WAV must hold `channels` channels of IEEE float (or PCM when
// full_scale_pa is given: PCM full scale = that many Pa) at a rate of at least 40 kHz that resamples to 40 kHz.
void read_mics_wav(const std::filesystem::path& file, std::uint32_t channels, std::optional<double> full_scale_pa,
                   RunDir& run);
void parse_mics_wav(const std::uint8_t* data, std::size_t size, const std::string& file, std::uint32_t channels,
                    std::optional<double> full_scale_pa, RunDir& run);

// The run's mean speed from its encoder samples: crank angle travelled over the time it took (first to last
// row), rpm; NaN with fewer than two samples.
double encoder_speed_rpm(const RunDir& run);

// The encoder step of an increasing crank angle: the median of the steps between consecutive values (the step
// of rank (n - 1) / 2 among the n - 1 steps, as std::nth_element gives it); NaN with fewer than two values.
double crank_step_deg(const std::vector<double>& crank_deg);

// Encoder steps a crank-angle gap may span (larger gaps are an error; smaller ones are filled by
// interpolation when the run is resampled to 40 kHz).
inline constexpr double kMaxCrankGapSteps = 4.0;
// Largest relative difference between the pressure rows' mean speed and run.json's condition.speed_rpm (when
// it is known).
inline constexpr double kSpeedTolerance = 0.25;
// Writes DIR/run.json, DIR/pressure.csv (pressure in `pressure_units`, "bar" or "Pa") and, when the run has
// microphones, DIR/mics.wav (32-bit float). Unknown condition values (NaN, motored_known false) are written as
// null, pressure.noise_floor_bar only when known. Creates DIR; throws RunDirError naming the file on failure.
void write_run_dir(const std::filesystem::path& dir, const RunDir& run, const std::string& pressure_units = "bar");

}  // namespace noisemon::drivers::formats
