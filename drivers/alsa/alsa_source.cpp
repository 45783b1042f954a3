#include "drivers/alsa/alsa_source.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "drivers/aligned_stream.hpp"
#include "drivers/mic_positions.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers::alsa {
namespace {

void check(const AlsaSourceConfig& c) {
  const std::size_t n = c.channels.size();
  if (n == 0 || n > SampleBlock::kMaxChannels)
    throw std::invalid_argument("alsa.channels: expected 1.." + std::to_string(SampleBlock::kMaxChannels) +
                                " microphone channels");
  for (unsigned ch : c.channels)
    if (ch >= kMaxCaptureChannels)
      throw std::invalid_argument("alsa.channels: channel " + std::to_string(ch) + " is beyond the " +
                                  std::to_string(kMaxCaptureChannels) + " an interface may capture");
  if (c.sensitivity_mv_per_pa.size() != n)
    throw std::invalid_argument("alsa.sensitivity_mv_per_pa: " + std::to_string(c.sensitivity_mv_per_pa.size()) +
                                " values for " + std::to_string(n) + " microphones");
  for (double s : c.sensitivity_mv_per_pa)
    if (!(s > 0.0)) throw std::invalid_argument("alsa.sensitivity_mv_per_pa: expected positive values (mV/Pa)");
  if (!(c.full_scale_v > 0.0)) throw std::invalid_argument("alsa.full_scale_v: expected a positive voltage");
  if (!c.positions_m.empty() && c.positions_m.size() != n)
    throw std::invalid_argument("alsa.positions_m: " + std::to_string(c.positions_m.size()) + " positions for " +
                                std::to_string(n) + " microphones");
  if (c.sync_channel >= static_cast<int>(kMaxCaptureChannels) ||
      std::find(c.channels.begin(), c.channels.end(), c.sync_channel) != c.channels.end())
    throw std::invalid_argument("alsa.sync_channel: " + std::to_string(c.sync_channel) +
                                " must be a spare capture channel, none of the microphones', below " +
                                std::to_string(kMaxCaptureChannels));
  if (c.sync_channel >= 0 && !std::isfinite(c.sync_angle_deg))
    throw std::invalid_argument("alsa.sync_angle_deg: the crank angle of the sync pulse is needed with a sync channel");
  if (c.capture.rate_hz < kMinRateHz || c.capture.rate_hz > kMaxRateHz)
    throw std::invalid_argument("alsa.rate_hz: " + std::to_string(c.capture.rate_hz) + " Hz is outside " +
                                std::to_string(kMinRateHz) + ".." + std::to_string(kMaxRateHz));
}

CaptureConfig capture_config(const AlsaSourceConfig& c) {
  CaptureConfig cc = c.capture;
  const unsigned needed =
      std::max(*std::max_element(c.channels.begin(), c.channels.end()) + 1, static_cast<unsigned>(c.sync_channel + 1));
  if (cc.channels == 0) {
    cc.channels = needed;
    cc.at_least_channels = true;
  }
  if (cc.channels < needed)
    throw std::invalid_argument("alsa.capture_channels: " + std::to_string(cc.channels) +
                                " channels do not reach microphone channel " + std::to_string(needed - 1));
  return cc;
}

class AlsaSource final : public MicSource {
 public:
  explicit AlsaSource(const AlsaSourceConfig& config)
      : config_(config),
        capture_config_(capture_config(config)),
        capture_(capture_config_),
        worker_("alsa.microphones") {
    const std::size_t n = config.channels.size();
    info_.mic_count = static_cast<std::uint32_t>(n);
    info_.mic_positions_m = config.positions_m;
    if (info_.mic_positions_m.empty()) {
      info_.mic_positions_m = thesis_mic_positions(config.radius_m / 1.75);
      info_.mic_positions_m.resize(n);
    }
    info_.radius_m = config.radius_m;
    info_.acoustic_delay_s = config.radius_m / config.speed_of_sound_m_s;
    info_.mic_passband_hz = dsp::converter_passband_hz(config.capture.rate_hz);
    for (std::size_t i = 0; i < n; ++i)
      pa_per_unit_.push_back(config.full_scale_v / (1e-3 * config.sensitivity_mv_per_pa[i]));
    const bool one_scale =
        std::all_of(pa_per_unit_.begin(), pa_per_unit_.end(), [&](double s) { return s == pa_per_unit_.front(); });
    info_.mic_full_scale_pa = one_scale ? pa_per_unit_.front() : 0.0;
    if (config.sync_channel >= 0) info_.sync_angle_deg = config.sync_angle_deg;
  }
  ~AlsaSource() override { stop(); }

  std::string name() const override { return "alsa"; }
  MicStreamInfo info() const override { return info_; }

  void start(BlockRing& mics, std::int64_t epoch_utime, const CrankReference* reference) override {
    if (worker_.joinable()) throw std::logic_error("alsa source: start() while running; stop() first");
    AlignedStreamAssembler::Options o;
    o.channels = info_.mic_count;
    o.card_rate_hz = capture_config_.rate_hz;
    o.epoch_utime = epoch_utime;
    o.reference = config_.sync_channel >= 0 ? reference : nullptr;
    o.read_period_s = static_cast<double>(capture_.period_frames()) / capture_config_.rate_hz;
    o.host_delay_uncertainty_s = config_.host_delay_uncertainty_s;
    epoch_utime_ = epoch_utime;
    assembler_ = std::make_unique<AlignedStreamAssembler>(o);
    restart();
    worker_.start("nm-mics", config_.thread, [this, &mics](const std::atomic<bool>& stop) { run(mics, stop); });
  }
  void stop() override { worker_.stop(); }
  bool running() const override { return worker_.state() == ThreadState::kRunning && worker_.blocks_written() > 0; }
  std::vector<DriverThreadStatus> thread_status() const override { return {worker_.status()}; }
  std::vector<DriverCounter> counters() const override {
    auto count = [](const std::atomic<std::int64_t>& c) { return c.load(std::memory_order_relaxed); };
    std::vector<DriverCounter> out{{"alsa.mics.overruns", static_cast<std::int64_t>(overruns_.load())},
                                   {"alsa.mics.frames", static_cast<std::int64_t>(frames_.load())},
                                   {"alsa.mics.clock_ppb", count(clock_ppb_), true},
                                   {"alsa.mics.alignment_uncertainty_us", count(uncertainty_us_), true}};
    if (config_.sync_channel >= 0) {
      out.push_back({"alsa.mics.synced", count(synced_), true});
      out.push_back({"alsa.mics.sync_losses", count(sync_losses_)});
      out.push_back({"alsa.mics.sync_pulses_rejected", count(pulses_rejected_)});
    }
    return out;
  }

 private:
  void run(BlockRing& ring, const std::atomic<bool>& stop) {
    std::vector<double> values, frame(info_.mic_count);
    while (!stop.load(std::memory_order_relaxed)) {
      std::size_t frames = 0;
      switch (capture_.read(values, frames)) {
        case ReadStatus::kNothingYet:
          capture_.wait(50);
          continue;
        case ReadStatus::kOverrun:
          assembler_->deliver(ring, true);
          overruns_.fetch_add(1, std::memory_order_relaxed);
          restart();
          continue;
        case ReadStatus::kFrames:
          break;
      }
      for (std::size_t f = 0; f < frames; ++f) {
        const double* in = &values[f * capture_.channels()];
        for (std::size_t m = 0; m < frame.size(); ++m) frame[m] = in[config_.channels[m]] * pa_per_unit_[m];
        assembler_->add_scan(frame.data(), config_.sync_channel >= 0 ? in[config_.sync_channel] : 0.0, ring);
      }
      frames_.fetch_add(frames, std::memory_order_relaxed);
      assembler_->observe_host(host_seconds());
      assembler_->deliver(ring, false);
      publish_alignment();
      worker_.set_blocks_written(assembler_->blocks_written());
    }
    assembler_->deliver(ring, true);
    worker_.set_blocks_written(assembler_->blocks_written());
  }

  // Capture starts (again): scan 0 at the wall time it returns, the monotonic clock read beside it.
  void restart() {
    origin_utime_ = capture_.start();
    origin_steady_ = std::chrono::steady_clock::now();
    assembler_->restart(origin_utime_);
  }
  // Now on the pipeline's clock by the host's monotonic clock (s since the epoch).
  double host_seconds() const {
    const std::chrono::duration<double> since = std::chrono::steady_clock::now() - origin_steady_;
    return static_cast<double>(origin_utime_ - epoch_utime_) * 1e-6 + since.count();
  }
  void publish_alignment() {
    clock_ppb_.store(std::llround(assembler_->ppm() * 1000.0), std::memory_order_relaxed);
    uncertainty_us_.store(std::llround(assembler_->uncertainty_s() * 1e6), std::memory_order_relaxed);
    synced_.store(assembler_->synced() ? 1 : 0, std::memory_order_relaxed);
    sync_losses_.store(static_cast<std::int64_t>(assembler_->sync_losses()), std::memory_order_relaxed);
    pulses_rejected_.store(static_cast<std::int64_t>(assembler_->pulses_rejected()), std::memory_order_relaxed);
  }

  AlsaSourceConfig config_;
  CaptureConfig capture_config_;
  Capture capture_;
  MicStreamInfo info_;
  std::vector<double> pa_per_unit_;  // Pa of digital full scale, per microphone
  std::unique_ptr<AlignedStreamAssembler> assembler_;
  std::int64_t epoch_utime_ = 0, origin_utime_ = 0;
  std::chrono::steady_clock::time_point origin_steady_;
  std::atomic<std::uint64_t> overruns_{0}, frames_{0};
  std::atomic<std::int64_t> clock_ppb_{0}, uncertainty_us_{0}, synced_{0}, sync_losses_{0}, pulses_rejected_{0};
  WorkerThread worker_;
};

}  // namespace

std::unique_ptr<MicSource> make_alsa_source(const AlsaSourceConfig& config) {
  check(config);
  return std::make_unique<AlsaSource>(config);
}

}  // namespace noisemon::drivers::alsa
