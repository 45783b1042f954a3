#include "drivers/lcm/lcm_source.hpp"

#include <atomic>
#include <chrono>
#include <lcm/lcm-cpp.hpp>

#include "drivers/formats/raw_stream_decoder.hpp"

namespace noisemon::drivers::lcm {
namespace {

// Messages LCM holds for a subscription until they are handled; beyond it drops the newest. LCM's default (30, under
// 0.1 s of raw blocks) lost the first cycles of a played log: nothing is handled between the session's arrival and
// start(), while the pipeline is built, nor while a loaded machine leaves this thread unscheduled. 4096 raw blocks are
// about 10 s of a full-rate stream (some 20 MB held only while a stall lasts).
constexpr int kQueuedMessages = 4096;

class LcmSource final : public Source {
 public:
  explicit LcmSource(const LcmSourceConfig& c)
      : config_(c),
        lcm_(c.url),
        decoder_({{c.raw_channel, c.operating_point_channel, c.session_channel}, formats::SessionChanges::kKeepFirst}) {
    const std::string where =
        "'" + c.session_channel + "' at " + (c.url.empty() ? std::string("LCM's default URL") : c.url);
    if (!lcm_.good())
      throw std::runtime_error("lcm source: cannot open LCM " + where + " (is there a multicast route?)");
    for (const std::string* channel : {&c.session_channel, &c.raw_channel, &c.operating_point_channel})
      lcm_.subscribe(*channel, &LcmSource::on_message, this)->setQueueCapacity(kQueuedMessages);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(c.session_timeout_s);
    while (!decoder_.has_session() && std::chrono::steady_clock::now() < deadline) lcm_.handleTimeout(100);
    if (!decoder_.has_session())
      throw std::runtime_error("lcm source: no noisemon.session_t on " + where + " within " +
                               std::to_string(c.session_timeout_s) +
                               " s (start lcm-logplayer, or a daemon publishing raw blocks)");
    info_ = decoder_.info();
  }
  ~LcmSource() override { stop(); }

  std::string name() const override { return "lcm"; }
  // The first session fixes the time base: a pipeline cannot change it while it runs.
  StreamInfo info() const override { return info_; }

  void start(const Streams& streams) override {
    streams_ = streams;
    worker_.start("nm-lcm-in", config_.thread, [this](const std::atomic<bool>& stop) {
      while (!stop.load(std::memory_order_relaxed)) lcm_.handleTimeout(50);
    });
  }
  void stop() override { worker_.stop(); }
  bool running() const override { return worker_.blocks_written() > 0; }
  std::vector<DriverCounter> counters() const override {
    return {{"lcm.blocks", static_cast<std::int64_t>(worker_.blocks_written())},
            {"lcm.damaged_blocks", static_cast<std::int64_t>(damaged_blocks_.load())},
            {"lcm.other_session_blocks", static_cast<std::int64_t>(other_session_.load())},
            {"lcm.damaged_messages", static_cast<std::int64_t>(damaged_messages_.load())}};
  }
  std::vector<DriverThreadStatus> thread_status() const override { return {worker_.status()}; }

 private:
  void on_message(const ::lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    const formats::RawEvent& e = decoder_.decode(channel, rbuf->data, rbuf->data_size);
    switch (e.kind) {
      case formats::RawEventKind::kBlock:
        if (!streams_.pressure) return;  // before start(): nothing to feed yet
        if (BlockRing* ring = formats::ring_of(streams_, e.stream))
          (void)ring->write(&e.block, 1);  // full: counted there
        worker_.add_blocks_written();      // a full ring counts the overrun itself
        return;
      case formats::RawEventKind::kOperatingPoint:
        if (streams_.operating_point) (void)streams_.operating_point->push(e.operating_point);
        return;
      case formats::RawEventKind::kOtherSessionBlock:
        // Another session (the next run of a multi-run log): its frame indices restart on another time base, which
        // this daemon's processing cannot continue. Counted, never mixed in (`noisemon replay` handles such logs).
        ++other_session_;
        return;
      case formats::RawEventKind::kBadBlock:  // never reaches the processing, which would fail on it
        ++damaged_blocks_;
        return;
      case formats::RawEventKind::kDamaged:
        ++(e.channel == formats::RawChannel::kRaw ? damaged_blocks_ : damaged_messages_);
        return;
      case formats::RawEventKind::kSession:  // repeats, and other runs' sessions: the first one stays
      case formats::RawEventKind::kBeforeSession:
      case formats::RawEventKind::kOtherChannel:
        return;
    }
  }

  LcmSourceConfig config_;
  ::lcm::LCM lcm_;
  formats::RawStreamDecoder decoder_;  // used by one thread at a time: the constructor's, then the worker
  StreamInfo info_;
  Streams streams_;
  std::atomic<std::uint64_t> damaged_blocks_{0}, other_session_{0}, damaged_messages_{0};
  // Last: destroyed (stopped) first, before anything its body uses.
  WorkerThread worker_{"lcm.receive"};
};

}  // namespace

std::unique_ptr<Source> make_lcm_source(const LcmSourceConfig& config) { return std::make_unique<LcmSource>(config); }

}  // namespace noisemon::drivers::lcm
