#include "drivers/can/can_source.hpp"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <thread>

#include "drivers/can/socketcan_reader.hpp"
#include "drivers/formats/candump.hpp"

namespace noisemon::drivers::can {
namespace {

constexpr int kPollMs = 100;  // how often the threads look at the stop flag

// Tracks which mapped fields have been received, so operating points go out only once all are known.
class OperatingPointAssembler {
 public:
  explicit OperatingPointAssembler(const formats::CanSignalMap& map) : map_(map) {
    for (const formats::CanSignal& s : map.signals()) wanted_ |= bit(s.field);
    op_.rail_pressure_bar = std::numeric_limits<double>::quiet_NaN();
  }
  // True when the frame changed the operating point and it is complete.
  bool decode(const formats::CanFrame& frame, std::int64_t utime) {
    int set = 0;
    for (const formats::CanSignal& s : map_.signals()) {
      if (s.id != frame.id || s.extended != frame.extended || frame.dlc < can_signal_min_dlc(s)) continue;
      seen_ |= bit(s.field);
      ++set;
    }
    if (set == 0) return false;
    map_.decode(frame, op_);
    op_.utime = utime;
    return (seen_ & wanted_) == wanted_;
  }
  const OperatingPoint& op() const { return op_; }

 private:
  static unsigned bit(formats::OperatingPointField f) { return 1u << static_cast<unsigned>(f); }
  const formats::CanSignalMap& map_;
  unsigned wanted_ = 0, seen_ = 0;
  OperatingPoint op_;
};

// What the CAN threads share with the rest of the source.
class CanSourceBase : public OperatingPointSource {
 public:
  CanSourceBase(std::string name, std::string thread_name, formats::CanSignalMap map, const ThreadPolicy& policy)
      : name_(std::move(name)), map_(std::move(map)), policy_(policy), worker_(std::move(thread_name)) {}
  std::string name() const override { return name_; }
  void start(OperatingPointRing& ring) override {
    if (worker_.joinable()) throw std::logic_error(name_ + " source: start() while running; stop() first");
    worker_.start("nm-can", policy_, [this, &ring](const std::atomic<bool>&) { run(ring); });
  }
  void stop() override { worker_.stop(); }
  // Started and not failed: a candump replay that reached its end has delivered what it has.
  bool running() const override {
    const ThreadState s = worker_.state();
    return s == ThreadState::kRunning || s == ThreadState::kStopped;
  }
  std::vector<DriverThreadStatus> thread_status() const override { return {worker_.status()}; }

 protected:
  virtual void run(OperatingPointRing& ring) = 0;
  bool stop_requested() const { return worker_.stop_requested(); }
  // Pushes an operating point; when `wait`, retries while the ring is full (offline replay loses nothing).
  void push(OperatingPointRing& ring, const OperatingPoint& op, bool wait) {
    while (!ring.push(op)) {
      if (!wait || stop_requested()) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    worker_.add_blocks_written();
  }
  static std::int64_t count(const std::atomic<std::uint64_t>& a) {
    return static_cast<std::int64_t>(a.load(std::memory_order_relaxed));
  }

  std::string name_;
  formats::CanSignalMap map_;

 private:
  ThreadPolicy policy_;
  WorkerThread worker_;
};

class SocketCanSource final : public CanSourceBase {
 public:
  SocketCanSource(int fd, bool owns_fd, const formats::CanSignalMap& map, std::string label, const ThreadPolicy& policy)
      : CanSourceBase("socketcan", "socketcan." + label, map, policy),
        fd_(fd),
        owns_fd_(owns_fd),
        label_(std::move(label)) {}
  ~SocketCanSource() override {
    stop();
    if (owns_fd_) ::close(fd_);
  }
  std::vector<DriverCounter> counters() const override {
    return {{"can.data_frames", count(data_frames_)},
            {"can.decoded_frames", count(decoded_)},
            {"can.error_frames", count(error_frames_)},
            {"can.bus_off", count(bus_off_)},
            {"can.controller_problems", count(controller_problems_)},
            {"can.kernel_drops", count(kernel_drops_)},
            {"can.malformed", count(malformed_)}};
  }

 private:
  void run(OperatingPointRing& ring) override {
    SocketCanReader reader(fd_);
    OperatingPointAssembler assembler(map_);
    ReceivedCanFrame rx;
    while (!stop_requested()) {
      CanReadResult r;
      try {
        r = reader.read(kPollMs, rx);
      } catch (const std::exception& e) {
        throw std::runtime_error("CAN interface '" + label_ + "': " + e.what());
      }
      const SocketCanStats& s = reader.stats();
      data_frames_.store(s.data_frames, std::memory_order_relaxed);
      error_frames_.store(s.error_frames, std::memory_order_relaxed);
      bus_off_.store(s.bus_off, std::memory_order_relaxed);
      controller_problems_.store(s.controller_problems, std::memory_order_relaxed);
      kernel_drops_.store(s.kernel_drops, std::memory_order_relaxed);
      malformed_.store(s.malformed, std::memory_order_relaxed);
      if (r == CanReadResult::kClosed) return;  // the peer of a test socket closed
      if (r != CanReadResult::kDataFrame) continue;
      if (assembler.decode(rx.frame, rx.utime)) {
        decoded_.fetch_add(1, std::memory_order_relaxed);
        push(ring, assembler.op(), false);
      }
    }
  }

  int fd_;
  bool owns_fd_;
  std::string label_;
  std::atomic<std::uint64_t> data_frames_{0}, decoded_{0}, error_frames_{0}, bus_off_{0}, controller_problems_{0},
      kernel_drops_{0}, malformed_{0};
};

class CandumpSource final : public CanSourceBase {
 public:
  explicit CandumpSource(const CanSourceConfig& c)
      : CanSourceBase("candump", "candump.replay", c.map, c.thread),
        path_(c.candump_path),
        interface_(c.interface),
        paced_(c.paced),
        reader_(std::make_unique<formats::CandumpReader>(c.candump_path)) {}
  ~CandumpSource() override { stop(); }
  std::vector<DriverCounter> counters() const override {
    return {{"candump.records", count(records_)},
            {"candump.decoded_frames", count(decoded_)},
            {"candump.other_interface", count(other_interface_)},
            {"candump.malformed_lines", count(malformed_)}};
  }

 private:
  void run(OperatingPointRing& ring) override {
    OperatingPointAssembler assembler(map_);
    formats::CandumpRecord rec;
    bool first = true;
    std::int64_t rec0 = 0, wall0 = 0;
    while (!stop_requested() && reader_->next(rec)) {
      records_.fetch_add(1, std::memory_order_relaxed);
      malformed_.store(reader_->bad_lines(), std::memory_order_relaxed);
      if (!interface_.empty() && rec.interface != interface_) {
        other_interface_.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      if (first) {
        rec0 = rec.utime;
        wall0 = wall_utime();
        first = false;
      }
      std::int64_t utime = rec.utime;
      if (paced_) {
        // Re-timed to now: the recording plays as if live, each frame at its recorded offset.
        utime = wall0 + (rec.utime - rec0);
        while (!stop_requested()) {
          const std::int64_t wait = utime - wall_utime();
          if (wait <= 0) break;
          std::this_thread::sleep_for(std::chrono::microseconds(std::min<std::int64_t>(wait, kPollMs * 1000)));
        }
      }
      if (rec.remote) continue;
      if (assembler.decode(rec.frame, utime)) {
        decoded_.fetch_add(1, std::memory_order_relaxed);
        push(ring, assembler.op(), !paced_);
      }
    }
    malformed_.store(reader_->bad_lines(), std::memory_order_relaxed);
  }

  std::string path_, interface_;
  bool paced_;
  std::unique_ptr<formats::CandumpReader> reader_;
  std::atomic<std::uint64_t> records_{0}, decoded_{0}, other_interface_{0}, malformed_{0};
};

}  // namespace

std::unique_ptr<OperatingPointSource> make_can_source(const CanSourceConfig& config) {
  if (config.map.signals().empty())
    throw std::invalid_argument(
        "can: no [[can.signal]] entries: nothing to decode from " +
        (config.candump_path.empty() ? "interface '" + config.interface + "'" : "'" + config.candump_path + "'"));
  if (!config.candump_path.empty()) return std::make_unique<CandumpSource>(config);
  const int fd = open_socketcan(config.interface, config.map);
  return std::make_unique<SocketCanSource>(fd, true, config.map, config.interface, config.thread);
}

std::unique_ptr<OperatingPointSource> make_socketcan_source_on_fd(int fd, const formats::CanSignalMap& map,
                                                                  const std::string& label,
                                                                  const ThreadPolicy& policy) {
  return std::make_unique<SocketCanSource>(fd, false, map, label, policy);
}

}  // namespace noisemon::drivers::can
