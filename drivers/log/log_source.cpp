#include "drivers/log/log_source.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace noisemon::drivers::log {

struct LogSessions::State {
  explicit State(LogSourceConfig c)
      : config(std::move(c)), reader(config.path), decoder({config.channels, formats::SessionChanges::kFollow}) {}

  // The next event, counted (and paced when realtime); nullptr at the end of the log, or when *stop turns true
  // while pacing.
  const formats::RawEvent* next(formats::LcmLogEvent& e, const std::atomic<bool>* stop);
  void pace(std::int64_t timestamp, const std::atomic<bool>* stop);

  LogSourceConfig config;
  formats::LcmLogReader reader;
  formats::RawStreamDecoder decoder;
  LogCounts counts;
  bool session_pending = false;  // the decoder holds a session that no source has been made for yet
  std::string condition;
  std::atomic<std::size_t> position{0};
  // The running source has delivered its whole session (LogSessions::wait_for_session_end).
  std::mutex session_end_mutex;
  std::condition_variable session_end;
  bool session_ended = false;
  const std::chrono::steady_clock::time_point wall_start = std::chrono::steady_clock::now();
  std::int64_t first_timestamp = 0;
};

const formats::RawEvent* LogSessions::State::next(formats::LcmLogEvent& e, const std::atomic<bool>* stop) {
  if (!reader.next(e)) return nullptr;
  if (++counts.events == 1) first_timestamp = e.timestamp;
  if (config.realtime) {
    pace(e.timestamp, stop);
    if (stop && stop->load(std::memory_order_relaxed)) return nullptr;
  }
  const formats::RawEvent& ev = decoder.decode(e.channel, e.data, static_cast<std::size_t>(e.datalen));
  position.store(reader.position(), std::memory_order_relaxed);
  switch (ev.kind) {
    case formats::RawEventKind::kSession:
      if (ev.session_started) ++counts.sessions;
      break;
    case formats::RawEventKind::kDamaged:
    case formats::RawEventKind::kBadBlock:
    case formats::RawEventKind::kOtherSessionBlock:
      ++counts.damaged;
      if (config.on_damaged) config.on_damaged({e.eventnum, e.channel, ev.reason});
      break;
    case formats::RawEventKind::kOtherChannel:
      ++counts.other_channels;
      break;
    default:
      break;
  }
  return &ev;
}

void LogSessions::State::pace(std::int64_t timestamp, const std::atomic<bool>* stop) {
  const auto due = wall_start + std::chrono::microseconds(timestamp - first_timestamp);
  constexpr auto kLookAtStop = std::chrono::milliseconds(50);
  while (std::chrono::steady_clock::now() < due) {
    if (stop && stop->load(std::memory_order_relaxed)) return;
    std::this_thread::sleep_until(std::min(due, std::chrono::steady_clock::now() + kLookAtStop));
  }
}

namespace {

// Two operating points the reports cannot tell apart: the same values (unknown ones included), whatever their time.
bool same_values(const OperatingPoint& a, const OperatingPoint& b) {
  const auto same = [](double x, double y) { return x == y || (std::isnan(x) && std::isnan(y)); };
  return same(a.speed_rpm, b.speed_rpm) && same(a.load_nm, b.load_nm) && same(a.soi_deg_btdc, b.soi_deg_btdc) &&
         same(a.rail_pressure_bar, b.rail_pressure_bar) && a.motored == b.motored;
}

// Waits until `done` holds, looking every `interval`; false when a stop was requested first.
template <class Condition>
bool wait_until(const std::atomic<bool>& stop, std::chrono::microseconds interval, Condition done) {
  while (!done()) {
    if (stop.load(std::memory_order_relaxed)) return false;
    std::this_thread::sleep_for(interval);
  }
  return true;
}

// A full ring has a block's processing time to go before it has room: no haste (fewer wake-ups, more CPU for the
// processing). The processing takes an operating point within its next round: looked at more often.
constexpr std::chrono::microseconds kRoomInterval{250}, kTakenInterval{50};

template <class Item>
bool push_waiting(dsp::SpscRing<Item>& ring, const Item& item, const std::atomic<bool>& stop) {
  if (!wait_until(stop, kRoomInterval, [&] { return ring.size() < ring.capacity(); })) return false;
  return ring.push(item);  // the only producer: the room is still there
}

class LogSource final : public Source {
 public:
  explicit LogSource(std::shared_ptr<LogSessions::State> state)
      : state_(std::move(state)), info_(state_->decoder.info()), policy_(state_->config.thread) {}
  ~LogSource() override { stop(); }

  std::string name() const override { return "log"; }
  StreamInfo info() const override { return info_; }
  void start(const Streams& streams) override {
    if (!streams.pressure || !streams.mics || !streams.operating_point)
      throw std::invalid_argument("log source: start() needs the pressure, microphone and operating-point rings");
    worker_.start("nm-log-in", policy_, [this, streams](const std::atomic<bool>& stop) { run(streams, stop); });
  }
  void stop() override { worker_.stop(); }
  bool running() const override { return exhausted() || worker_.blocks_written() > 0; }
  bool exhausted() const override { return exhausted_.load(); }
  std::vector<DriverThreadStatus> thread_status() const override { return {worker_.status()}; }
  std::vector<DriverCounter> counters() const override {
    return {{"log.blocks", static_cast<std::int64_t>(worker_.blocks_written())}};
  }

 private:
  void run(const Streams& streams, const std::atomic<bool>& stop) {
    LogSessions::State& s = *state_;
    formats::LcmLogEvent e;
    while (!stop.load(std::memory_order_relaxed)) {
      const formats::RawEvent* ev = s.next(e, &stop);
      if (!ev) break;
      if (ev->kind == formats::RawEventKind::kSession && ev->session_started) {
        s.session_pending = true;  // the next run: the next source's
        break;
      }
      if (ev->kind == formats::RawEventKind::kBlock) {
        BlockRing* ring = formats::ring_of(streams, ev->stream);
        if (ring && !push_waiting(*ring, ev->block, stop)) break;
        ++s.counts.raw_blocks;
        worker_.add_blocks_written();
      } else if (ev->kind == formats::RawEventKind::kOperatingPoint) {
        if (!deliver(streams, ev->operating_point, stop)) break;
      }
    }
    if (stop.load()) return;
    exhausted_.store(true);
    std::lock_guard lock(s.session_end_mutex);
    s.session_ended = true;
    s.session_end.notify_all();
  }

  // A changed operating point is handed over only once the processing has taken every block before it, and the
  // blocks after it only once it has taken the operating point (pipeline.cpp takes operating points before blocks
  // and processes last in each round). Repeats carry nothing new and need no such care.
  bool deliver(const Streams& streams, const OperatingPoint& op, const std::atomic<bool>& stop) {
    if (have_last_ && same_values(last_, op)) return push_waiting(*streams.operating_point, op, stop);
    last_ = op;
    have_last_ = true;
    const auto taken = [&] {
      return streams.pressure->empty() && streams.mics->empty() &&
             (!streams.pressure_angle || streams.pressure_angle->empty());
    };
    return wait_until(stop, kTakenInterval, taken) && push_waiting(*streams.operating_point, op, stop) &&
           wait_until(stop, kTakenInterval, [&] { return streams.operating_point->empty(); });
  }

  std::shared_ptr<LogSessions::State> state_;
  StreamInfo info_;
  ThreadPolicy policy_;
  OperatingPoint last_;
  bool have_last_ = false;
  std::atomic<bool> exhausted_{false};
  // Last: destroyed (stopped) first, before anything its body uses.
  WorkerThread worker_{"log.replay"};
};

}  // namespace

LogSessions::LogSessions(LogSourceConfig config) : state_(std::make_shared<State>(std::move(config))) {}
LogSessions::~LogSessions() = default;

std::unique_ptr<Source> LogSessions::next_session() {
  State& s = *state_;
  formats::LcmLogEvent e;
  while (!s.session_pending) {
    const formats::RawEvent* ev = s.next(e, nullptr);
    if (!ev) return nullptr;
    if (ev->kind == formats::RawEventKind::kBeforeSession && ev->channel == formats::RawChannel::kRaw)
      throw std::runtime_error(s.config.path + ": event " + std::to_string(e.eventnum) + ": raw block before any " +
                               s.config.channels.session +
                               " message (was the log started with the daemon's channels?)");
    if (ev->kind == formats::RawEventKind::kSession && ev->session_started) s.session_pending = true;
  }
  s.session_pending = false;
  s.condition = s.decoder.condition();
  {
    std::lock_guard lock(s.session_end_mutex);
    s.session_ended = false;
  }
  return std::make_unique<LogSource>(state_);
}

const std::string& LogSessions::condition() const { return state_->condition; }

bool LogSessions::wait_for_session_end(std::chrono::milliseconds timeout) const {
  State& s = *state_;
  std::unique_lock lock(s.session_end_mutex);
  return s.session_end.wait_for(lock, timeout, [&] { return s.session_ended; });
}

double LogSessions::fraction_read() const {
  const std::size_t size = state_->reader.size();
  const auto read = static_cast<double>(state_->position.load(std::memory_order_relaxed));
  return size > 0 ? read / static_cast<double>(size) : 1.0;
}

LogCounts LogSessions::counts() const { return state_->counts; }

const formats::LcmLogReader& LogSessions::reader() const { return state_->reader; }

}  // namespace noisemon::drivers::log
