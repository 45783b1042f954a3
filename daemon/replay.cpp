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

namespace noisemon::daemon {
namespace {

// Decodes one event's payload; false when it does not decode (a damaged or foreign event).
template <class Message>
bool decode(const lcm::LogEvent& e, Message& m) {
  return m.decode(e.data, 0, e.datalen) == e.datalen;
}

class Progress {
 public:
  Progress(bool enabled, long total_bytes) : enabled_(enabled && isatty(STDERR_FILENO) && total_bytes > 0), total_(total_bytes) {}
  void update(long done_bytes, std::int64_t reports) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    const double f = static_cast<double>(done_bytes) / static_cast<double>(total_);
    const int width = 40, filled = static_cast<int>(f * width);
    std::fprintf(stderr, "\r[%s%s] %5.1f%%  %lld cycles", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), 100 * f, static_cast<long long>(reports));
  }
  void finish() {
    if (enabled_) std::fprintf(stderr, "\n");
  }

 private:
  bool enabled_;
  long total_;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace

ReplaySummary run_replay(const ReplayOptions& o) {
  struct stat st {};
  if (stat(o.log_path.c_str(), &st) != 0) throw std::runtime_error(o.log_path + ": cannot open log file");
  lcm::LogFile log(o.log_path, "r");
  if (!log.good()) throw std::runtime_error(o.log_path + ": cannot open log file");
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
  std::unique_ptr<CycleProcessor> processor;
  std::vector<char> encoded;
  const auto sink = [&](const CycleReport& r) {
    const noisemon::cycle_report_t m = to_message(r);
    if (csv.is_open()) csv << cycle_csv_row(m);
    if (out) {
      encoded.resize(static_cast<std::size_t>(m.getEncodedSize()));
      m.encode(encoded.data(), 0, static_cast<int>(encoded.size()));
      lcm::LogEvent e{0, r.window_end_utime, ch.report_channel, static_cast<std::int32_t>(encoded.size()), encoded.data()};
      out->writeEvent(&e);
    }
    ++sum.reports;
  };
  const auto skip_damaged = [&](const lcm::LogEvent& e) {
    if (sum.skipped_damaged++ < 10)
      spdlog::warn("{}: event {} on {} does not decode as the expected type: skipped", o.log_path, e.eventnum, e.channel);
  };

  Progress progress(o.progress, static_cast<long>(st.st_size));
  std::int64_t first_utime = 0;
  const auto wall_start = std::chrono::steady_clock::now();
  while (const lcm::LogEvent* e = log.readNextEvent()) {
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
      if (!processor) {
        try {
          info = from_message(m);
        } catch (const std::invalid_argument& err) {
          throw std::runtime_error(o.log_path + ": event " + std::to_string(e->eventnum) + ": " + err.what());
        }
        ProcessorConfig pc;
        pc.model = o.config.model;
        pc.acoustic_delay_s = o.config.acoustic_delay_s;
        processor = std::make_unique<CycleProcessor>(pc, *info, sink);
      }
    } else if (e->channel == ch.raw_channel) {
      noisemon::raw_block_t m;
      if (!decode(*e, m)) {
        skip_damaged(*e);
        continue;
      }
      if (!processor)
        throw std::runtime_error(o.log_path + ": event " + std::to_string(e->eventnum) + ": raw block before any " +
                                 ch.session_channel + " message (was the log started with the daemon's channels?)");
      drivers::SampleBlock b;
      try {
        b = from_message(m);
      } catch (const std::invalid_argument& err) {
        skip_damaged(*e);
        continue;
      }
      ++sum.raw_blocks;
      if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE)
        processor->add_pressure(b);
      else if (m.stream == noisemon::raw_block_t::STREAM_MICS)
        processor->add_mics(b);
      else
        skip_damaged(*e);
      processor->process();
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
    progress.update(std::ftell(log.getFilePtr()), sum.reports);
  }
  progress.finish();
  if (!processor) throw std::runtime_error(o.log_path + ": no " + ch.session_channel + " message: nothing to replay");
  sum.cycles_dropped = processor->counters().cycles_dropped;
  return sum;
}

}  // namespace noisemon::daemon
