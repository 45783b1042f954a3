#include "drivers/combined_source.hpp"

#include <stdexcept>

namespace noisemon::drivers {
namespace {

// Both parts' thread states or counters, the stream source's first.
template <class T>
std::vector<T> joined(std::vector<T> first, std::vector<T> second) {
  for (auto& item : second) first.push_back(std::move(item));
  return first;
}

class CombinedSource final : public Source {
 public:
  CombinedSource(std::unique_ptr<Source> streams, std::unique_ptr<OperatingPointSource> op)
      : streams_(std::move(streams)), op_(std::move(op)), discarded_(64) {
    if (!streams_ || !op_) throw std::invalid_argument("combine_sources: both sources are required");
  }
  ~CombinedSource() override { stop(); }

  std::string name() const override { return streams_->name() + "+" + op_->name(); }
  StreamInfo info() const override { return streams_->info(); }
  void start(const Streams& s) override {
    if (!s.operating_point) throw std::invalid_argument(name() + ": start() needs the operating-point ring");
    op_->start(*s.operating_point);
    try {
      streams_->start(Streams{s.pressure, s.mics, &discarded_});
    } catch (...) {
      op_->stop();
      throw;
    }
  }
  void stop() override {
    streams_->stop();
    op_->stop();
  }
  bool running() const override { return streams_->running() && op_->running(); }
  bool exhausted() const override { return streams_->exhausted(); }
  std::vector<DriverThreadStatus> thread_status() const override {
    return joined(streams_->thread_status(), op_->thread_status());
  }
  std::vector<DriverCounter> counters() const override { return joined(streams_->counters(), op_->counters()); }

 private:
  std::unique_ptr<Source> streams_;
  std::unique_ptr<OperatingPointSource> op_;
  OperatingPointRing discarded_;
};

// The stream source's own microphones are generated into a small ring nobody reads (its pushes fail once full).
class MicComposedSource final : public Source {
 public:
  MicComposedSource(std::unique_ptr<Source> streams, std::unique_ptr<MicSource> mics)
      : streams_(std::move(streams)), mics_(std::move(mics)), discarded_(4) {
    if (!streams_ || !mics_) throw std::invalid_argument("compose_microphones: both sources are required");
  }
  ~MicComposedSource() override { stop(); }

  std::string name() const override { return streams_->name() + "+" + mics_->name(); }
  StreamInfo info() const override {
    StreamInfo info = streams_->info();
    const MicStreamInfo m = mics_->info();
    info.mic_count = m.mic_count;
    info.mic_positions_m = m.mic_positions_m;
    info.radius_m = m.radius_m;
    info.acoustic_delay_s = m.acoustic_delay_s;
    info.mic_full_scale_pa = m.mic_full_scale_pa;
    info.mic_passband_hz = m.mic_passband_hz;
    info.sync_angle_deg = m.sync_angle_deg;
    return info;
  }
  void start(const Streams& s) override {
    if (!s.mics) throw std::invalid_argument(name() + ": start() needs the microphone ring");
    mics_->start(*s.mics, streams_->info().epoch_utime, s.crank_reference);
    try {
      Streams own = s;
      own.mics = &discarded_;
      streams_->start(own);
    } catch (...) {
      mics_->stop();
      throw;
    }
  }
  void stop() override {
    streams_->stop();
    mics_->stop();
  }
  bool running() const override { return streams_->running() && mics_->running(); }
  bool exhausted() const override { return streams_->exhausted(); }
  std::vector<DriverThreadStatus> thread_status() const override {
    return joined(streams_->thread_status(), mics_->thread_status());
  }
  std::vector<DriverCounter> counters() const override { return joined(streams_->counters(), mics_->counters()); }

 private:
  std::unique_ptr<Source> streams_;
  std::unique_ptr<MicSource> mics_;
  BlockRing discarded_;
};

}  // namespace

std::unique_ptr<Source> compose_microphones(std::unique_ptr<Source> streams, std::unique_ptr<MicSource> mics) {
  return std::make_unique<MicComposedSource>(std::move(streams), std::move(mics));
}

std::unique_ptr<Source> combine_sources(std::unique_ptr<Source> streams,
                                        std::unique_ptr<OperatingPointSource> operating_point) {
  return std::make_unique<CombinedSource>(std::move(streams), std::move(operating_point));
}

}  // namespace noisemon::drivers
