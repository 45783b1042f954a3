#include "cli/source_capture.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <thread>

#include "daemon/sources.hpp"

namespace noisemon::cli {
namespace {

struct Rings {
  drivers::BlockRing pressure{4096}, mics{4096}, angle{4096};
  drivers::OperatingPointRing ops{4096};
};

void take_pressure(Rings& r, CapturedStreams& out, drivers::SampleBlock& block) {
  while (r.pressure.read(&block, 1) == 1)
    for (std::uint32_t f = 0; f < block.frames; ++f) {
      out.pressure_pa.push_back(block.data[f * block.channels + drivers::kPressureChannel]);
      out.crank_deg.push_back(block.data[f * block.channels + drivers::kCrankChannel]);
    }
  while (r.angle.read(&block, 1) == 1) {
  }
  drivers::OperatingPoint op;
  while (r.ops.read(&op, 1) == 1) {
    ++out.operating_points;
    out.last_speed_rpm = op.speed_rpm;
    if (std::isfinite(op.speed_rpm)) out.max_speed_rpm = std::max(out.max_speed_rpm, op.speed_rpm);
  }
}

}  // namespace

CapturedStreams capture_streams(const daemon::Config& config, double seconds, double settle_s,
                                daemon::PressureClock clock, const SourceMaker& make) {
  auto source = make ? make(config, clock) : daemon::make_source(config, clock);
  CapturedStreams out;
  out.info = source->info();
  out.mics.resize(out.info.mic_count);
  auto rings = std::make_unique<Rings>();
  source->start(drivers::Streams{&rings->pressure, &rings->mics, &rings->ops, &rings->angle});
  const auto settle = static_cast<std::size_t>(settle_s * drivers::kPipelineRateHz);
  const std::size_t wanted = settle + static_cast<std::size_t>(seconds * drivers::kPipelineRateHz);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(3 * (settle_s + seconds) + 10);
  auto block = std::make_unique<drivers::SampleBlock>();
  std::int64_t next_frame = -1;
  std::size_t held = 0;
  while (held < wanted && std::chrono::steady_clock::now() < deadline) {
    while (rings->mics.read(block.get(), 1) == 1) {
      if (next_frame >= 0 && block->first_index != next_frame) {  // an overrun: one unbroken stretch is kept
        for (auto& m : out.mics) m.clear();
        held = 0;
        ++out.mic_gaps;
      }
      next_frame = block->first_index + block->frames;
      for (std::uint32_t f = 0; f < block->frames; ++f)
        for (std::uint32_t m = 0; m < out.info.mic_count; ++m)
          out.mics[m].push_back(block->data[f * block->channels + m]);
      held += block->frames;
    }
    take_pressure(*rings, out, *block);
    for (const auto& t : source->thread_status())
      if (t.state == drivers::ThreadState::kFailed) throw std::runtime_error(t.name + ": " + t.error);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  out.counters = source->counters();
  out.threads = source->thread_status();
  source->stop();
  if (held < wanted)
    throw std::runtime_error("the microphones delivered " + std::to_string(held) + " of " + std::to_string(wanted) +
                             " unbroken samples in time (" + std::to_string(out.mic_gaps) +
                             " gaps: overruns; give the microphone thread a priority in [threads.mics])");
  for (auto& m : out.mics) m.erase(m.begin(), m.begin() + static_cast<std::ptrdiff_t>(std::min(settle, m.size())));
  return out;
}

std::size_t engine_cycles_seen(const CapturedStreams& streams) {
  std::size_t wraps = 0;
  double previous = NAN;
  for (double a : streams.crank_deg) {
    if (std::isfinite(a) && std::isfinite(previous) && a < previous - 360.0) ++wraps;  // a new cycle
    previous = a;
  }
  return wraps;
}

}  // namespace noisemon::cli
