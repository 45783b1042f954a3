// The processing thread's work, without the thread: align the pressure and microphone streams by their grid
// index, run the block model on the pressure, cut engine cycles at crank angle -360 deg (firing TDC in the
// middle of each 720-deg cycle), and turn each cycle into band levels, A-weighted overall levels, sound power
// and attenuation curves.
//
// Alignment: combined frame n holds pressure(n), the model's prediction for instant n, and microphone frame
// n + d, where d is the acoustic delay in frames (sound radiated at n reaches the microphones at n + d).
// All channels then pass through one 1/3-octave bank, so every channel sees the same filter delays.
//
// Faulty channels degrade the report, never the processing: a non-finite pressure sample is replaced by the last
// finite pressure before the block model and the bank (a NaN would stay in their IIR states for ever), a
// non-finite microphone sample by 0. Each cycle judges every channel (flat, overloaded, replaced samples; a
// microphone also far below the others): a faulty microphone is left out of the measured levels, a faulty
// pressure makes the cycle's CPL, predictions, attenuation and combustion metrics NaN. A frame whose crank angle
// is NaN (not known) is never a cycle boundary and never on the combustion-metrics grid. See the CYCLE_* and
// MIC_* flags in msgs/cycle_report_t.lcm.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include "daemon/angle_cycles.hpp"
#include "daemon/crank_grid.hpp"
#include "daemon/crank_windows.hpp"
#include "daemon/cycle_report.hpp"
#include "daemon/frame_fifo.hpp"
#include "daemon/sound_power_setup.hpp"
#include "drivers/source.hpp"
#include "dsp/third_octave_bank.hpp"
#include "model/block_model.hpp"
#include "model/combustion_metrics.hpp"
#include "model/combustion_noise.hpp"

namespace noisemon::daemon {

struct ProcessorConfig {
  model::BlockParams model;
  double acoustic_delay_s = -1;  // < 0: take the source's StreamInfo::acoustic_delay_s
  double fifo_seconds = 4.0;     // how far one stream may run ahead of another before data is discarded
  model::EngineGeometry engine;  // for the combustion metrics (default: the Yanmar L100V, as the virtual engine)
  model::MetricsOptions metrics;
  // A microphone whose A-weighted level (mic_lpa_db) lies more than this below the median level of the microphones
  // that are not flat, overloaded or NaN is left out of the measured levels (MIC_LOW): an unplugged microphone reads
  // only its converter's noise. With two microphones the median is their mean in dB: one of them is left out only
  // when they differ by more than twice this.
  double mic_low_db = 20.0;
  SoundPowerConfig sound_power;  // K1 (background), K2, the surface check
  // How the microphones make the measured band levels: false, an energy mean of their band levels (area-weighted; an
  // excluded microphone left out); true, the band levels of their (area-weighted) mean time history, as the thesis
  // averaged them before its spectra (Table 4.1's presets were tuned on that): sound that differs in phase between
  // the positions partly cancels, and so does uncorrelated noise. An excluded microphone stays in the time mean
  // (a cycle's exclusion is decided after its samples went through the filters); its flags still show.
  bool time_average_mics = false;
};

struct ProcessorCounters {
  std::int64_t cycles_completed = 0;  // reported + dropped
  std::int64_t cycles_dropped = 0;    // not reported: samples were lost in them
  std::int64_t frames_processed = 0;
  std::int64_t gap_frames = 0;            // frames filled in because blocks were lost, or skipped after a stall
  std::int64_t frames_discarded = 0;      // frames pushed out unconsumed: one stream ran fifo_seconds ahead of another
  std::int64_t samples_replaced = 0;      // non-finite pressure or microphone samples replaced before the filters
  std::int64_t crank_unknown_frames = 0;  // frames whose crank angle was NaN (encoder fault, before a resync)
};

class CycleProcessor {
 public:
  using Sink = std::function<void(const CycleReport&)>;

  CycleProcessor(const ProcessorConfig& config, const drivers::StreamInfo& info, Sink sink);
  ~CycleProcessor();

  void add_pressure(const drivers::SampleBlock& block);
  void add_mics(const drivers::SampleBlock& block);
  // The crank-angle stream (drivers::kAngleStreamChannels), when the source's info has pressure_angle_step_deg > 0:
  // the combustion figures then come from its edges, and a cycle boundary is processed only once an edge beyond it
  // has arrived (or end_of_streams() said none will).
  void add_pressure_angle(const drivers::SampleBlock& block);
  // The streams have ended (a log is exhausted, the drivers have stopped): process() no longer waits for edges.
  void end_of_streams() { streams_ended_ = true; }
  void set_operating_point(const drivers::OperatingPoint& op);
  // Processes every combined frame whose inputs have all arrived; calls the sink once per completed cycle.
  void process();

  // Times the calls made while it is open with one pair of CPU-clock reads (each a system call) instead of a
  // pair per call: the processing thread opens one around each batch of blocks it feeds and processes.
  class CpuBatch {
   public:
    explicit CpuBatch(CycleProcessor& p);
    ~CpuBatch();
    CpuBatch(const CpuBatch&) = delete;
    CpuBatch& operator=(const CpuBatch&) = delete;

   private:
    CycleProcessor& p_;
    double start_;
  };

  const ProcessorCounters& counters() const { return counters_; }
  const std::vector<dsp::ThirdOctaveBand>& bands() const { return bank_.bands(); }
  std::int64_t delay_frames() const { return delay_frames_; }
  const SoundPowerSetup& sound_power() const { return sound_power_; }

 private:
  // Per-cycle health of one channel (0: pressure, 1 + m: microphone m), over the values the bank sees.
  struct ChannelStats {
    double min, max;
    std::int64_t replaced;  // non-finite samples replaced
    bool overload;
  };
  struct CycleHealth {
    bool pressure_fault = false;
    bool overload = false;
    std::int8_t mic_flags[kMaxMics] = {};  // kMicFlat, kMicOverload, kMicNan
  };

  std::uint32_t sanitise_pressure(const drivers::SampleBlock& block);
  void feed_held_to_model(std::int64_t from, std::int64_t to);
  void run_model(std::int64_t first, std::size_t n);  // input in model_in_[0, n)
  void flush_chunk();
  void unknown_crank();
  void close_cycle(double crank_deg, double pressure_pa);
  void add_frame(const double* pressure_frame);
  void reset_stats();
  CycleHealth take_health(std::int64_t start, std::int64_t end_index);
  model::CombustionMetrics take_combustion(std::int64_t start, std::int64_t end_index, bool wanted, bool& angle_gap);
  bool take_gaps(std::int64_t start, std::int64_t end_index);
  void count_dropped(double duration_s);
  void finish_cycle(std::int64_t end_index);
  void mic_levels(CycleReport& r) const;
  void select_mics(CycleReport& r) const;
  struct PassbandLimits {
    double pressure_hz = std::numeric_limits<double>::infinity();
    double mic_hz = std::numeric_limits<double>::infinity();
  };
  PassbandLimits passband_limits(double duration_s) const;
  void band_levels(CycleReport& r, double settled_s, bool pressure_fault) const;
  void window_levels(CycleReport& r, bool pressure_fault) const;
  std::int8_t band_flags(std::size_t b, double duration_s, double settled_s) const;
  // The measured band's mean square (unweighted): the area-weighted energy mean over the microphones used.
  double measured_mean_square(const CycleReport& r, std::size_t b) const;

  ProcessorConfig config_;
  drivers::StreamInfo info_;
  Sink sink_;
  std::size_t mics_;
  std::size_t bank_channels_;  // pressure, predicted, mic 1..M, and with time_average_mics their mean
  std::int64_t delay_frames_;

  model::BlockModel model_;
  std::int64_t model_latency_;
  FrameFifo pressure_;         // pressure (non-finite replaced), crank, 1 where the pressure was replaced
  FrameFifo predicted_;        // model output, indexed by the instant it describes
  FrameFifo mics_fifo_;        // as received (non-finite samples are replaced on their way to the bank)
  std::vector<double> clean_;  // a pressure block as the FIFO holds it
  std::vector<double> model_in_, model_out_, model_prime_;
  bool model_primed_ = false;
  double last_finite_pressure_ = 0;
  bool have_finite_pressure_ = false;  // until then, non-finite pressure is not data: the stream has not begun

  dsp::ThirdOctaveBank bank_;  // channels: pressure, predicted, mic 1..M
  SoundPowerSetup sound_power_;
  std::vector<double> a_gain_;  // A-weighting per band as a mean-square factor
  std::vector<double> chunk_;   // combined frames waiting for the bank
  std::size_t chunk_frames_ = 0;
  std::vector<double> mean_square_;
  CrankWindows windows_;    // A-weighted prediction and microphones per crank window (out[1 ...] of a frame)
  std::size_t window_ = 0;  // the crank window of the frames being added
  std::vector<ChannelStats> stats_;
  // Per channel: one past the last combined frame whose sample was replaced. The bank's filters ring after the
  // replaced stretch: the channel stays faulty into the next cycle while its non-slow bands have not settled.
  std::vector<std::int64_t> replaced_until_;
  double pressure_overload_pa_, mic_overload_pa_;  // 0.99 of the full scales; +inf when not known

  std::int64_t next_ = INT64_MIN;  // next combined frame to process
  double last_crank_ = 0;          // the last known crank angle
  bool have_last_crank_ = false;
  bool crank_unknown_ = false;            // NaN crank angles since last_crank_
  bool cycle_encoder_ = false;            // the current cycle had unknown angles or started after them
  std::int64_t cycle_start_ = INT64_MIN;  // INT64_MIN until the first boundary
  std::int64_t settle_from_ = INT64_MIN;  // start of the stretch of continuous data (start or last gap)
  struct Gap {
    std::int64_t from, to;
  };  // combined-frame interval affected by lost samples
  std::vector<Gap> gaps_;
  void note_gap(std::int64_t from, std::int64_t to);
  // The cycle's pressure on a uniform crank-angle grid, for the combustion metrics: from the crank-angle stream's
  // edges when the source has one, else from the 40 kHz frames (a kGridStepDeg grid).
  CrankGrid* combustion_grid(std::int64_t start, std::int64_t end_index, bool& angle_gap);
  CrankGrid frame_grid_;                // NaN where no frame has reached yet
  std::unique_ptr<AngleCycles> angle_;  // the crank-angle stream's cycles (nullptr: the source has none)
  bool angle_abandoned_ = false;        // none came while kAngleWaitFrames of pressure did: the frames' grid
  bool streams_ended_ = false;
  std::int64_t angle_end(std::int64_t end);
  model::MetricsWorkspace metrics_scratch_;  // sized by the first cycle, reused: no allocation per cycle
  double last_duration_s_ = 0;               // of the last reported cycle without kCycleEncoder
  drivers::OperatingPoint op_;
  bool have_op_ = false;
  double cpu_spent_s_ = 0;       // CPU time spent in add_*/process since the last cycle was finished
  bool cpu_batch_open_ = false;  // a CpuBatch times the calls
  struct CpuScope;
  ProcessorCounters counters_;
};

}  // namespace noisemon::daemon
