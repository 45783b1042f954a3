#include "cli/replay_command.hpp"

#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>

#include "cli/hdf5_publisher.hpp"
#include "daemon/config.hpp"
#include "model/block_params.hpp"

namespace noisemon::cli {
namespace {

namespace fs = std::filesystem;

// The output directories of a multi-log replay, with their option names and file extensions.
struct OutputDir {
  const char* option;
  const std::string& dir;
  const char* extension;
};

std::vector<OutputDir> output_dirs(const MultiReplayOptions& m) {
  std::vector<OutputDir> out;
  for (const OutputDir& o : {OutputDir{"--out", m.out_dir, ".lcmlog"}, OutputDir{"--csv", m.csv_dir, ".csv"},
                             OutputDir{"--hdf5", m.hdf5_dir, ".h5"}})
    if (!o.dir.empty()) out.push_back(o);
  return out;
}

std::string output_path(const std::string& dir, const std::string& log, const char* extension) {
  return (fs::path(dir) / (replay_output_name(log) + extension)).string();
}

// What the last line of a replay says about it.
std::string summary_text(const daemon::ReplaySummary& s) {
  char text[400];
  std::snprintf(text, sizeof text,
                "%lld session(s), %lld events, %lld raw blocks, %lld cycles reported, %lld dropped, %lld events of "
                "other channels, %lld damaged events skipped",
                static_cast<long long>(s.sessions), static_cast<long long>(s.events),
                static_cast<long long>(s.raw_blocks), static_cast<long long>(s.reports),
                static_cast<long long>(s.cycles_dropped), static_cast<long long>(s.skipped_unknown),
                static_cast<long long>(s.skipped_damaged));
  return text;
}

// One log of a multi-log replay, with its own outputs; a failure is returned, not thrown.
LogReplayResult replay_one(const MultiReplayOptions& m, const std::string& log) {
  LogReplayResult r;
  r.log = log;
  const auto start = std::chrono::steady_clock::now();
  try {
    daemon::ReplayOptions o = m.base;
    o.log_path = log;
    o.progress = false;  // bars of several logs would overwrite each other: one line per finished log instead
    o.publishers.clear();
    o.on_report = nullptr;
    if (!m.out_dir.empty()) o.out_log = output_path(m.out_dir, log, ".lcmlog");
    if (!m.csv_dir.empty()) o.csv_path = output_path(m.csv_dir, log, ".csv");
    if (!m.hdf5_dir.empty())
      o.publishers.push_back(std::make_shared<Hdf5Publisher>(output_path(m.hdf5_dir, log, ".h5")));
    r.summary = daemon::run_replay(o);
  } catch (const std::exception& e) {  // the outputs are closed here, before the log counts as finished
    r.error = e.what();
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

}  // namespace

std::string replay_output_name(const std::string& log) {
  const fs::path name = fs::path(log).filename();
  return name.extension() == ".lcmlog" ? name.stem().string() : name.string();
}

void check_multi_replay(const MultiReplayOptions& m) {
  if (m.jobs < 1) throw std::invalid_argument("--jobs " + std::to_string(m.jobs) + ": must be at least 1");
  const std::vector<OutputDir> dirs = output_dirs(m);
  const std::string logs = std::to_string(m.logs.size()) + " logs";
  for (const OutputDir& o : dirs)
    if (!fs::is_directory(o.dir))
      throw std::invalid_argument(std::string(o.option) + " " + o.dir + ": with " + logs + ", " + o.option +
                                  " names an existing directory (each log's reports go to DIR/<log name>" +
                                  o.extension + "); '" + o.dir + "' is not one");
  if (dirs.empty()) return;
  std::map<std::string, std::string> names;  // output name -> log
  std::set<fs::path> inputs;
  for (const std::string& log : m.logs) {
    const auto [it, fresh] = names.emplace(replay_output_name(log), log);
    if (!fresh)
      throw std::invalid_argument(it->second + " and " + log + " have the same name '" + it->first +
                                  "': their outputs would replace each other; rename or copy one");
    inputs.insert(fs::weakly_canonical(log));
  }
  for (const OutputDir& o : dirs)
    for (const std::string& log : m.logs)
      if (const std::string out = output_path(o.dir, log, o.extension); inputs.count(fs::weakly_canonical(out)))
        throw std::invalid_argument(std::string(o.option) + " " + o.dir + " would replace the input log " + out +
                                    ": choose another directory");
}

std::vector<LogReplayResult> run_replays(
    const MultiReplayOptions& m, const std::function<void(const LogReplayResult&, std::size_t, std::size_t)>& on_done) {
  check_multi_replay(m);
  // spdlog's registry is built on first use; build it here, before the threads log (a race as ThreadSanitizer
  // sees it: the library's own once-only initialisation is not instrumented).
  spdlog::default_logger_raw();
  const std::size_t n = m.logs.size();
  std::vector<LogReplayResult> results(n);
  std::atomic<std::size_t> next{0};
  std::mutex done_mutex;
  std::size_t done = 0;
  const auto worker = [&] {
    for (std::size_t i; (i = next++) < n;) {
      results[i] = replay_one(m, m.logs[i]);
      const std::lock_guard lock(done_mutex);
      ++done;
      if (on_done) on_done(results[i], done, n);
    }
  };
  {
    std::vector<std::jthread> threads;
    const std::size_t count = std::min(n, static_cast<std::size_t>(m.jobs));
    for (std::size_t t = 0; t < count; ++t) threads.emplace_back(worker);
  }  // joined
  return results;
}

ReplayCommand::ReplayCommand(CLI::App& app) {
  replay_ =
      app.add_subcommand("replay", "run raw LCM logs (lcm-logger of noisemond's channels) through the processing");
  replay_->add_option("LOG", logs_, "LCM logs holding NOISEMON_SESSION, NOISEMON_RAW and NOISEMON_OP (one or more)")
      ->required()
      ->check(CLI::ExistingFile);
  replay_->add_option("--out", out_, "write the cycle reports to this LCM log (several logs: a directory)");
  replay_->add_option("--csv", csv_, "write one CSV row per cycle to this file (several logs: a directory)");
  replay_->add_option("--hdf5", hdf5_,
                      "write the cycle reports to this HDF5 file (h5py, MATLAB; docs/sources-and-formats.md; several "
                      "logs: a directory)");
  replay_->add_option("-j,--jobs", jobs_, "replay up to N of several logs at a time, each in a thread of its own")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  replay_->add_flag("--realtime", options_.realtime,
                    "pace the events at their recorded times (default: as fast as possible)");
  replay_->add_option("--config", config_path_, "noisemond TOML configuration for the model and channel names")
      ->check(CLI::ExistingFile);
  replay_->add_option(
      "--model", model_,
      "model preset, overrides [model] preset (linear, nl_damper, nl_spring_damper, nl_spring_damper_opt)");
  replay_->add_flag("!--no-progress", options_.progress, "no progress bar");
  replay_->footer(
      "\nSeveral logs: --out, --csv and --hdf5 name existing directories; each log's reports go to DIR/<name>.lcmlog,\n"
      "DIR/<name>.csv, DIR/<name>.h5 (<name>: the log's file name less a .lcmlog extension). Logs of the same name,\n"
      "or an output that would replace an input log, are refused. One line per finished log on stderr; a log that\n"
      "fails does not stop the others (exit status 1).\n\n"
      "Examples:\n"
      "  noisemon replay session.lcmlog --csv cycles.csv --out reports.lcmlog\n"
      "  noisemon replay logs/*.lcmlog -j 2 --csv csv/ --hdf5 h5/\n");
}

void ReplayCommand::apply_config() {
  if (!config_path_.empty()) options_.config = daemon::load_config(config_path_);
  if (!model_.empty()) options_.config.model = noisemon::model::preset(model_);
}

int ReplayCommand::run() {
  if (!replay_->parsed()) return -1;
  apply_config();
  return logs_.size() == 1 ? run_one() : run_several();
}

int ReplayCommand::run_one() {
  options_.log_path = logs_.front();
  options_.out_log = out_;
  options_.csv_path = csv_;
  if (!hdf5_.empty()) options_.publishers.push_back(std::make_shared<Hdf5Publisher>(hdf5_));
  const daemon::ReplaySummary s = run_replay(options_);
  std::fprintf(stderr, "noisemon replay: %s\n", summary_text(s).c_str());
  return 0;
}

int ReplayCommand::run_several() {
  MultiReplayOptions m;
  m.logs = logs_;
  m.out_dir = out_;
  m.csv_dir = csv_;
  m.hdf5_dir = hdf5_;
  m.jobs = jobs_;
  m.base = options_;
  const auto start = std::chrono::steady_clock::now();
  const auto print = [](const LogReplayResult& r, std::size_t done, std::size_t total) {
    if (r.error.empty())
      std::fprintf(stderr, "noisemon replay: [%zu/%zu] %s: %s (%.2f s)\n", done, total, r.log.c_str(),
                   summary_text(r.summary).c_str(), r.seconds);
    else
      std::fprintf(stderr, "noisemon replay: [%zu/%zu] %s: failed: %s\n", done, total, r.log.c_str(), r.error.c_str());
  };
  const std::vector<LogReplayResult> results = run_replays(m, print);
  long long reports = 0, dropped = 0, failed = 0;
  for (const LogReplayResult& r : results) {
    reports += r.summary.reports;
    dropped += r.summary.cycles_dropped;
    failed += r.error.empty() ? 0 : 1;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::string failures = failed ? ", " + std::to_string(failed) + " log(s) failed" : "";
  std::fprintf(stderr, "noisemon replay: %zu logs (-j %d) in %.2f s: %lld cycles reported, %lld dropped%s\n",
               results.size(), jobs_, seconds, reports, dropped, failures.c_str());
  return failed ? 1 : 0;
}

}  // namespace noisemon::cli
