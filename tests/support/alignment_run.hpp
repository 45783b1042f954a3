// The clock-alignment harness of the tests and the benchmark: a DriftingCard's scans through an
// AlignedStreamAssembler as a front-end's driver thread would feed it, and the output's time error measured against
// the card's own instants.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>

#include "drivers/aligned_stream.hpp"
#include "drivers/crank_reference.hpp"
#include "tests/support/drifting_card.hpp"

namespace noisemon::test {

struct AlignmentRun {
  double worst_error_s = 0.0;            // the output's worst time error over 1 s windows after the first 3 s
  double worst_error_over_stated = 0.0;  // worst |error| / the uncertainty the assembler stated then
  double ppm = 0.0, ppm_sigma = 0.0;     // the tracked rate and its stated 1-sigma uncertainty
  bool synced = false;
  std::uint64_t sync_losses = 0, realignments = 0, frames = 0;
};

// The delay of the output against the card's tones, from each tone's phase (a lock-in over the window): the
// lowest tone's gives it unambiguously to +-38 ms, each higher one refines it within its own period.
class ToneDelay {
 public:
  explicit ToneDelay(const DriftingCardSpec& spec) : spec_(spec) {}
  void add(double t, double y) {
    for (int i = 0; i < 3; ++i) {
      const double w = 2.0 * M_PI * spec_.tone_hz[i];
      c_[i] += y * std::cos(w * t);
      s_[i] += y * std::sin(w * t);
    }
  }
  // The delay d of y(t) = x(t - d) over the samples since the last call.
  double take() {
    double delay = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double w = 2.0 * M_PI * spec_.tone_hz[i];
      const double d = std::atan2(-c_[i], s_[i]) / w;  // y = A sin(w t - phi): phi = w d, modulo the period
      const double period = 1.0 / spec_.tone_hz[i];
      delay = i == 0 ? d : d + period * std::round((delay - d) / period);
      c_[i] = s_[i] = 0.0;
    }
    return delay;
  }

 private:
  DriftingCardSpec spec_;
  double c_[3] = {}, s_[3] = {};
};

// The card's scans through the assembler for `seconds`, the crank instants posted 30 ms late (the pipeline reads
// the crank after the card's scans), host readings every period; the output's time error measured per second as
// the delay that best maps the true sound onto it.
// window(t_s, error_s, stated_s) after each second, if given.
inline AlignmentRun run_card(const DriftingCardSpec& spec, bool sync, double seconds, double sync_stops_at = 1e300,
                             const std::function<void(double, double, double)>& window = {}) {
  namespace nd = noisemon::drivers;
  DriftingCard card(spec);
  nd::CrankReference reference(0.0);
  nd::AlignedStreamAssembler::Options o;
  o.channels = 1;
  o.card_rate_hz = spec.rate_hz;
  o.epoch_utime = 0;
  o.reference = sync ? &reference : nullptr;
  o.read_period_s = spec.period_scans / spec.rate_hz;
  nd::AlignedStreamAssembler assembler(o);
  nd::BlockRing ring(64);
  assembler.restart(static_cast<std::int64_t>(std::llround((spec.t0_s + 0.003) * 1e6)));  // the host 3 ms off
  AlignmentRun run;
  double window_end = 4.0, stated = 0.0;  // windows of a second from 3 s
  ToneDelay delay(card.spec());
  auto measure = [&](const nd::SampleBlock& b) {
    for (std::uint32_t f = 0; f < b.frames; ++f) {
      const double t = static_cast<double>(b.first_index + f) / 40000.0;
      if (t < 3.0) continue;
      delay.add(t, b.data[f]);
      if (t >= window_end) {
        const double error = delay.take();
        run.worst_error_s = std::max(run.worst_error_s, std::abs(error));
        run.worst_error_over_stated = std::max(run.worst_error_over_stated, std::abs(error) / stated);
        if (window) window(t, error, stated);
        window_end += 1.0;
      }
    }
  };
  while (card.scan_instant(card.scans()) < spec.t0_s + seconds) {
    const DriftingCard::Scan s = card.next();
    const double sync_value = s.t < sync_stops_at ? s.sync : -0.4;
    assembler.add_scan(&s.mic, sync_value, ring);
    if (!card.reading_due()) continue;
    for (double instant : card.crank_instants_until(s.t - 0.03)) reference.post(instant);
    assembler.observe_host(card.reading_instant());
    assembler.deliver(ring, false);
    stated = assembler.uncertainty_s();
    nd::SampleBlock b;
    while (ring.read(&b, 1) == 1) measure(b);
  }
  run.ppm = assembler.ppm();
  run.ppm_sigma = assembler.ppm_sigma();
  run.synced = assembler.synced();
  run.sync_losses = assembler.sync_losses();
  run.realignments = assembler.realignments();
  run.frames = assembler.frames();
  return run;
}

}  // namespace noisemon::test
