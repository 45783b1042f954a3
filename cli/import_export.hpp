// `noisemon import` and `noisemon export`: recordings from other systems into the raw LCM log that
// `noisemon replay`, `noisemond --source lcm` and `noisemon diagnose` read, and back.
//
//   import RUN_DIR...          run directories (docs/sources-and-formats.md, "Run directory format") -> one log, one
//   session per run import --cycles-table F    an indicating system's cycle table (crank angle + one pressure column
//   per cycle) export LOG                 one run directory per session (and per stretch without lost samples)
//
// The conversions themselves live in drivers/ (run_dir, cycle_table, recording); this file sequences them,
// names the epochs, shows progress and collects what to tell the user.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cli/formats/cycle_table.hpp"
#include "cli/formats/recording.hpp"
#include "model/motored_tdc.hpp"

namespace noisemon::cli {

// Fills Recording::mics_pa and the microphone layout of Recording::info from the recording's pressure (and
// operating point): the hook of `--mics sim`, which synthesizes the acoustic side with the virtual engine.
// The recording arrives with its pressure on the 40 kHz grid; the step must leave frames() unchanged.
using MicSynthesizer = std::function<void(formats::Recording&)>;

// The synthesizer named on the command line: "sim" (cli::synthesize_recording_mics with the default
// SimRunSpec). Throws std::invalid_argument for an unknown name.
MicSynthesizer mic_synthesizer(const std::string& name);

struct ImportCommon {
  std::string out_log;
  std::int64_t epoch_utime = 0;    // epoch of the first run; 0: the wall clock now. Later runs follow it.
  MicSynthesizer synthesize_mics;  // empty: the runs' own microphones (or none)
  bool progress = true;            // on stderr, when it is a terminal
  formats::LogChannels channels;
};

struct ImportOptions : ImportCommon {
  std::vector<std::string> run_dirs;
  // Thermodynamic TDC (model/motored_tdc.hpp): a motored run directory of the same engine and encoder; every run's
  // crank angles move by its TDC (on the encoder's scale: `noisemon tdc`), so the logs are on the piston's angles.
  // Empty: the runs' angles are taken as they are.
  std::string motored_run;
  double loss_angle_deg = 0.7;  // model::kDefaultLossAngleDeg
};

struct CycleTableImportOptions : ImportCommon {
  std::string table;
  formats::CycleTableOptions table_options;  // speed_rpm required; condition name defaults to the file's stem
  // Thermodynamic TDC (model/motored_tdc.hpp): a motored table of the same engine, speed and resolution; its peak
  // plus the loss angle moves table_options.tdc_deg. Empty: the table's scale is taken as it is.
  std::string motored_table;
  double loss_angle_deg = 0.7;  // model::kDefaultLossAngleDeg
  double motored_rpm = 0.0;     // the motored table's speed when it differs from the fired one (0: the same)
};

// A motored cycle table's thermodynamic TDC on its own scale (nominal TDC at nominal_tdc_deg; the pegging row, when
// there is one, left out); errors name the file.
model::MotoredTdc motored_table_tdc(const formats::CycleTable& table, const std::string& file, double nominal_tdc_deg,
                                    double loss_angle_deg);

struct ImportedRun {
  std::string source;  // run directory or table file
  std::string condition;
  std::int64_t epoch_utime = 0;
  std::size_t frames = 0;  // at 40 kHz
  std::uint32_t mics = 0;
};

struct ImportSummary {
  std::vector<ImportedRun> runs;
  std::vector<std::string> notes;        // what the user should know (pegging row dropped, cycles expected, ...)
  std::optional<model::MotoredTdc> tdc;  // a cycle table's thermodynamic TDC, when a motored table was given
};

// Throw (drivers::formats::RunDirError, std::runtime_error) naming the file and what is wrong; the output log is then
// removed rather than left half-written.
ImportSummary run_import(const ImportOptions& options);
ImportSummary run_import_cycle_table(const CycleTableImportOptions& options);

struct ExportOptions {
  std::string log;
  std::string out_dir;
  std::string pressure_units = "bar";
  bool force = false;  // overwrite run directories that already exist
  bool progress = true;
  formats::LogChannels channels;
};

struct ExportSummary {
  std::vector<std::string> run_dirs;
  formats::LogReadStats stats;
};

// One run directory per recording of the log: out_dir itself when there is one; otherwise out_dir/<name>/,
// <name> the condition (characters other than letters, digits, '.', '-', '_' replaced by '_'; "run<i>" when
// empty; "_2", "_3"... appended to repeats). Refuses to overwrite an existing run.json unless force.
ExportSummary run_export(const ExportOptions& options);

}  // namespace noisemon::cli
