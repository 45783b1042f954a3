#include "drivers/lcm/lcm_source.hpp"

#include <atomic>
#include <chrono>
#include <lcm/lcm-cpp.hpp>

#include "drivers/formats/stream_messages.hpp"

namespace noisemon::drivers {
namespace {

class LcmSource final : public Source {
 public:
  explicit LcmSource(const LcmSourceConfig& c) : config_(c), lcm_(c.url) {
    const std::string where = "'" + c.session_channel + "' at " + (c.url.empty() ? std::string("LCM's default URL") : c.url);
    if (!lcm_.good()) throw std::runtime_error("lcm source: cannot open LCM " + where + " (is there a multicast route?)");
    lcm_.subscribe(c.session_channel, &LcmSource::on_session, this);
    lcm_.subscribe(c.raw_channel, &LcmSource::on_raw, this);
    lcm_.subscribe(c.operating_point_channel, &LcmSource::on_operating_point, this);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(c.session_timeout_s);
    while (!have_session_ && std::chrono::steady_clock::now() < deadline) lcm_.handleTimeout(100);
    if (!have_session_)
      throw std::runtime_error("lcm source: no noisemon.session_t on " + where + " within " +
                               std::to_string(c.session_timeout_s) + " s (start lcm-logplayer, or a daemon publishing raw blocks)");
  }
  ~LcmSource() override { stop(); }

  std::string name() const override { return "lcm"; }
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
            {"lcm.damaged_blocks", static_cast<std::int64_t>(damaged_.load())},
            {"lcm.other_session_blocks", static_cast<std::int64_t>(other_session_.load())}};
  }
  std::vector<DriverThreadStatus> thread_status() const override { return {worker_.status()}; }

 private:
  void on_session(const lcm::ReceiveBuffer*, const std::string&, const noisemon::session_t* m) {
    if (have_session_) return;  // the first session fixes the time base; repeats are the same session
    info_ = from_message(*m);
    have_session_ = true;
  }
  void on_raw(const lcm::ReceiveBuffer*, const std::string&, const noisemon::raw_block_t* m) {
    if (!streams_.pressure) return;  // before start(): nothing to feed yet
    if (m->epoch_utime != info_.epoch_utime) {
      // Another session (the next run of a multi-run log): its frame indices restart on another time base, which
      // this daemon's processing cannot continue. Counted, never mixed in (`noisemon replay` handles such logs).
      ++other_session_;
      return;
    }
    SampleBlock& b = block_;
    try {
      b = from_message(*m);
    } catch (const std::invalid_argument&) {
      ++damaged_;
      return;
    }
    BlockRing* ring = m->stream == noisemon::raw_block_t::STREAM_PRESSURE ? streams_.pressure
                      : m->stream == noisemon::raw_block_t::STREAM_MICS   ? streams_.mics
                                                                           : nullptr;
    if (!ring) {
      ++damaged_;
      return;
    }
    ring->write(&b, 1);  // a full ring counts the overrun itself
    worker_.add_blocks_written();
  }
  void on_operating_point(const lcm::ReceiveBuffer*, const std::string&, const noisemon::operating_point_t* m) {
    if (streams_.operating_point) streams_.operating_point->push(from_message(*m));
  }

  LcmSourceConfig config_;
  lcm::LCM lcm_;
  StreamInfo info_;
  bool have_session_ = false;
  Streams streams_;
  SampleBlock block_;
  std::atomic<std::uint64_t> damaged_{0}, other_session_{0};
  // Last: destroyed (stopped) first, before anything its body uses.
  WorkerThread worker_{"lcm.receive"};
};

}  // namespace

std::unique_ptr<Source> make_lcm_source(const LcmSourceConfig& config) { return std::make_unique<LcmSource>(config); }

}  // namespace noisemon::drivers
