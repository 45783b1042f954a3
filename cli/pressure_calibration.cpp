#include "cli/pressure_calibration.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/config_edit.hpp"
#include "cli/source_capture.hpp"
#include "daemon/calibration_history.hpp"
#include "daemon/config.hpp"

namespace noisemon::cli {
namespace {

constexpr double kMaxReadingSdBar = 0.1;      // steadier than this, or the reference (or the chain) is not settled
constexpr double kMinGainReferenceBar = 5.0;  // below, the zero's uncertainty weighs on the slope
constexpr double kTurningRpm = 1.0;           // an operating point faster than this: the engine turns
constexpr double kWarnGainChange = 0.02;      // a sensitivity that moved more: check the transducer first
constexpr double kPressureSettleS = 0.5;      // the source's start, left out
constexpr const char* kTable = "comedi.pressure";

// The chain [comedi.pressure] describes: where its sensitivity is written, and whether it has an absolute zero.
struct Chain {
  const char* key;
  const char* unit;
  double sensitivity;
  bool charge;
};

Chain configured_chain(const daemon::Config& c) {
  if (c.source != "sim" && c.source != "comedi")
    throw std::invalid_argument("calibrate --pressure: the pressure comes from " + c.source +
                                " (another process's stream): calibrate on the cell whose card samples it");
  const auto& p = c.comedi.pressure;
  if ((p.sensitivity_mv_per_bar > 0) == (p.sensitivity_pc_per_bar > 0))
    throw std::invalid_argument(
        "calibrate --pressure: [comedi.pressure] must set either sensitivity_mv_per_bar (a voltage-output chain) or "
        "sensitivity_pc_per_bar (a charge chain): the calibration is written there");
  if (p.sensitivity_mv_per_bar > 0) return {"sensitivity_mv_per_bar", "mV/bar", p.sensitivity_mv_per_bar, false};
  return {"sensitivity_pc_per_bar", "pC/bar", p.sensitivity_pc_per_bar, true};
}

// Checked before anything is measured: what the chain and the reference allow.
void check_request(const PressureCalibration& r, const Chain& chain) {
  char what[512];
  if (!r.gain && chain.charge)
    throw std::invalid_argument(
        "calibrate --pressure: a charge chain (sensitivity_pc_per_bar behind a charge amplifier) has no absolute zero: "
        "the amplifier drifts and is reset, so a zero taken now would not hold. Reference it every cycle instead, by "
        "pegging ([comedi.pressure] peg_pa) or at TDC; its gain can be calibrated (--gain)");
  if (r.gain && r.reference_bar < kMinGainReferenceBar) {
    std::snprintf(
        what, sizeof what,
        "calibrate --pressure --gain: --reference-bar %g is below %.0f bar: a gain needs a dead-weight tester "
        "or reference transducer well above the zero",
        r.reference_bar, kMinGainReferenceBar);
    throw std::invalid_argument(what);
  }
}

std::string number_text(double v, const char* format) {
  char text[64];
  std::snprintf(text, sizeof text, format, v);
  return text;
}

struct Reading {
  double mean_bar = 0.0, sd_bar = 0.0;
  std::size_t samples = 0;
};

// The pressure over `seconds` with the engine stopped, sampled on the card's timer (PressureClock::kAtRest); refused
// when the engine turns (cycles on the crank angle, or a speed from the encoder's edges or CAN) or the reading is not
// steady.
Reading steady_reading(const daemon::Config& config, double seconds, const SourceMaker& make) {
  const CapturedStreams s = capture_streams(config, seconds, kPressureSettleS, daemon::PressureClock::kAtRest, make);
  char what[512];
  if (const std::size_t cycles = engine_cycles_seen(s); cycles > 0 || s.max_speed_rpm > kTurningRpm) {
    std::snprintf(what, sizeof what,
                  "calibrate --pressure: the engine is turning (%zu cycles, %.0f rpm while measuring): the pressure "
                  "chain is calibrated with the engine stopped and the cylinder at a steady, known pressure",
                  cycles, s.max_speed_rpm);
    throw std::runtime_error(what);
  }
  const auto skip = static_cast<std::size_t>(kPressureSettleS * drivers::kPipelineRateHz);
  double sum = 0, sum2 = 0;
  Reading r;
  for (std::size_t k = skip; k < s.pressure_pa.size(); ++k)
    if (const double bar = 1e-5 * s.pressure_pa[k]; std::isfinite(bar)) sum += bar, sum2 += bar * bar, ++r.samples;
  if (r.samples == 0)
    throw std::runtime_error("calibrate --pressure: no pressure samples arrived from " + config.source + " in " +
                             number_text(seconds, "%.0f") +
                             " s: is the pressure channel configured ([comedi.pressure] device, subdevice, channel) "
                             "and the source delivering?");
  r.mean_bar = sum / static_cast<double>(r.samples);
  r.sd_bar = std::sqrt(std::max(0.0, sum2 / static_cast<double>(r.samples) - r.mean_bar * r.mean_bar));
  if (r.sd_bar > kMaxReadingSdBar) {
    std::snprintf(what, sizeof what,
                  "calibrate --pressure: the reading is not steady: its standard deviation over %.0f s is %.3f bar "
                  "(more than %.1f bar). Let the reference settle (a dead-weight tester's piston floating, no leak), "
                  "check the chain's noise, and measure again",
                  seconds, r.sd_bar, kMaxReadingSdBar);
    throw std::runtime_error(what);
  }
  return r;
}

// What one calibration writes: the edits, and the history's row.
struct Result {
  std::vector<TomlEdit> edits;
  daemon::CalibrationRecord record;
  double offset_bar = 0.0, sensitivity = 0.0;
};

// The zero: the offset that makes the chain read the reference now.
Result zero_calibration(const daemon::Config& config, const Chain& chain, const Reading& m, double reference_bar) {
  const double old_offset = config.comedi.pressure.offset_bar;
  Result r;
  r.offset_bar = old_offset + (m.mean_bar - reference_bar);
  r.sensitivity = chain.sensitivity;
  r.edits = {{kTable, "offset_bar", number_text(r.offset_bar, "%.5f")}};
  std::printf("zero: the chain read %.4f bar at the reference %.4f bar: offset_bar %.5f -> %.5f bar\n", m.mean_bar,
              reference_bar, old_offset, r.offset_bar);
  r.record.pressure_step = "zero";
  return r;
}

// The gain, against the latest zero: the reading's rise above the zero's reference over the reference's. A voltage
// chain's offset is rescaled with it (it is subtracted in bar of the reading) so that the zero still holds; a charge
// chain reads from its amplifier's reset, its zero 0 bar.
Result gain_calibration(const daemon::Config& config, const Chain& chain, const Reading& m, double reference_bar,
                        const std::vector<daemon::CalibrationRecord>& history) {
  double zero_bar = 0.0;
  if (!chain.charge) {
    const daemon::CalibrationRecord* z = daemon::last_pressure_calibration(history, "zero");
    if (!z)
      throw std::runtime_error(
          "calibrate --pressure --gain: the history holds no zero of the pressure chain: zero it first, at ambient "
          "(noisemon calibrate --pressure --reference-bar <barometer reading>)");
    zero_bar = z->reference_bar;
    std::printf("against the zero of %s at %.4f bar\n", daemon::calibration_date(z->utime).c_str(), zero_bar);
  }
  const double old_offset = config.comedi.pressure.offset_bar;
  const double ratio = (m.mean_bar - zero_bar) / (reference_bar - zero_bar);
  if (!(ratio > 0.5 && ratio < 2.0))
    throw std::runtime_error("calibrate --pressure --gain: the chain read " + number_text(m.mean_bar, "%.3f") +
                             " bar at " + number_text(reference_bar, "%.3f") +
                             " bar: not a gain error (is the reference connected, the chain zeroed?)");
  Result r;
  r.sensitivity = chain.sensitivity * ratio;
  r.offset_bar = chain.charge ? old_offset : (zero_bar + old_offset) / ratio - zero_bar;
  r.edits = {{kTable, chain.key, number_text(r.sensitivity, "%.7g")}};
  if (!chain.charge) r.edits.push_back({kTable, "offset_bar", number_text(r.offset_bar, "%.5f")});
  std::printf("gain: the chain read %.4f bar at the reference %.4f bar: %s %.5g -> %.5g %s (%+.2f %%)", m.mean_bar,
              reference_bar, chain.key, chain.sensitivity, r.sensitivity, chain.unit, 100.0 * (ratio - 1.0));
  if (!chain.charge) std::printf(", offset_bar %.5f -> %.5f bar", old_offset, r.offset_bar);
  std::printf("\n");
  if (std::abs(ratio - 1.0) > kWarnGainChange)
    std::fprintf(stderr,
                 "calibrate: warning: the pressure chain's sensitivity moved %+.1f %% from the configured value: check "
                 "the transducer, its cable and the amplifier's setting before trusting it\n",
                 100.0 * (ratio - 1.0));
  r.record.pressure_step = "gain";
  r.record.change_db = 20.0 * std::log10(ratio);
  return r;
}

}  // namespace

int calibrate_pressure(const PressureCalibration& request, const SourceMaker& make) {
  const daemon::Config config = daemon::load_config(request.config_path);
  const Chain chain = configured_chain(config);
  check_request(request, chain);
  const std::string history = request.history_path.empty() ? config.calibration_history : request.history_path;
  const std::vector<daemon::CalibrationRecord> rows = daemon::read_calibration_history(history);
  std::fprintf(stderr, "calibrate: measuring the pressure chain for %.0f s (%s)\n", request.seconds,
               config.source.c_str());
  const Reading m = steady_reading(config, request.seconds, make);
  std::printf("pressure chain: %.5f bar, standard deviation %.4f bar over %zu samples (the mean to +-%.5f bar)\n",
              m.mean_bar, m.sd_bar, m.samples, m.sd_bar / std::sqrt(static_cast<double>(m.samples)));
  Result r = request.gain ? gain_calibration(config, chain, m, request.reference_bar, rows)
                          : zero_calibration(config, chain, m, request.reference_bar);
  if (request.dry_run) return 0;
  edit_config_file(request.config_path, r.edits, [&](const daemon::Config& c) {
    const Chain written = configured_chain(c);
    return std::abs(written.sensitivity - r.sensitivity) <= 1e-6 * r.sensitivity &&
           std::abs(c.comedi.pressure.offset_bar - r.offset_bar) <= 1e-5;
  });
  r.record.utime = drivers::wall_utime();
  r.record.serial = request.serial;
  r.record.sensitivity = r.sensitivity;
  r.record.reference_bar = request.reference_bar;
  r.record.offset_bar = r.offset_bar;
  daemon::append_calibration(history, r.record);
  std::string keys;
  for (const TomlEdit& e : r.edits) keys += (keys.empty() ? "" : ", ") + e.key;
  std::printf("written: %s ([%s] %s), %s\n", request.config_path.c_str(), kTable, keys.c_str(), history.c_str());
  return 0;
}

}  // namespace noisemon::cli
