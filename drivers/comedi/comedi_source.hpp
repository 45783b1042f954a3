// The `comedi` source: the test cell's DAQ hardware through libcomedi.
//
// Wiring it expects (all subdevices stream: SDF_CMD):
//  - pressure: an analog input subdevice whose scans are clocked by the encoder's edge line (scan_begin
//    TRIG_EXT): one scan per encoder edge holding the pressure channel (and optionally a cam sensor channel);
//  - encoder: a counter subdevice clocked by the same edge line, each scan holding the position counter
//    (quadrature, reset by the once-per-revolution index) and a timebase counter latched at the edge (the
//    edge's time); the timestamp may also come from a second counter subdevice;
//  - microphones: an analog input subdevice on the card's timer (scan_begin TRIG_TIMER).
// With more than one encoder-clocked subdevice, wire the index line as their common start trigger
// (start_trigger) so scan n of each is the same edge.
//
// Driver threads: `comedi.encoder_pressure` polls the encoder-clocked subdevices together, pairs their scans
// and feeds the EdgeStreamAssembler (-> Streams::pressure), or at rest (at_rest) the timer-clocked pressure through
// the TimedStreamAssembler with the encoder's edges counted beside it; `comedi.microphones` feeds the
// TimedStreamAssembler (-> Streams::mics). Both run the same code whether the bytes come from the device's
// descriptor or, in tests, from a pipe: an Acquisition is anything with a descriptor, a sample width, per-channel
// conversions and start/restart/cancel. A buffer overrun (EPIPE) restarts the affected acquisition (the
// encoder-clocked ones together) after a backoff, and is counted; the stream resumes after a gap (the affected
// cycles are dropped downstream). The operating point does not come from here (see can_source.hpp).
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "drivers/comedi/comedi_device.hpp"
#include "drivers/comedi/comedi_streams.hpp"
#include "drivers/source.hpp"
#include "drivers/worker_thread.hpp"

namespace noisemon::drivers::comedi {

struct ComediSourceConfig {
  struct Pressure {
    std::string device = "/dev/comedi0";
    int subdevice = -1;         // -1: the device's default streaming read subdevice
    unsigned edge_trigger = 0;  // scan_begin_arg of the TRIG_EXT scan clock (the input wired to the encoder edge)
    int start_trigger = -1;     // >= 0: start on this external trigger (the index line); -1: start at once
    unsigned convert_src = TRIG_TIMER;
    ComediChannelConfig channel;          // si_per_volt is set from the sensitivity below
    double sensitivity_mv_per_bar = 0.0;  // voltage-output chain; or:
    double sensitivity_pc_per_bar = 0.0;  // charge-output transducer ...
    double amplifier_mv_per_pc = 0.0;     // ... behind a charge amplifier of this gain
    double offset_bar = 0.0;  // voltage-output chain: its zero error, subtracted after the conversion (what it reads
                              // above the reference at ambient; `noisemon calibrate --pressure` sets it)
    int cam_channel = -1;     // analog channel of the cam sensor (V), scanned after the pressure; -1: none
    unsigned cam_range = 0;
    unsigned cam_aref = AREF_GROUND;
    double peg_pa = 0.0;  // > 0: relative sensor, pegged to this pressure at peg_angle_deg every cycle
    double peg_angle_deg = -180.0;
    unsigned buffer_bytes = 0;           // > 0: the kernel acquisition buffer's size; 0: leave the driver's
    bool wake_every_scan = false;        // CMDF_WAKE_EOS: wake the driver thread after every scan
    double rest_scan_rate_hz = 40000.0;  // at_rest: the pressure channel's scan rate on the card's timer (whole Hz)
  } pressure;

  struct Encoder {
    std::string device = "/dev/comedi0";
    int subdevice = -1;  // the counter subdevice (required)
    unsigned edge_trigger = 0;
    int start_trigger = -1;
    unsigned convert_src = TRIG_NOW;
    unsigned position_channel = 0;
    int position_counter_mode = -1;  // comedi_set_counter_mode bits (card-specific), -1: leave as configured
    int timestamp_subdevice = -1;    // -1: the timestamp counter is on `subdevice`, scanned after the position
    unsigned timestamp_channel = 1;
    int timestamp_counter_mode = -1;
    TimestampMode timestamp_mode = TimestampMode::kAbsolute;
    double timebase_hz = 80e6;
    std::uint32_t timestamp_bits = 32;
    std::uint32_t counts_per_rev = 3600;
    double index_angle_deg = 0.0;       // crank angle of the index pulse, degrees after a TDC
    bool index_resets_counter = true;   // the index resets the position counter: each revolution's count is checked
    std::uint32_t counts_per_edge = 1;  // position counts between two clocking edges (4 for x4 decoding on one edge)
    double max_rpm = 0.0;               // the engine's highest speed (sizes the resampler); 0: any encoder
    unsigned buffer_bytes = 0;          // as for the pressure (also the separate timestamp subdevice's)
    bool wake_every_scan = false;
  } encoder;

  // The engine at rest (comedi_rest.hpp; `noisemon calibrate --pressure`, `noisemon check`): the pressure channel is
  // scanned on the card's timer at pressure.rest_scan_rate_hz instead of on the encoder's edges, and goes out as the
  // 40 kHz pressure stream with the crank angle NaN; the encoder's counter runs on its own (no timestamp subdevice),
  // its edges counted into operating points of speed only (0 at rest), every 100 ms. Never the daemon's mode.
  bool at_rest = false;

  PhaseSource phase = PhaseSource::kPressure;
  double cam_threshold_v = 2.5;
  double cam_edge_deg = 0.0;  // crank angle of the cam signal's rising edge (0 = firing TDC)

  struct Mics {
    std::string device = "/dev/comedi1";
    int subdevice = -1;
    double scan_rate_hz = 50000.0;                   // the settled rate must be a whole number of Hz
    std::vector<ComediChannelConfig> channels;       // si_per_volt set from the sensitivities
    std::vector<double> sensitivity_mv_per_pa;       // one per channel
    std::vector<std::array<double, 3>> positions_m;  // empty: thesis Table 3.1 (up to 10 microphones)
    double radius_m = 1.75;
    double speed_of_sound_m_s = 343.0;
    unsigned buffer_bytes = 0;
    bool wake_every_scan = false;
  } mics;

  std::chrono::microseconds initial_backoff{10000};
  std::chrono::microseconds max_backoff{1000000};
  unsigned max_consecutive_overruns = 16;

  // Start-up notes (each kernel buffer's size and the seconds it holds); empty: written to stderr.
  std::function<void(const std::string&)> log_info;

  // Scheduling of the driver threads nm-pressure (encoder and pressure) and nm-mics (the daemon's [threads]).
  struct Threads {
    ThreadPolicy pressure, mics;
  } threads;
};

// One streaming subdevice as the driver threads use it.
class Acquisition {
 public:
  virtual ~Acquisition() = default;
  virtual std::string where() const = 0;  // "<device> subdevice <n>"
  virtual int fd() const = 0;
  virtual SampleWidth sample_width() const = 0;
  virtual const std::vector<ChannelConversion>& conversions() const = 0;  // raw -> SI, channel-list order
  virtual double scan_period_s() const = 0;       // timed acquisitions, after start(); 0 for externally clocked
  virtual void start() = 0;                       // issues the command; throws naming the device on failure
  virtual bool restart() = 0;                     // after an overrun: re-issue; false on failure
  virtual void cancel() = 0;                      // stop acquiring (unblocks readers)
  virtual std::int64_t origin_utime() const = 0;  // host time of the first timer tick of the latest (re)start
  virtual ReadFunction read_function() const { return {}; }  // empty: ::read
  virtual unsigned buffer_bytes() const { return 0; }        // the kernel buffer's size; 0: no kernel buffer
};

// The libcomedi-backed Acquisition (ComediDevice); origin_utime is the host time around comedi_command.
std::unique_ptr<Acquisition> open_comedi_acquisition(const ComediAcquisitionConfig& config);

// How the source obtains its acquisitions (tests substitute descriptors they own).
using AcquisitionFactory = std::function<std::unique_ptr<Acquisition>(const ComediAcquisitionConfig&)>;

// The most scans per second an edge-clocked acquisition delivers: the edge rate at encoder.max_rpm, or with
// max_rpm 0 the most the crank-angle resampler accepts (600 kHz).
double edge_scan_rate_hz(const ComediSourceConfig::Encoder& encoder);

// The start-up note on an acquisition's kernel buffer: its size, the scan rate and the seconds it holds then
// (how long the driver thread may stall before the card overruns). rate_what says where the rate comes from.
std::string buffer_note(const Acquisition& acquisition, const ComediAcquisitionConfig& config, double scan_rate_hz,
                        const std::string& rate_what);

// The acquisition configurations the source opens, in order: the encoder-clocked ones (pressure, encoder,
// [separate timestamp counter]) then the microphones; at rest: the pressure on the card's timer, the encoder's
// counter, the microphones. Throws std::invalid_argument naming the config field.
std::vector<ComediAcquisitionConfig> comedi_acquisitions(const ComediSourceConfig& config);

// Opens every acquisition now (a missing device or a subdevice that cannot stream throws std::runtime_error
// naming device and subdevice). epoch_utime 0: now.
std::unique_ptr<Source> make_comedi_source(const ComediSourceConfig& config, const AcquisitionFactory& factory = {},
                                           std::int64_t epoch_utime = 0);

}  // namespace noisemon::drivers::comedi
