#include "daemon/replay.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "daemon/csv_publisher.hpp"
#include "daemon/cycle_processor.hpp"
#include "daemon/log_publisher.hpp"
#include "daemon/pipeline.hpp"
#include "daemon/report_messages.hpp"
#include "drivers/log/log_source.hpp"

namespace noisemon::daemon {
namespace {

constexpr double kReplayRingSeconds = 0.05;  // 16 blocks a ring
constexpr std::chrono::milliseconds kProgressInterval{100};

class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO)) {}
  void update(double fraction, std::int64_t reports, bool force = false) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (!force && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    const int width = 40, filled = static_cast<int>(fraction * width);
    std::fprintf(stderr, "\r[%s%s] %5.1f%%  %lld cycles", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), 100 * fraction, static_cast<long long>(reports));
  }
  // The final state (not the last throttled one), then the line ends.
  void finish(double fraction, std::int64_t reports) {
    update(fraction, reports, true);
    if (enabled_) std::fprintf(stderr, "\n");
  }

 private:
  bool enabled_;
  std::chrono::steady_clock::time_point last_{};
};

// The daemon's configuration as replay runs it: every cycle of the log reported, the streams not published (or
// recorded) again,
// the threads scheduled normally (a service configuration's real-time priorities are the test cell's), and short
// rings: the log source waits while they are full, so they only set how far it reads ahead, and a pipeline per run
// costs little to set up.
Config replay_config(Config c) {
  c.cycles = 0;
  c.ring_seconds = kReplayRingSeconds;
  c.lcm.publish_raw = false;
  c.lcm.publish_operating_point = false;
  c.record.enabled = false;
  c.threads = ThreadsConfig{};
  return c;
}

// Where the reports go: the LCM log (only the report channel), the CSV file and the caller's publishers.
std::shared_ptr<FanoutPublisher> open_outputs(const ReplayOptions& o) {
  auto all = std::make_shared<FanoutPublisher>();
  if (!o.out_log.empty())
    all->add(std::make_shared<LogPublisher>(o.out_log, std::vector<std::string>{o.config.lcm.report_channel}));
  if (!o.csv_path.empty()) all->add(std::make_shared<CsvPublisher>(o.csv_path));
  for (const auto& p : o.publishers) all->add(p);
  return all;
}

// One run of the log through the daemon's pipeline, until its source has delivered the whole session.
void replay_session(const ReplayOptions& o, const Config& config, std::unique_ptr<drivers::Source> source,
                    const std::shared_ptr<FanoutPublisher>& outputs, const drivers::log::LogSessions& log,
                    Progress& progress, ReplaySummary& sum) {
  const std::string& condition = log.condition();
  outputs->begin_run(condition);
  PipelineOptions po;
  po.lossless = true;
  po.quiet = true;
  po.fifo_seconds = ProcessorConfig{}.fifo_seconds;  // what replay has always given a stream to run ahead
  if (o.on_report) po.on_report = [&o, condition](const CycleReport& r) { o.on_report(to_message(r), condition); };
  Pipeline pipeline(config, std::move(source), outputs, po);
  pipeline.start();
  while (!pipeline.finished()) {
    progress.update(log.fraction_read(), sum.reports + pipeline.cycles_published());
    log.wait_for_session_end(kProgressInterval);  // at once when the session ends; a failure within the interval
  }
  pipeline.stop();
  if (const std::string why = pipeline.failure(); !why.empty()) throw std::runtime_error(o.log_path + ": " + why);
  sum.reports += pipeline.cycles_published();
  sum.cycles_dropped += pipeline.cycles_dropped();
}

}  // namespace

ReplaySummary run_replay(const ReplayOptions& o) {
  const LcmConfig& ch = o.config.lcm;
  drivers::log::LogSourceConfig lc;
  lc.path = o.log_path;
  lc.channels = {ch.raw_channel, ch.operating_point_channel, ch.session_channel};
  lc.realtime = o.realtime;
  std::int64_t warned = 0;
  lc.on_damaged = [&](const drivers::log::LogDamage& d) {
    if (warned++ < 10) spdlog::warn("{}: event {} on {}: {}: skipped", o.log_path, d.eventnum, d.channel, d.reason);
  };
  drivers::log::LogSessions log(lc);
  const std::shared_ptr<FanoutPublisher> outputs = open_outputs(o);
  const Config config = replay_config(o.config);
  Progress progress(o.progress);
  ReplaySummary sum;
  // A new epoch (or layout, or condition) is a new run and gets a pipeline of its own: the previous run's filter
  // and model states must not leak into it, and its cycle numbers start again at 0.
  while (std::unique_ptr<drivers::Source> source = log.next_session())
    replay_session(o, config, std::move(source), outputs, log, progress, sum);
  progress.finish(log.fraction_read(), sum.reports);
  const drivers::formats::LcmLogReader& framing = log.reader();
  if (framing.damaged() > 0) {
    // Stretches of the file that were no event at all (damaged framing, a log cut short): one each.
    spdlog::warn("{}: {} damaged stretch(es) of {} bytes skipped, the first at byte {}{}", o.log_path,
                 framing.damaged(), framing.damaged_bytes(), framing.first_damage_offset(),
                 framing.truncated() ? " (the log ends inside an event)" : "");
  }
  const drivers::log::LogCounts counts = log.counts();
  if (counts.sessions == 0)
    throw std::runtime_error(o.log_path + ": no " + ch.session_channel + " message: nothing to replay");
  sum.events = counts.events + framing.damaged();
  sum.sessions = counts.sessions;
  sum.raw_blocks = counts.raw_blocks;
  sum.skipped_unknown = counts.other_channels;
  sum.skipped_damaged = counts.damaged + framing.damaged();
  return sum;
}

}  // namespace noisemon::daemon
