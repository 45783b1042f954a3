#include "drivers/combined_source.hpp"

#include <stdexcept>

namespace noisemon::drivers {
namespace {

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
    auto out = streams_->thread_status();
    for (auto& t : op_->thread_status()) out.push_back(std::move(t));
    return out;
  }
  std::vector<DriverCounter> counters() const override {
    auto out = streams_->counters();
    for (auto& c : op_->counters()) out.push_back(std::move(c));
    return out;
  }

 private:
  std::unique_ptr<Source> streams_;
  std::unique_ptr<OperatingPointSource> op_;
  OperatingPointRing discarded_;
};

}  // namespace

std::unique_ptr<Source> combine_sources(std::unique_ptr<Source> streams,
                                        std::unique_ptr<OperatingPointSource> operating_point) {
  return std::make_unique<CombinedSource>(std::move(streams), std::move(operating_point));
}

}  // namespace noisemon::drivers
