#include "cli/summary_command.hpp"

#include <CLI/CLI.hpp>

#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <map>

#include <nlohmann/json.hpp>

#include "cli/import_export.hpp"
#include "daemon/cycle_statistics.hpp"
#include "daemon/replay.hpp"
#include "model/block_params.hpp"

namespace noisemon::cli {
namespace {

namespace fs = std::filesystem;

// Runs in order of their first cycle, each with its accumulator.
struct Runs {
  std::vector<std::string> order;
  std::map<std::string, daemon::CycleStatisticsAccumulator> stats;
  void add(const std::string& run, const noisemon::cycle_report_t& r) {
    auto [it, fresh] = stats.try_emplace(run);
    if (fresh) order.push_back(run);
    it->second.add(r);
  }
};

// A raw LCM log as is; a run directory imported into a temporary log first.
void summarize_input(const std::string& input, const daemon::ReplayOptions& base, Runs& runs) {
  daemon::ReplayOptions replay = base;
  replay.log_path = input;
  fs::path temporary;
  if (fs::is_directory(input)) {
    temporary = fs::temp_directory_path() / ("noisemon-summary-" + std::to_string(::getpid()) + ".lcmlog");
    ImportOptions import;
    import.run_dirs = {input};
    import.out_log = temporary.string();
    import.progress = false;
    run_import(import);
    replay.log_path = temporary.string();
  }
  const std::string fallback = fs::path(input).filename().string();
  replay.on_report = [&](const noisemon::cycle_report_t& r, const std::string& condition) {
    runs.add(condition.empty() ? fallback : condition, r);
  };
  try {
    daemon::run_replay(replay);
  } catch (...) {
    if (!temporary.empty()) fs::remove(temporary);
    throw;
  }
  if (!temporary.empty()) fs::remove(temporary);
}

}  // namespace

SummaryCommand::SummaryCommand(CLI::App& app) {
  summary_ = app.add_subcommand("summary",
                                "statistics over the cycles of whole recordings, per run: energy-mean levels, "
                                "Leq(A), mean, std, COV, min and max of every scalar, valid and flagged cycles");
  summary_->add_option("DATA", inputs_, "raw LCM logs (lcm-logger of noisemond's channels) or run directories")
      ->required()
      ->check(CLI::ExistingPath);
  summary_->add_flag("--json", json_, "one JSON object: runs by name, each with its statistics");
  summary_->add_flag("--csv", csv_, "one CSV row per run and quantity");
  summary_->add_option("--config", config_path_, "noisemond TOML configuration for the model and channel names")
      ->check(CLI::ExistingFile);
  summary_->add_option("--model", model_, "model preset for the predicted levels (default: the configuration's)");
  summary_->add_flag("!--no-progress", progress_, "no progress bar");
  summary_->footer(
      "\nExamples:\n  noisemon summary runs/full_mi12 runs/idle_mi12\n  noisemon summary fired.lcmlog --csv > "
      "fired_summary.csv\n");
}

int SummaryCommand::run() {
  if (!summary_->parsed()) return -1;
  if (json_ && csv_) throw CLI::ValidationError("--json and --csv", "choose one");
  daemon::ReplayOptions base;
  if (!config_path_.empty()) base.config = daemon::load_config(config_path_);
  if (!model_.empty()) base.config.model = model::preset(model_);
  base.progress = progress_;
  Runs runs;
  for (const std::string& input : inputs_) summarize_input(input, base, runs);
  if (json_) {
    nlohmann::json all = nlohmann::json::object();
    for (const std::string& run : runs.order)
      all[run] = nlohmann::json::parse(daemon::statistics_json(runs.stats.at(run).result()));
    std::cout << all.dump(1) << "\n";
  } else if (csv_) {
    std::cout << daemon::statistics_csv_header();
    for (const std::string& run : runs.order)
      std::cout << daemon::statistics_csv_rows(runs.stats.at(run).result(), run);
  } else {
    for (const std::string& run : runs.order)
      std::cout << run << ": " << daemon::statistics_text(runs.stats.at(run).result()) << "\n";
  }
  if (runs.order.empty()) {
    std::cerr << "noisemon summary: no complete cycle in the data\n";
    return 1;
  }
  return 0;
}

}  // namespace noisemon::cli
