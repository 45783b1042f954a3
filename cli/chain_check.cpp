#include "cli/chain_check.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "dsp/levels.hpp"

namespace noisemon::cli {
namespace {

constexpr double kDeadPa = dsp::kReferencePressurePa;  // below 0 dB SPL: no microphone's self-noise is that quiet
constexpr double kImplausibleDb = 10.0;                // this far from the median of the others
constexpr double kDeadBelowOthersDb = 40.0;            // this far below them: an open input's noise, not a microphone
constexpr double kAtmosphereBar = 1.013;               // what an absolute transducer reads with the engine stopped
constexpr double kOffsetLimitBar = 0.2;
constexpr double kImplausiblePpm = 1000.0;  // a crystal this far off is a wrong nominal rate, not drift
constexpr double kRestSeconds = 1.0;        // the second listen, the pressure on the card's timer
constexpr double kRestTurningRpm = 1.0;     // the encoder's edges (or CAN) faster than this at rest: turning

double db(double rms_pa) { return dsp::level_db(std::max(rms_pa * rms_pa, 1e-24)); }

double rms(const std::vector<double>& x, std::size_t from, std::size_t to) {
  double s = 0;
  for (std::size_t k = from; k < to; ++k) s += x[k] * x[k];
  return to > from ? std::sqrt(s / static_cast<double>(to - from)) : 0.0;
}

// The quietest tenth of 100 ms blocks: the floor under the passing sounds.
double floor_db(const std::vector<double>& x) {
  std::vector<double> levels;
  for (std::size_t k = 0; k + 4000 <= x.size(); k += 4000) levels.push_back(db(rms(x, k, k + 4000)));
  if (levels.empty()) return db(rms(x, 0, x.size()));
  std::sort(levels.begin(), levels.end());
  return levels[levels.size() / 10];
}

std::vector<CheckRow> microphone_rows(const CapturedStreams& s) {
  std::vector<double> levels;
  for (const auto& m : s.mics) levels.push_back(db(rms(m, 0, m.size())));
  std::vector<CheckRow> rows;
  for (std::size_t i = 0; i < s.mics.size(); ++i) {
    const std::vector<double>& x = s.mics[i];
    std::vector<double> others;
    for (std::size_t j = 0; j < levels.size(); ++j)
      if (j != i) others.push_back(levels[j]);
    std::nth_element(others.begin(), others.begin() + static_cast<std::ptrdiff_t>(others.size() / 2), others.end());
    const double median = others.empty() ? levels[i] : others[others.size() / 2];
    const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
    const bool finite = std::all_of(x.begin(), x.end(), [](double v) { return std::isfinite(v); });
    const double full = s.info.mic_full_scale_pa;
    CheckRow r{"microphone " + std::to_string(i + 1), "", "ok"};
    char value[96];
    std::snprintf(value, sizeof value, "%.1f dB, floor %.1f dB", levels[i], floor_db(x));
    r.value = value;
    char why[96];
    if (!finite || rms(x, 0, x.size()) < kDeadPa || *lo == *hi) {
      r.verdict = !finite ? "dead: not a number" : "dead: no signal (unplugged, no power, or muted)";
    } else if (full > 0 && std::max(-*lo, *hi) >= 0.999 * full) {
      std::snprintf(why, sizeof why, "clipped: peaks at the converter's full scale (%.0f Pa)", full);
      r.verdict = why;
    } else if (levels[i] - median < -kDeadBelowOthersDb) {
      std::snprintf(why, sizeof why, "dead: %.0f dB below the others (unplugged, no power, or muted)",
                    median - levels[i]);
      r.verdict = why;
    } else if (std::abs(levels[i] - median) > kImplausibleDb) {
      std::snprintf(why, sizeof why, "implausible: %+.1f dB from the others' median", levels[i] - median);
      r.verdict = why;
    }
    r.failed = r.verdict != "ok";
    rows.push_back(r);
  }
  return rows;
}

std::size_t finite_count(const std::vector<double>& x) {
  return static_cast<std::size_t>(std::count_if(x.begin(), x.end(), [](double v) { return std::isfinite(v); }));
}

// With the engine stopped, a card whose pressure the encoder's edges clock delivered none: it is sampled again on the
// card's timer (daemon::PressureClock::kAtRest).
bool needs_rest_capture(const CapturedStreams& s) {
  return engine_cycles_seen(s) == 0 && finite_count(s.pressure_pa) == 0;
}

// [comedi.pressure] describes a charge transducer behind an amplifier: no absolute zero (the amplifier is reset and
// drifts), so its reading at rest says nothing of the chain; each cycle is referenced instead (pegging).
bool charge_chain(const daemon::Config& c) { return c.comedi.pressure.sensitivity_pc_per_bar > 0; }

// The pressure row: its mean with the engine stopped against the atmosphere.
CheckRow pressure_row(double mean_bar, bool charge) {
  char value[96];
  std::snprintf(value, sizeof value, "%.3f bar with the engine stopped", mean_bar);
  if (charge) return {"pressure", value, "offset not checked: a charge chain has no absolute zero (pegged)", false};
  const bool bad = std::abs(mean_bar - kAtmosphereBar) > kOffsetLimitBar;
  return {"pressure", value, bad ? "offset: not atmospheric (offset_bar, or calibrate --pressure)" : "ok", bad};
}

// s: the listen; rest: the second one at rest, when there was one (its pressure gives the offset).
std::vector<CheckRow> pressure_and_encoder_rows(const CapturedStreams& s, const CapturedStreams* rest, bool charge) {
  std::vector<CheckRow> rows;
  std::size_t known = 0, finite = 0;
  double sum = 0;
  for (std::size_t k = 0; k < s.crank_deg.size(); ++k)
    if (std::isfinite(s.crank_deg[k])) ++known;
  for (double p : (rest ? rest->pressure_pa : s.pressure_pa))
    if (std::isfinite(p)) sum += p, ++finite;
  const std::size_t wraps = engine_cycles_seen(s);
  const bool turning = wraps > 0 || (rest && rest->max_speed_rpm > kRestTurningRpm);
  if (finite == 0)
    rows.push_back({"pressure", "no samples", "no pressure stream", true});
  else if (!turning)
    rows.push_back(pressure_row(sum / static_cast<double>(finite) / 1e5, charge));
  else
    rows.push_back({"pressure", "engine turning", "offset not checked (it needs the engine stopped)", false});
  char value[96];
  std::snprintf(
      value, sizeof value, "%zu cycles, crank angle known in %.0f %% of frames", wraps,
      s.crank_deg.empty() ? 0.0 : 100.0 * static_cast<double>(known) / static_cast<double>(s.crank_deg.size()));
  rows.push_back({"encoder", value, wraps > 0 ? "ok" : "not turning: checked when the engine turns", false});
  return rows;
}

// The microphone front-end's clock against the encoder's, from the source's gauges (drivers/aligned_stream.hpp).
CheckRow clock_row(const CapturedStreams& s, bool turning) {
  const auto gauge = [&](const char* name) -> std::optional<std::int64_t> {
    for (const auto& c : s.counters)
      if (c.name == name) return c.value;
    return std::nullopt;
  };
  const std::optional<std::int64_t> ppb = gauge("alsa.mics.clock_ppb");
  if (!ppb) return {"clock drift", "one clock", "ok: the microphones are on the encoder's card", false};
  const std::optional<std::int64_t> synced = gauge("alsa.mics.synced");
  char value[96];
  std::snprintf(value, sizeof value, "%+.1f ppm, placed to %lld us (%s)", 1e-3 * static_cast<double>(*ppb),
                static_cast<long long>(gauge("alsa.mics.alignment_uncertainty_us").value_or(-1)),
                synced ? (*synced ? "sync pulse" : "sync pulse not locked") : "host clock");
  if (std::abs(1e-3 * static_cast<double>(*ppb)) > kImplausiblePpm)
    return {"clock drift", value, "implausible: is rate_hz the interface's rate?", true};
  if (synced && !*synced)
    return turning
               ? CheckRow{"clock drift", value, "the sync pulse did not lock: wiring, level or sync_angle_deg?", true}
               : CheckRow{"clock drift", value, "sync not checked: it locks when the engine turns", false};
  return {"clock drift", value, "ok", false};
}

std::vector<CheckRow> driver_rows(const CapturedStreams& s, bool can_configured, bool turning) {
  std::vector<CheckRow> rows;
  if (can_configured) {
    char value[64];
    std::snprintf(value, sizeof value, "%zu operating points, last %.0f rpm", s.operating_points, s.last_speed_rpm);
    const bool none = s.operating_points == 0;
    rows.push_back({"CAN", value, none ? "no frames decoded: bus, bitrate or signal map?" : "ok", none});
  }
  for (const auto& c : s.counters) {
    const bool error_count = c.name.find("error") != std::string::npos || c.name.find("overrun") != std::string::npos ||
                             c.name.find("lost") != std::string::npos;
    if (error_count && c.value > 0) rows.push_back({c.name, std::to_string(c.value), "errors during the check", true});
  }
  if (s.mic_gaps > 0) rows.push_back({"microphone stream", std::to_string(s.mic_gaps) + " gaps", "overruns", true});
  rows.push_back(clock_row(s, turning));
  return rows;
}

}  // namespace

std::vector<CheckRow> check_measurement_chain(const daemon::Config& config, double seconds, const SourceMaker& make) {
  const CapturedStreams streams = capture_streams(config, seconds, 0.5, daemon::PressureClock::kEncoder, make);
  std::optional<CapturedStreams> rest;
  if (needs_rest_capture(streams)) {
    std::fprintf(stderr, "check: no pressure with the engine stopped: %.0f s more with it on the card's timer\n",
                 kRestSeconds);
    rest = capture_streams(config, kRestSeconds, 0.5, daemon::PressureClock::kAtRest, make);
  }
  std::vector<CheckRow> rows = microphone_rows(streams);
  for (CheckRow& r : pressure_and_encoder_rows(streams, rest ? &*rest : nullptr, charge_chain(config)))
    rows.push_back(std::move(r));
  for (CheckRow& r : driver_rows(streams, config.can.configured(), engine_cycles_seen(streams) > 0))
    rows.push_back(std::move(r));
  return rows;
}

}  // namespace noisemon::cli
