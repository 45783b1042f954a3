// The processing thread's work, without the thread: align the pressure and microphone streams by their grid
// index, run the block model on the pressure, cut engine cycles at crank angle -360 deg (firing TDC in the
// middle of each 720-deg cycle), and turn each cycle into band levels, A-weighted overall levels, sound power
// and attenuation curves.
//
// Alignment: combined frame n holds pressure(n), the model's prediction for instant n, and microphone frame
// n + d, where d is the acoustic delay in frames (sound radiated at n reaches the microphones at n + d).
// All channels then pass through one 1/3-octave bank, so every channel sees the same filter delays.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "daemon/cycle_report.hpp"
#include "daemon/frame_fifo.hpp"
#include "drivers/source.hpp"
#include "dsp/third_octave_bank.hpp"
#include "model/block_model.hpp"
#include "model/combustion_metrics.hpp"

namespace noisemon::daemon {

struct ProcessorConfig {
  model::BlockParams model;
  double acoustic_delay_s = -1;  // < 0: take the source's StreamInfo::acoustic_delay_s
  double fifo_seconds = 4.0;     // how far one stream may run ahead of another before data is discarded
  model::EngineGeometry engine;  // for the combustion metrics (default: the Yanmar L100V, as the virtual engine)
  model::MetricsOptions metrics;
};

struct ProcessorCounters {
  std::int64_t cycles_completed = 0;  // reported + dropped
  std::int64_t cycles_dropped = 0;    // not reported: samples were lost in them
  std::int64_t frames_processed = 0;
  std::int64_t gap_frames = 0;        // frames filled in because blocks were lost, or skipped after a stall
  std::int64_t frames_discarded = 0;  // frames pushed out unconsumed: one stream ran fifo_seconds ahead of another
};

class CycleProcessor {
 public:
  using Sink = std::function<void(const CycleReport&)>;

  CycleProcessor(const ProcessorConfig& config, const drivers::StreamInfo& info, Sink sink);
  ~CycleProcessor();

  void add_pressure(const drivers::SampleBlock& block);
  void add_mics(const drivers::SampleBlock& block);
  void set_operating_point(const drivers::OperatingPoint& op);
  // Processes every combined frame whose inputs have all arrived; calls the sink once per completed cycle.
  void process();

  const ProcessorCounters& counters() const { return counters_; }
  const std::vector<dsp::ThirdOctaveBand>& bands() const { return bank_.bands(); }
  std::int64_t delay_frames() const { return delay_frames_; }

 private:
  void predict(std::int64_t first, const drivers::SampleBlock& block);
  void flush_chunk();
  void finish_cycle(std::int64_t end_index);

  ProcessorConfig config_;
  drivers::StreamInfo info_;
  Sink sink_;
  std::size_t mics_;
  std::int64_t delay_frames_;

  model::BlockModel model_;
  std::int64_t model_latency_;
  FrameFifo pressure_;   // pressure, crank
  FrameFifo predicted_;  // model output, indexed by the instant it describes
  FrameFifo mics_fifo_;
  std::vector<double> model_in_, model_out_;
  bool model_primed_ = false;

  dsp::ThirdOctaveBank bank_;  // channels: pressure, predicted, mic 1..M
  std::vector<double> chunk_;  // combined frames waiting for the bank
  std::size_t chunk_frames_ = 0;
  std::vector<double> mean_square_;

  std::int64_t next_ = INT64_MIN;        // next combined frame to process
  double last_crank_ = 0;
  bool have_last_crank_ = false;
  std::int64_t cycle_start_ = INT64_MIN;  // INT64_MIN until the first boundary
  std::int64_t settle_from_ = INT64_MIN;  // start of the stretch of continuous data (start or last gap)
  struct Gap { std::int64_t from, to; };  // combined-frame interval affected by lost samples
  std::vector<Gap> gaps_;
  void note_gap(std::int64_t from, std::int64_t to);
  // The cycle's pressure on a uniform crank-angle grid (kGridStepDeg from -360), for the combustion metrics.
  void grid_pressure(double crank_deg, double pressure_pa);
  std::vector<double> grid_;            // NaN where no frame has reached yet
  double grid_last_deg_ = 0, grid_last_pa_ = 0;
  bool grid_has_last_ = false;
  double last_duration_s_ = 0;
  drivers::OperatingPoint op_;
  bool have_op_ = false;
  double cpu_spent_s_ = 0;  // CPU time spent in add_*/process since the last cycle was finished
  struct CpuScope;
  ProcessorCounters counters_;
};

}  // namespace noisemon::daemon
