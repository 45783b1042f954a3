#include "cli/import_export_cli.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>

namespace noisemon::cli {

ImportExportCommands::ImportExportCommands(CLI::App& app) {
  add_import(app);
  add_export(app);
}

void ImportExportCommands::add_import(CLI::App& app) {
  import_ = app.add_subcommand(
      "import",
      "convert recordings from other systems into a raw LCM log for `noisemon replay`: run directories "
      "(run.json + pressure.csv + mics.wav, see docs/sources-and-formats.md, 'Run directory format') or an indicating "
      "system's cycle table");
  import_->add_option("RUN_DIR", dirs_.run_dirs, "run directories; each becomes one session (run) of the log")
      ->check(CLI::ExistingDirectory);
  import_->add_option("-o,--out", dirs_.out_log, "the LCM log to write (replaced)")->required();
  CLI::Option* table = import_
                           ->add_option("--cycles-table", table_.table,
                                        "a cycle table instead of run directories: first column crank angle "
                                        "(deg), then one column of pressure (bar) per consecutive cycle")
                           ->check(CLI::ExistingFile);
  add_table_options(table);
  import_
      ->add_option("--motored-run", dirs_.motored_run,
                   "a motored run directory of the same engine and encoder: firing TDC is its pressure peak plus "
                   "the loss angle (as `noisemon tdc` finds it), and every run's angles move by it")
      ->check(CLI::ExistingDirectory)
      ->excludes(table);
  import_
      ->add_option("--loss-angle-deg", loss_angle_deg_,
                   "thermodynamic loss angle: how far before TDC the motored peak lies (0 ... 3; measured "
                   "0.4 ... 1.3 on motored engines), with --motored-table or --motored-run")
      ->capture_default_str();
  import_
      ->add_option("--motored-rpm", table_.motored_rpm,
                   "speed of the motored table (default: --rpm); more than 2 % from --rpm is refused")
      ->check(CLI::PositiveNumber)
      ->needs(table);
  import_
      ->add_option("--pegging", pegging_,
                   "first row of each cycle: auto (a pegging value when equal in every cycle), first-row "
                   "(always a pegging value: dropped), none (a sample)")
      ->check(CLI::IsMember({"auto", "first-row", "none"}))
      ->capture_default_str()
      ->needs(table);
  import_->add_option("--mics", mics_,
                      "synthesize the microphones from the imported pressure: \"sim\" (the virtual engine's "
                      "acoustic side, its default ten microphones, linear block)");
  import_->add_option("--epoch-utime", dirs_.epoch_utime,
                      "utime (us since 1970) of the first run's frame 0 (default: now); later runs follow it");
  import_->add_flag("!--no-progress", dirs_.progress, "no progress display");
  import_->footer(
      "Examples:\n"
      "  noisemon import runs/idle_mi12 runs/full_mi18 -o runs.lcmlog\n"
      "  noisemon import --cycles-table yanmar_l100v_fired_18Nm.txt --rpm 1799.9 --load 18 --soi 9.6 -o fired.lcmlog\n"
      "  noisemon import --cycles-table yanmar_l100v_fired_18Nm.txt --motored-table yanmar_l100v_motored.txt \\\n"
      "      --rpm 1799.9 --load 18 --soi 9.6 -o fired.lcmlog\n"
      "  noisemon replay fired.lcmlog --csv fired.csv");
}

// The cycle table's own options (each needs --cycles-table).
void ImportExportCommands::add_table_options(CLI::Option* table) {
  import_
      ->add_option("--rpm", table_.table_options.speed_rpm,
                   "engine speed of the cycle table (required with --cycles-table)")
      ->check(CLI::PositiveNumber)
      ->needs(table);
  import_
      ->add_option("--condition", table_.table_options.condition.name,
                   "condition name (default: the table file's name)")
      ->needs(table);
  import_->add_option("--load", table_.table_options.condition.load_nm, "load, N m")->needs(table);
  import_->add_option("--soi", table_.table_options.condition.soi_deg_btdc, "start of injection, deg before firing TDC")
      ->needs(table);
  import_->add_option("--rail", rail_bar_, "rail pressure, bar (default: unknown)")
      ->check(CLI::NonNegativeNumber)
      ->needs(table);
  import_->add_flag("--motored", table_.table_options.condition.motored, "the engine was motored (no combustion)")
      ->needs(table);
  import_
      ->add_option("--tdc-deg", table_.table_options.tdc_deg,
                   "the table's crank angle of firing TDC (0 when the table runs -180..540; 360 for 0..720)")
      ->capture_default_str()
      ->needs(table);
  import_
      ->add_option("--motored-table", table_.motored_table,
                   "a motored cycle table of the same engine, speed and resolution: firing TDC is set to its "
                   "pressure peak plus the loss angle (thermodynamic TDC), and the fired table's angles move by it")
      ->check(CLI::ExistingFile)
      ->needs(table);
}

void ImportExportCommands::add_export(CLI::App& app) {
  export_ = app.add_subcommand(
      "export", "write the sessions of a raw LCM log as run directories (run.json, pressure.csv, mics.wav)");
  export_->add_option("LOG", export_options_.log, "raw LCM log (noisemond's recording or an import)")
      ->required()
      ->check(CLI::ExistingFile);
  export_
      ->add_option("-o,--out", export_options_.out_dir,
                   "run directory; with several sessions, one subdirectory per session named after its condition")
      ->required();
  export_->add_option("--units", export_options_.pressure_units, "pressure units of pressure.csv")
      ->check(CLI::IsMember({"bar", "Pa"}))
      ->capture_default_str();
  export_->add_flag("--force", export_options_.force, "overwrite existing run directories");
  export_->add_flag("!--no-progress", export_options_.progress, "no progress display");
}

int ImportExportCommands::run() {
  try {
    if (import_->parsed()) return import_command();
    if (export_->parsed()) return export_command();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "noisemon: %s\n", e.what());
    return 1;
  }
  return -1;
}

int ImportExportCommands::import_command() {
  const bool from_table = !table_.table.empty();
  if (from_table == !dirs_.run_dirs.empty()) {
    std::fprintf(stderr, "noisemon import: give run directories or --cycles-table FILE (one of them)\n");
    return 2;
  }
  if (from_table && !(table_.table_options.speed_rpm > 0)) {
    std::fprintf(stderr, "noisemon import: --cycles-table needs --rpm (a cycle table holds no time)\n");
    return 2;
  }
  if (import_->count("--loss-angle-deg") > 0 && table_.motored_table.empty() && dirs_.motored_run.empty()) {
    std::fprintf(stderr, "noisemon import: --loss-angle-deg needs --motored-table or --motored-run\n");
    return 2;
  }
  table_.loss_angle_deg = dirs_.loss_angle_deg = loss_angle_deg_;
  MicSynthesizer synth = mics_.empty() ? MicSynthesizer{} : mic_synthesizer(mics_);
  ImportSummary sum;
  if (from_table) {
    static_cast<ImportCommon&>(table_) = static_cast<const ImportCommon&>(dirs_);
    table_.synthesize_mics = synth;
    table_.table_options.condition.speed_rpm = table_.table_options.speed_rpm;
    if (rail_bar_ >= 0) table_.table_options.condition.rail_pressure_bar = rail_bar_;
    table_.table_options.pegging = pegging_ == "first-row" ? formats::PeggingRow::kFirstRow
                                   : pegging_ == "none"    ? formats::PeggingRow::kNone
                                                           : formats::PeggingRow::kAuto;
    sum = run_import_cycle_table(table_);
  } else {
    dirs_.synthesize_mics = synth;
    sum = run_import(dirs_);
  }
  for (const ImportedRun& r : sum.runs)
    std::fprintf(stderr, "noisemon import: %s -> '%s': %.2f s at 40 kHz, %u microphone(s), epoch %lld\n",
                 r.source.c_str(), r.condition.c_str(), static_cast<double>(r.frames) / 40000.0, r.mics,
                 static_cast<long long>(r.epoch_utime));
  for (const std::string& n : sum.notes) std::fprintf(stderr, "noisemon import: %s\n", n.c_str());
  std::fprintf(stderr, "noisemon import: wrote %s (%zu run(s))\n", dirs_.out_log.c_str(), sum.runs.size());
  return 0;
}

int ImportExportCommands::export_command() {
  const ExportSummary s = run_export(export_options_);
  for (const std::string& d : s.run_dirs) std::fprintf(stderr, "noisemon export: wrote %s\n", d.c_str());
  if (s.stats.damaged > 0) {
    std::fprintf(stderr, "noisemon export: %lld damaged event(s) skipped:\n", static_cast<long long>(s.stats.damaged));
    for (const std::string& d : s.stats.damage) std::fprintf(stderr, "  %s\n", d.c_str());
  }
  if (s.stats.pieces_split > 0)
    std::fprintf(stderr, "noisemon export: samples were missing: %lld session(s) split where they were lost\n",
                 static_cast<long long>(s.stats.pieces_split));
  return 0;
}

}  // namespace noisemon::cli
