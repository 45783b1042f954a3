#include "daemon/replay.hpp"

#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <optional>
#include <thread>

#include "daemon/cycle_processor.hpp"
#include "daemon/report_messages.hpp"
#include "drivers/formats/lcm_log_reader.hpp"

namespace noisemon::daemon {
namespace {

// Decodes one event's payload; false when it does not decode (a damaged or foreign event).
template <class Message>
bool decode(const drivers::LcmLogEvent& e, Message& m) {
  return drivers::decode_message(e.data, static_cast<std::size_t>(e.datalen), m);
}

class Progress {
 public:
  Progress(bool enabled, long total_bytes) : enabled_(enabled && isatty(STDERR_FILENO) && total_bytes > 0), total_(total_bytes) {}
  void update(long done_bytes, std::int64_t reports, bool force = false) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (!force && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    const double f = static_cast<double>(done_bytes) / static_cast<double>(total_);
    const int width = 40, filled = static_cast<int>(f * width);
    std::fprintf(stderr, "\r[%s%s] %5.1f%%  %lld cycles", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), 100 * f, static_cast<long long>(reports));
  }
  // The final state (not the last throttled one), then the line ends.
  void finish(long done_bytes, std::int64_t reports) {
    update(done_bytes, reports, true);
    if (enabled_) std::fprintf(stderr, "\n");
  }

 private:
  bool enabled_;
  long total_;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace

ReplaySummary run_replay(const ReplayOptions& o) {
  drivers::LcmLogReader log(o.log_path);
  std::unique_ptr<lcm::LogFile> out;
  if (!o.out_log.empty()) {
    out = std::make_unique<lcm::LogFile>(o.out_log, "w");
    if (!out->good()) throw std::runtime_error(o.out_log + ": cannot write log file");
  }
  std::ofstream csv;
  if (!o.csv_path.empty()) {
    csv.open(o.csv_path);
    if (!csv) throw std::runtime_error(o.csv_path + ": cannot write CSV file");
    csv << cycle_csv_header();
  }

  const LcmConfig& ch = o.config.lcm;
  ReplaySummary sum;
  std::optional<drivers::StreamInfo> info;
  std::string condition;  // of the current session
  std::unique_ptr<CycleProcessor> processor;
  std::vector<char> encoded;
  const auto sink = [&](const CycleReport& r) {
    const noisemon::cycle_report_t m = to_message(r);
    if (csv.is_open()) csv << cycle_csv_row(m, condition);
    if (o.on_report) o.on_report(m, condition);
    if (out) {
      encoded.resize(static_cast<std::size_t>(m.getEncodedSize()));
      m.encode(encoded.data(), 0, static_cast<int>(encoded.size()));
      lcm::LogEvent e{0, r.window_end_utime, ch.report_channel, static_cast<std::int32_t>(encoded.size()), encoded.data()};
      out->writeEvent(&e);
    }
    ++sum.reports;
  };
  const auto skip_damaged = [&](const drivers::LcmLogEvent& e, const char* why = "does not decode as the expected type") {
    if (sum.skipped_damaged++ < 10)
      spdlog::warn("{}: event {} on {}: {}: skipped", o.log_path, e.eventnum, e.channel, why);
  };
  // A session ends: its last, unfinished cycle is not reported.
  const auto end_session = [&] {
    if (processor) sum.cycles_dropped += processor->counters().cycles_dropped;
    processor.reset();
  };

  Progress progress(o.progress, static_cast<long>(log.size()));
  std::int64_t first_utime = 0;
  const auto wall_start = std::chrono::steady_clock::now();
  drivers::LcmLogEvent event;
  const drivers::LcmLogEvent* e = &event;
  // Reused for every raw block: decoding into a fresh message allocated and zeroed its samples each time.
  noisemon::raw_block_t raw;
  while (log.next(event)) {
    ++sum.events;
    if (o.realtime) {
      if (sum.events == 1) first_utime = e->timestamp;
      std::this_thread::sleep_until(wall_start + std::chrono::microseconds(e->timestamp - first_utime));
    }
    if (e->channel == ch.session_channel) {
      noisemon::session_t m;
      if (!decode(*e, m)) {
        skip_damaged(*e);
        continue;
      }
      drivers::StreamInfo next;
      try {
        next = from_message(m);
      } catch (const std::invalid_argument& err) {
        skip_damaged(*e, err.what());
        continue;
      }
      // The daemon repeats its session message every second; a new epoch (or layout, or condition) is a new run
      // and gets a fresh processor: the previous run's filter and model states must not leak into it.
      const bool same = processor && info && info->epoch_utime == next.epoch_utime &&
                        info->mic_count == next.mic_count && condition == m.condition;
      if (!same) {
        end_session();
        ++sum.sessions;
        info = next;
        condition = m.condition;
        ProcessorConfig pc;
        pc.model = o.config.model;
        pc.acoustic_delay_s = o.config.acoustic_delay_s;
        pc.engine = o.config.engine;
        processor = std::make_unique<CycleProcessor>(pc, *info, sink);
      }
    } else if (e->channel == ch.raw_channel) {
      noisemon::raw_block_t& m = raw;
      if (!decode(*e, m)) {
        skip_damaged(*e);
        continue;
      }
      if (!processor)
        throw std::runtime_error(o.log_path + ": event " + std::to_string(e->eventnum) + ": raw block before any " +
                                 ch.session_channel + " message (was the log started with the daemon's channels?)");
      // A block that contradicts its session or itself is skipped: the processor then sees lost samples and
      // drops the cycles they touch instead of reporting wrong numbers.
      if (const std::string why = drivers::raw_block_problem(m, *info); !why.empty()) {
        skip_damaged(*e, why.c_str());
        continue;
      }
      const drivers::SampleBlock b = from_message(m);
      ++sum.raw_blocks;
      try {
        if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE)
          processor->add_pressure(b);
        else
          processor->add_mics(b);
        processor->process();
      } catch (const std::exception& err) {
        throw std::runtime_error(o.log_path + ": event " + std::to_string(e->eventnum) + ": " + err.what());
      }
    } else if (e->channel == ch.operating_point_channel) {
      noisemon::operating_point_t m;
      if (!decode(*e, m)) {
        skip_damaged(*e);
        continue;
      }
      if (processor) processor->set_operating_point(from_message(m));
    } else {
      ++sum.skipped_unknown;
    }
    progress.update(static_cast<long>(log.position()), sum.reports);
  }
  progress.finish(static_cast<long>(log.position()), sum.reports);
  if (log.damaged() > 0) {
    // Stretches of the file that were no event at all (damaged framing, a log cut short): one each.
    spdlog::warn("{}: {} damaged stretch(es) of {} bytes skipped, the first at byte {}{}", o.log_path, log.damaged(),
                 log.damaged_bytes(), log.first_damage_offset(), log.truncated() ? " (the log ends inside an event)" : "");
    sum.events += log.damaged();
    sum.skipped_damaged += log.damaged();
  }
  if (!processor) throw std::runtime_error(o.log_path + ": no " + ch.session_channel + " message: nothing to replay");
  end_session();
  return sum;
}

}  // namespace noisemon::daemon
