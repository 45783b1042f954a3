#include "cli/gapwatch_command.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>

#include "cli/cli_support.hpp"
#include "cli/gapwatch_io.hpp"
#include "cli/lcm_loop.hpp"
#include "daemon/config.hpp"
#include "daemon/replay.hpp"
#include "drivers/formats/lcm_log_reader.hpp"
#include "drivers/formats/stream_messages.hpp"

namespace noisemon::cli {
namespace {

namespace fs = std::filesystem;

// Feeds a log's cycle reports (and its sessions' encoder, for transducer_noise in bar) in order. A log without
// reports but with the raw streams is replayed through the daemon's pipeline first (what `noisemon replay` does).
// Returns the reports read.
std::int64_t read_log(const std::string& path, const daemon::Config& config, bool progress,
                      const std::function<void(const noisemon::session_t&)>& on_session,
                      const std::function<void(const noisemon::cycle_report_t&)>& on_report) {
  std::int64_t reports = 0, raw = 0;
  {
    drivers::formats::LcmLogReader reader(path);
    ProgressLine line(progress);
    drivers::formats::LcmLogEvent e;
    noisemon::cycle_report_t report;
    noisemon::session_t session;
    for (std::int64_t n = 0; reader.next(e); ++n) {
      if (e.channel == config.lcm.report_channel) {
        if (report.decode(e.data, 0, e.datalen) != e.datalen) continue;  // damaged: left out (counted by the reader)
        on_report(report);
        ++reports;
      } else if (e.channel == config.lcm.session_channel &&
                 drivers::formats::decode_message(e.data, static_cast<std::size_t>(e.datalen), session)) {
        on_session(session);
      } else if (e.channel == config.lcm.raw_channel) {
        ++raw;
      }
      if (n % 4096 == 0)
        line.show("gapwatch " + path + ": " +
                  std::to_string(100 * reader.position() / std::max<std::size_t>(reader.size(), 1)) + " %");
    }
  }
  if (reports > 0 || raw == 0) return reports;
  daemon::ReplayOptions replay;
  replay.log_path = path;
  replay.config = config;
  replay.progress = progress;
  replay.on_report = [&](const noisemon::cycle_report_t& r, const std::string&) {
    on_report(r);
    ++reports;
  };
  daemon::run_replay(replay);
  return reports;
}

std::string event_line(const model::diagnosis::GapEvent& e) {
  char head[256];
  std::snprintf(head, sizeof head, "gap event at %.1f s (cycle %lld; %s from %.1f s, cycle %lld): %s", e.detected_s,
                static_cast<long long>(e.detected_cycle), e.kind.c_str(), e.onset_s,
                static_cast<long long>(e.onset_cycle), e.effect.c_str());
  std::string line = head;
  for (const auto& [key, value] : e.params) {
    char p[64];
    std::snprintf(p, sizeof p, " %s=%.4g", key.c_str(), value);
    line += p;
  }
  char tail[200];
  std::snprintf(tail, sizeof tail, ", confidence %.2f; gap %.2f -> %.2f dB", e.confidence, e.gap_before_db,
                e.gap_after_db);
  if (e.kind == "drift")
    std::snprintf(tail + std::strlen(tail), sizeof tail - std::strlen(tail), "; drifting %+.3f dB/min",
                  e.drift_db_per_min);
  return line + tail + "\n  " + e.attribution.explanation;
}

}  // namespace

GapwatchCommand::GapwatchCommand(CLI::App& app) {
  gapwatch_ = app.add_subcommand("gapwatch",
                                 "watch the sim-to-real gap live (or over a log): detect a change as it happens, "
                                 "locate its onset, name its cause");
  auto* g = gapwatch_;
  g->add_option("--lcm", lcm_url_, "LCM URL (default: the configuration's, else LCM's default udpm URL)");
  g->add_option(
       "--log", log_,
       "read the cycle reports of this LCM log instead of the bus (a log of raw streams only is replayed first)")
      ->check(CLI::ExistingFile);
  g->add_option("--json", json_, "append one JSON object per event to this file (JSON lines)");
  g->add_option(
       "--reference", reference_,
       "start from this reference: a file --save-reference wrote, or an LCM log whose cycles are all reference")
      ->check(CLI::ExistingFile);
  g->add_option("--save-reference", save_reference_,
                "write the reference learnt (every operating point's) to this JSON file at the end");
  g->add_option("--config", config_path_,
                "noisemond TOML configuration: channel names, the cell, the model (the cubic candidates)")
      ->check(CLI::ExistingFile);
  g->add_option("--cell", cell_, "test cell id: the channels suffixed _ID");
  g->add_flag("--publish", publish_, "with --log: publish the events on LCM too (live: always)");
  g->add_option("--reference-s", options_.reference_s, "engine seconds that make an operating point's reference")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  g->add_option("--false-alarm-hours", options_.false_alarm_hours,
                "mean engine hours between false alarms, over every feature")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  g->add_option("--min-shift-db", options_.min_shift_db,
                "smallest shift of a band, microphone or the overall gap to detect, dB")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  g->add_option("--block-cycles", options_.block_cycles, "cycles averaged per observation")
      ->capture_default_str()
      ->check(CLI::Range(2, 1000));
  g->add_option("--after-blocks", options_.after_blocks, "blocks gathered after an alarm before the attribution")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  g->add_option("--encoder-step-deg", encoder_step_deg_,
                "the encoder's step when no session message says it (transducer_noise in bar)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  g->add_flag("!--no-progress", progress_, "no progress line");
  g->footer(
      "\nExamples:\n  noisemon gapwatch                                   # live, beside noisemond\n"
      "  noisemon gapwatch --reference clean.lcmlog --save-reference cell3.json\n"
      "  noisemon gapwatch --log run.lcmlog --json events.jsonl\n");
}

namespace {

// The reference a log's every cycle makes (each operating point's, however long it ran).
model::diagnosis::GapReference learn_reference(const std::string& path, const daemon::Config& config,
                                               model::diagnosis::GapWatchOptions options, bool progress) {
  options.reference_s = 1e12;
  model::diagnosis::GapWatch learner(options);
  const std::int64_t reports = read_log(
      path, config, progress, [](const auto&) {},
      [&](const noisemon::cycle_report_t& r) { learner.add(cycle_gap(r)); });
  learner.finish_learning();
  if (reports == 0)
    throw std::runtime_error(path + ": no cycle reports (channel " + config.lcm.report_channel +
                             ") and no raw streams");
  return learner.reference();
}

void write_json_file(const std::string& path, const nlohmann::json& j) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write");
  out << j.dump(1) << "\n";
  if (!out) throw std::runtime_error(path + ": write failed");
}

}  // namespace

int GapwatchCommand::run() {
  if (!gapwatch_->parsed()) return -1;
  return exit_status_of("gapwatch", [&] {
    daemon::Config config = config_path_.empty() ? daemon::Config{} : daemon::load_config(config_path_);
    if (gapwatch_->count("--cell") > 0) daemon::set_cell(config.lcm, cell_);
    if (gapwatch_->count("--lcm") > 0) config.lcm.url = lcm_url_;
    options_.attribution.model_block = config.model;
    options_.pressure_edge_rate_per_rev = 360.0 / encoder_step_deg_;
    model::diagnosis::GapWatch watch(options_);
    if (!reference_.empty()) {
      watch.set_reference(fs::path(reference_).extension() == ".json"
                              ? load_reference(reference_)
                              : learn_reference(reference_, config, options_, progress_));
      std::fprintf(stderr, "noisemon gapwatch: reference %s: %zu operating points\n", reference_.c_str(),
                   watch.reference().points.size());
    }
    std::ofstream json;
    if (!json_.empty()) {
      json.open(json_, std::ios::app);
      if (!json) throw std::runtime_error(json_ + ": cannot open for writing");
    }
    const bool live = log_.empty();
    std::unique_ptr<lcm::LCM> lcm;
    if (live || publish_) {
      lcm = std::make_unique<lcm::LCM>(config.lcm.url);
      if (!lcm->good()) throw std::runtime_error(lcm_open_error(config.lcm.url));
    }
    std::int64_t utime = 0, events = 0;
    watch.on_event = [&](const model::diagnosis::GapEvent& e) {
      ++events;
      std::printf("%s\n", event_line(e).c_str());
      std::fflush(stdout);
      if (json.is_open()) json << gap_event_json(e).dump() << "\n" << std::flush;
      if (lcm) {
        const noisemon::gap_event_t m = gap_event_message(e, utime);
        lcm->publish(config.lcm.gap_event_channel, &m);
      }
    };
    std::int64_t status_utime = 0;
    auto on_report = [&](const noisemon::cycle_report_t& r) {
      utime = r.utime;
      watch.add(cycle_gap(r));
      if (lcm && utime - status_utime >= 1000000) {  // once a second on the reports' clock
        status_utime = utime;
        const noisemon::gap_status_t m = gap_status_message(watch, utime, static_cast<std::int32_t>(events));
        lcm->publish(config.lcm.gap_status_channel, &m);
      }
    };
    auto on_session = [&](const noisemon::session_t& s) {
      if (s.pressure_edges_per_rev > 0.0) watch.set_pressure_edges_per_rev(s.pressure_edges_per_rev);
    };
    if (live) {
      LcmHandler<noisemon::cycle_report_t> reports{on_report};
      LcmHandler<noisemon::session_t> sessions{on_session};
      lcm->subscribe(config.lcm.report_channel, &LcmHandler<noisemon::cycle_report_t>::on, &reports);
      lcm->subscribe(config.lcm.session_channel, &LcmHandler<noisemon::session_t>::on, &sessions);
      std::fprintf(stderr, "noisemon gapwatch: watching %s, events on %s\n", config.lcm.report_channel.c_str(),
                   config.lcm.gap_event_channel.c_str());
      handle_until_signal(*lcm);
    } else {
      const std::int64_t reports = read_log(log_, config, progress_, on_session, on_report);
      if (reports == 0)
        throw std::runtime_error(log_ + ": no cycle reports (channel " + config.lcm.report_channel +
                                 ") and no raw streams");
    }
    watch.flush();  // the last cycles, waiting to know whether their operating point held
    if (!save_reference_.empty()) write_json_file(save_reference_, reference_json(watch.reference()));
    std::fprintf(stderr,
                 "noisemon gapwatch: %lld cycles (%lld in changes of operating point, not watched), %lld events, %zu "
                 "operating points\n",
                 static_cast<long long>(watch.cycles()), static_cast<long long>(watch.transient_cycles()),
                 static_cast<long long>(events), watch.reference().points.size());
  });
}

}  // namespace noisemon::cli
