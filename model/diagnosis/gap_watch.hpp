// The live gap watch (noisemon gapwatch): the sim-to-real gap watched cycle by cycle while the engine runs, a
// change detected as it happens, its onset located and its cause named (change_attribution.hpp).
//
// Features of a cycle: per 1/3-octave band the gap measured - predicted (dB(A)), per microphone its offset from the
// array's energy mean, the overall gap, and per crank window the gap of its A-weighted levels (when reported). Cycles
// are averaged in blocks of `block_cycles` consecutive usable cycles at one operating point (cycle-to-cycle scatter and
// the slow bands' smearing average out; a block's spread is measured, not assumed).
//
// Reference: per operating point (speed, load, SOI within tolerances, motored or fired) the first `reference_s`
// engine seconds of blocks give each feature's mean and block-to-block standard deviation (and the levels the
// attribution starts from). An operating point first met later learns its own reference the same way (an effect
// already present then becomes its normal); a reference can also be loaded (saved earlier, or learnt from a log).
//
// Detection: per operating point and feature, a two-sided CUSUM (dsp/cusum.hpp) on the standardised block means,
// k = half the smallest shift to detect (`min_shift_db` over the feature's spread), h from the target time between
// false alarms over the whole watch (`false_alarm_hours` of engine running, shared by every feature and side:
// Bonferroni). Operating-point changes move to another reference, never count as a change of the gap.
//
// An alarm opens an event: `after_blocks` more blocks are gathered at the alarm's operating point, then the change
// (the cycles from the onset on against the reference) is attributed, the event emitted, and that operating
// point's reference learnt afresh (the changed state is the new normal; a drift that goes on fires again).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "dsp/cusum.hpp"
#include "model/diagnosis/change_attribution.hpp"
#include "model/diagnosis/steady_state.hpp"

namespace noisemon::model::diagnosis {

inline constexpr double kNoValue = std::numeric_limits<double>::quiet_NaN();

// What the watch reads of one cycle report (the tool converts noisemon.cycle_report_t).
struct CycleGap {
  std::int64_t cycle = 0;
  double time_s = 0.0;  // the reports' own clock (utime), s
  double speed_rpm = 0.0, load_nm = 0.0, soi_deg_btdc = 0.0;
  bool motored = false;
  bool usable = true;           // no fault flag: settling, gap, encoder, pressure fault, overload ...
  std::vector<double> band_hz;  // nominal centres
  std::vector<double> measured_db, predicted_db, cpl_db;  // per band; NaN where the band says nothing
  std::vector<double> mic_db;                             // per microphone, dB(A); NaN when flagged
  double overall_measured_db = kNoValue, overall_predicted_db = kNoValue;
  std::vector<double> window_measured_db, window_predicted_db;  // per crank window, dB(A); empty: not reported
};

struct GapWatchOptions {
  double reference_s = 120.0;  // engine seconds of each operating point's reference
  std::size_t block_cycles = 16;
  double false_alarm_hours = 8.0;      // mean engine time between false alarms, over every feature
  double min_shift_db = 1.0;           // smallest shift to detect
  double sigma_floor_db = 0.05;        // a feature's block spread is never taken below this
  std::size_t after_blocks = 8;        // gathered after an alarm before the attribution
  std::size_t history_cycles = 60000;  // cycles kept for an onset far back (a slow drift)
  double speed_tolerance_rpm = 60.0;   // one operating point: within these of its centre
  double load_tolerance_nm = 2.0;
  double soi_tolerance_deg = 1.0;
  SteadyStateOptions steady;                   // cycles in and near a change of operating point are not watched
  double pressure_edge_rate_per_rev = 3600.0;  // encoder edges per revolution (transducer_noise in bar)
  AttributionOptions attribution;
};

// One feature's reference at an operating point.
struct FeatureReference {
  double mean = kNoValue;   // of the block means
  double sigma = kNoValue;  // block-to-block standard deviation
  std::size_t blocks = 0;
};

struct OperatingPointReference {
  double speed_rpm = 0.0, load_nm = 0.0, soi_deg_btdc = 0.0;
  bool motored = false;
  std::vector<FeatureReference> features;  // bands, microphones, overall, crank windows
  // Mean levels over the reference (the attribution's "before"), dB.
  std::vector<double> measured_db, predicted_db, cpl_db, mic_db, window_db;
  std::size_t cycles = 0;
};

struct GapReference {
  std::vector<double> band_hz;
  std::size_t mics = 0;
  std::size_t windows = 0;  // crank windows of the reports (0: none)
  std::vector<OperatingPointReference> points;
};

struct GapEvent {
  std::string effect;  // a candidate of change_attribution.hpp, or "unexplained"
  std::vector<std::pair<std::string, double>> params;
  double confidence = 0.0;
  std::string kind = "step";           // "step" or "drift" (a shift growing linearly from the onset)
  double drift_db_per_min = kNoValue;  // a drift's rate on the first feature that fired
  std::int64_t onset_cycle = 0, detected_cycle = 0;
  double onset_s = 0.0, detected_s = 0.0;  // since the first cycle report, on the reports' clock
  // The overall A-weighted gap measured - predicted over the watched bands (their energies summed), dB: the reference's
  // and the cycles' from the onset on.
  double gap_before_db = 0.0, gap_after_db = 0.0;
  std::vector<std::string> features;  // those that fired, e.g. "band 2000 Hz +", "mic 4 +", "overall -"
  double speed_rpm = 0.0, load_nm = 0.0, soi_deg_btdc = 0.0;
  bool motored = false;
  GapChange change;  // the evidence
  Attribution attribution;
};

class GapWatch {
 public:
  explicit GapWatch(const GapWatchOptions& options);
  // A reference to start from (loaded or learnt from a log): its operating points are watched from the start.
  void set_reference(const GapReference& reference);
  const GapReference& reference() const { return reference_; }

  // Completes the reference of every operating point still learning (a reference log read to its end); a point
  // with fewer than four blocks stays unlearnt.
  void finish_learning();

  // Encoder edges per revolution of the pressure (a session message says it): transducer_noise in bar.
  void set_pressure_edges_per_rev(double edges) { options_.pressure_edge_rate_per_rev = edges; }

  // One cycle report, in order; events complete as their evidence does. A cycle is taken once steady.after_s of
  // later reports tell whether its operating point held (steady_state.hpp).
  void add(const CycleGap& report);
  // The reports have ended: the cycles waiting for their steadiness to be known are taken on what came.
  void flush();
  std::function<void(const GapEvent&)> on_event;

  // State for the operators' views.
  std::size_t watched_features() const;
  double seconds_since_first() const { return last_s_ - first_s_; }
  double reference_seconds() const;        // of the current operating point's reference (0: learning)
  double since_reference_seconds() const;  // engine seconds since it was complete (0: learning)
  bool learning() const;                   // the current operating point's reference is not complete
  std::int64_t cycles() const { return cycles_; }
  std::int64_t blocks() const { return blocks_; }
  std::int64_t transient_cycles() const { return transient_cycles_; }  // left out: the operating point moved
  // CUSUM parameters at the current operating point (k, h of a band feature; NaN while learning).
  double current_h() const;

 private:
  // Sums over cycles: the features, then the levels (measured, predicted, CPL per band, microphones).
  struct Block {
    std::vector<double> sum;
    std::vector<std::size_t> count;
    std::size_t cycles = 0;
    std::int64_t first_cycle = 0;
    double first_s = 0.0, seconds = 0.0;
    void reset(std::size_t n);
    void add(const std::vector<double>& values, double cycle_s);
    double mean(std::size_t i, std::size_t min_count = 1) const;
  };
  struct PointState {
    bool learning = true;
    double learnt_s = 0.0;
    std::vector<std::vector<double>> block_means;  // per feature, while learning
    Block levels;                                  // per cycle, while learning
    std::vector<dsp::Cusum> cusum;                 // per feature
    std::vector<char> watched;
  };
  void take(CycleGap cycle);
  void start_layout(const CycleGap& cycle);
  std::size_t find_point(const CycleGap& cycle) const;  // SIZE_MAX: none
  std::size_t point_of(const CycleGap& cycle);
  void close_block();
  void learn(std::size_t point, std::int64_t index);
  void finish_reference(std::size_t point);
  void arm(std::size_t point);
  void watch(std::size_t point, std::int64_t index);
  void open_event(std::size_t point, std::int64_t onset_block, std::size_t feature, int side);
  void refine_onset();
  void complete_event();
  void add_speed_law(GapEvent& event);
  std::string feature_name(std::size_t f, int side) const;
  double watched_sigma(const FeatureReference& feature) const;
  std::vector<double> features_of(const CycleGap& cycle) const;

  GapWatchOptions options_;
  GapReference reference_;
  std::vector<PointState> points_;
  SteadyStateGate steady_;
  std::deque<CycleGap> pending_;  // waiting for the gate's decision
  std::int64_t transient_cycles_ = 0;
  std::deque<CycleGap> history_;            // its cycle: the watch's own count
  std::deque<std::int64_t> report_cycles_;  // the reports' cycle numbers, beside it
  Block block_;
  std::size_t block_point_ = SIZE_MAX;
  std::deque<std::pair<std::int64_t, double>> block_starts_;  // first cycle and time of the recent blocks
  std::int64_t block_starts_base_ = 0;                        // block index of block_starts_.front()
  std::size_t current_point_ = SIZE_MAX;
  bool layout_ = false;
  double first_s_ = 0.0, last_s_ = 0.0;
  std::int64_t last_cycle_ = 0;
  std::vector<std::int64_t> watched_from_;  // per point: the cycle its reference was complete
  std::vector<double> watched_from_s_;      // and its time
  std::int64_t cycles_ = 0, blocks_ = 0;
  std::vector<std::pair<double, double>> structural_gains_;  // speed (rpm) and gain (dB) of speed_dependence events
  // The open event.
  bool open_ = false;
  std::size_t event_point_ = 0, event_blocks_left_ = 0, event_blocks_seen_ = 0, event_feature_ = 0;
  GapEvent event_;
};

}  // namespace noisemon::model::diagnosis
