#include "cli/calibrate_command.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "cli/config_edit.hpp"
#include "cli/pressure_calibration.hpp"
#include "cli/source_capture.hpp"
#include "daemon/calibration_history.hpp"
#include "daemon/config.hpp"
#include "dsp/calibrator_tone.hpp"
#include "dsp/levels.hpp"

namespace noisemon::cli {
namespace {

constexpr double kFrequencyTolerance = 0.01;  // IEC 60942 class 1: the tone within 1 % of its stated frequency
constexpr double kMaxFluctuationDb = 0.2;     // its level steady within +-0.1 dB over the measurement
constexpr double kMinToneShareDb = -1.0;      // the tone at least 80 % of the signal's power: the calibrator is on
constexpr double kWarnChangeDb = 0.5;
constexpr double kSettleS = 0.5;  // the source's start: resamplers filling, the first blocks

// Where the microphones' sensitivities are written: the front-end they come from.
std::string mic_table(const daemon::Config& c) {
  if (c.microphones == "alsa") return "alsa";
  if (c.source == "comedi") return "comedi.mics";
  throw std::invalid_argument("calibrate: the microphones come from " + c.source +
                              " (the virtual engine or the bus): calibrate on the front-end they are wired to "
                              "([daemon] microphones = \"alsa\" or source = \"comedi\")");
}
std::vector<double>& sensitivities(daemon::Config& c) {
  return c.microphones == "alsa" ? c.alsa.sensitivity_mv_per_pa : c.comedi.mics.sensitivity_mv_per_pa;
}
const std::vector<double>& sensitivities(const daemon::Config& c) {
  return c.microphones == "alsa" ? c.alsa.sensitivity_mv_per_pa : c.comedi.mics.sensitivity_mv_per_pa;
}

// --mic N names one of the `count` microphones (0-based `mic`), checked before anything is captured.
void require_microphone(std::size_t mic, std::size_t count) {
  if (mic >= count)
    throw std::invalid_argument("calibrate: --mic " + std::to_string(mic + 1) + ", but the configuration has " +
                                std::to_string(count) + " microphones");
}

// `seconds` of microphone `mic` (0-based) at 40 kHz, after the source's start has settled.
std::vector<double> record_microphone(const daemon::Config& config, std::size_t mic, double seconds) {
  CapturedStreams streams = capture_streams(config, seconds, kSettleS);
  require_microphone(mic, streams.mics.size());
  if (streams.mic_gaps > 0)
    std::fprintf(stderr, "calibrate: %zu gaps in the stream (overruns); measured after the last\n", streams.mic_gaps);
  return std::move(streams.mics[mic]);
}

// The tone must be the calibrator's: at its frequency, steady, and most of what the microphone hears.
void check_tone(const dsp::ToneMeasurement& t, double freq_hz, int mic) {
  const double share_db = 20.0 * std::log10(t.rms / t.total_rms);
  char what[256];
  if (!(share_db >= kMinToneShareDb)) {
    std::snprintf(what, sizeof what,
                  "no calibrator tone near %.0f Hz on microphone %d: the tone carries %.0f %% of the signal's power "
                  "(is the calibrator seated on it, and switched on?)",
                  freq_hz, mic, 100.0 * std::pow(10.0, share_db / 10.0));
    throw std::runtime_error(what);
  }
  if (std::abs(t.frequency_hz - freq_hz) > kFrequencyTolerance * freq_hz) {
    std::snprintf(what, sizeof what, "the tone is at %.1f Hz, not within 1 %% of %.0f Hz (check --freq)",
                  t.frequency_hz, freq_hz);
    throw std::runtime_error(what);
  }
  if (t.fluctuation_db > kMaxFluctuationDb) {
    std::snprintf(what, sizeof what,
                  "the tone's level moved %.2f dB during the measurement (more than +-0.1 dB): hold the calibrator "
                  "still, seated fully, and measure again",
                  t.fluctuation_db);
    throw std::runtime_error(what);
  }
}

std::string array_text(const std::vector<double>& values) {
  std::ostringstream s;
  s << "[";
  for (std::size_t i = 0; i < values.size(); ++i) s << (i ? ", " : "") << std::round(values[i] * 1000.0) / 1000.0;
  s << "]";
  return s.str();
}

// The sensitivity of the microphone's last calibration in the history (and when); 0 when it has none.
double last_calibration(const std::string& history, int mic, std::int64_t& when) {
  double last = 0;
  for (const daemon::CalibrationRecord& r : daemon::read_calibration_history(history))
    if (r.microphone == mic && r.utime >= when) last = r.sensitivity, when = r.utime;
  return last;
}

}  // namespace

CalibrateCommand::CalibrateCommand(CLI::App& app) {
  calibrate_ = app.add_subcommand(
      "calibrate",
      "with a sound calibrator on one microphone (--mic): check its tone, derive the microphone's sensitivity and "
      "write it into the configuration file; or, with the engine stopped, the cylinder-pressure chain's zero or gain "
      "against a known pressure (--pressure); and append the calibration to the cell's history");
  calibrate_
      ->add_option("--config", config_path_, "the daemon's configuration file (the calibrated value is rewritten)")
      ->required()
      ->check(CLI::ExistingFile);
  CLI::Option* mic = calibrate_->add_option("--mic", mic_, "the microphone the calibrator is on (1 = the first)")
                         ->check(CLI::PositiveNumber);
  CLI::Option* pressure = calibrate_->add_flag(
      "--pressure", pressure_,
      "the pressure chain instead, engine stopped and the reading steady: its zero, [comedi.pressure] offset_bar = "
      "old + (reading - reference), with the transducer at ambient (a voltage-output chain only: a charge "
      "amplifier drifts, peg it instead); or with --gain its sensitivity");
  CLI::Option* reference =
      calibrate_
          ->add_option("--reference-bar", reference_bar_,
                       "--pressure: the pressure the transducer is at, bar absolute (ambient from a barometer; "
                       "with --gain a dead-weight tester's or a reference transducer's, at least 5 bar)")
          ->check(CLI::Range(0.0, 1000.0));
  CLI::Option* gain = calibrate_->add_flag(
      "--gain", gain_,
      "--pressure: the gain, after a zero: the sensitivity scaled by (reading - zero) / (reference - zero), the zero "
      "the latest in the history, and offset_bar rescaled so the zero holds");
  mic->excludes(pressure);
  pressure->needs(reference);
  reference->needs(pressure);
  gain->needs(pressure);
  calibrate_->add_option("--level", level_db_, "the calibrator's stated sound pressure level, dB re 20 uPa")
      ->capture_default_str()
      ->check(CLI::Range(40.0, 160.0));
  calibrate_->add_option("--freq", freq_hz_, "the calibrator's stated frequency, Hz")
      ->capture_default_str()
      ->check(CLI::Range(20.0, 16000.0));
  calibrate_->add_option("--seconds", seconds_, "how long to measure")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 60.0));
  calibrate_->add_option("--serial", serial_,
                         "the microphone's (or the pressure transducer's) serial number, for the history");
  calibrate_->add_option("--history", history_path_,
                         "the calibration history (CSV; default: <config>.calibrations.csv beside the file)");
  calibrate_->add_flag("--dry-run", dry_run_, "measure and report, but write nothing");
}

int CalibrateCommand::run() {
  if (!calibrate_->parsed()) return -1;
  if (pressure_)
    return calibrate_pressure({.config_path = config_path_,
                               .history_path = history_path_,
                               .serial = serial_,
                               .reference_bar = reference_bar_,
                               .gain = gain_,
                               .seconds = seconds_,
                               .dry_run = dry_run_});
  if (mic_ == 0)
    throw std::invalid_argument("calibrate: give --mic N (a microphone) or --pressure (the pressure chain)");
  return run_microphone();
}

int CalibrateCommand::run_microphone() {
  daemon::Config config = daemon::load_config(config_path_);
  const std::string table = mic_table(config);
  const auto index = static_cast<std::size_t>(mic_ - 1);
  require_microphone(index, sensitivities(config).size());
  std::fprintf(stderr, "calibrate: measuring microphone %d for %.0f s (%s)\n", mic_, seconds_, table.c_str());
  const std::vector<double> pa = record_microphone(config, index, seconds_);
  const dsp::ToneMeasurement tone = dsp::measure_tone(pa, drivers::kPipelineRateHz, freq_hz_);
  check_tone(tone, freq_hz_, mic_);

  std::vector<double>& s = sensitivities(config);
  const double old_mv_per_pa = s.at(index);
  const double true_rms = std::sqrt(dsp::mean_square_from_level(level_db_));
  const double new_mv_per_pa = old_mv_per_pa * tone.rms / true_rms;  // the same volts, now the stated pressure
  const std::string history = history_path_.empty() ? config.calibration_history : history_path_;
  std::int64_t last_utime = 0;
  const double last = last_calibration(history, mic_, last_utime);
  const std::string last_when = last > 0 ? daemon::calibration_date(last_utime) : "";
  const double reference = last > 0 ? last : old_mv_per_pa;
  const double change_db = 20.0 * std::log10(new_mv_per_pa / reference);
  std::printf(
      "microphone %d: tone %.2f Hz, %.2f dB re 20 uPa with the configured %.3f mV/Pa (steady within %.2f "
      "dB)\nsensitivity %.3f mV/Pa (%+.2f dB from %s; a class 1 calibrator's +-0.4 dB is its uncertainty)\n",
      mic_, tone.frequency_hz, dsp::level_db(tone.rms * tone.rms), old_mv_per_pa, tone.fluctuation_db, new_mv_per_pa,
      change_db, last > 0 ? ("the last calibration, " + last_when).c_str() : "the configuration");
  if (std::abs(change_db) > kWarnChangeDb)
    std::fprintf(stderr,
                 "calibrate: warning: microphone %d's sensitivity moved %+.2f dB since %s: check the capsule, its "
                 "cable and the preamplifier's gain before trusting it\n",
                 mic_, change_db, last > 0 ? last_when.c_str() : "the configured value");
  if (dry_run_) return 0;

  s[index] = new_mv_per_pa;
  edit_config_file(config_path_, {{table, "sensitivity_mv_per_pa", array_text(s)}}, [&](const daemon::Config& c) {
    return std::abs(sensitivities(c).at(index) - new_mv_per_pa) <= 1e-3;
  });
  daemon::CalibrationRecord row;
  row.utime = drivers::wall_utime();
  row.microphone = mic_;
  row.serial = serial_;
  row.sensitivity = new_mv_per_pa;
  row.change_db = change_db;
  row.level_db = level_db_;
  row.frequency_hz = tone.frequency_hz;
  daemon::append_calibration(history, row);
  std::printf("written: %s ([%s] sensitivity_mv_per_pa), %s\n", config_path_.c_str(), table.c_str(), history.c_str());
  return 0;
}

}  // namespace noisemon::cli
