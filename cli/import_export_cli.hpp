// The `noisemon import` and `noisemon export` subcommands (CLI11): options, checks and the summary printed
// on stderr. Kept out of noisemon_main.cpp so that file stays a list of subcommands.
#pragma once

#include <string>
#include <vector>

#include "cli/import_export.hpp"

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace noisemon::cli {

class ImportExportCommands {
 public:
  explicit ImportExportCommands(CLI::App& app);
  // After app.parse(): runs import or export if one was given and returns its exit status; -1 otherwise.
  // Errors are printed (naming the file) and give status 1.
  int run();

 private:
  void add_import(CLI::App& app);
  void add_table_options(CLI::Option* table);
  void add_export(CLI::App& app);
  int import_command();
  int export_command();

  CLI::App* import_ = nullptr;
  CLI::App* export_ = nullptr;
  ImportOptions dirs_;
  CycleTableImportOptions table_;
  std::string mics_;
  std::string pegging_ = "auto";
  double rail_bar_ = -1;
  double loss_angle_deg_ = 0.7;  // model::kDefaultLossAngleDeg, for --motored-table or --motored-run
  ExportOptions export_options_;
};

}  // namespace noisemon::cli
