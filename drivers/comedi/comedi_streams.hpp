// Turning decoded comedi scans into the 40 kHz streams of drivers/source.hpp, without threads or descriptors
// (the comedi source's driver threads feed them from the read loops; tests feed them directly too).
//
// EdgeStreamAssembler: the encoder-clocked scans (one per encoder edge) of one or more subdevices, paired scan
// by scan: cylinder pressure (Pa), optionally a cam sensor (V), the encoder's position counter (quadrature,
// reset by the once-per-revolution index) and the edge's timestamp in counter timebase ticks. It unwraps the
// crank angle, tells firing TDC from gas-exchange TDC (cam edge, or the TDC whose pressure rises more), pegs a
// relative (piezoelectric) pressure at a crank angle if asked, and resamples the pressure from the edge times
// to 40 kHz (dsp::NonuniformResampler) with the crank angle interpolated between edges.
//
// Encoder checks (index_resets_counter): the counter reads 0 at the edge of the index and counts_per_rev -
// counts_per_edge at the last edge before the next one. Each revolution's edges are held until the index that
// closes it confirms its count, so the output lags the edges by up to a revolution (two while a phase is being
// re-decided). A confirmed revolution goes out with its crank angles; one that fails a check (count short or
// long at the index, the raw position reaching counts_per_rev, a backward step, an index lost) goes out with
// NaN crank (its pressure is still resampled: it is right in time). The index is ground truth: the unwrapped
// count snaps to it, so the next revolution can be right again. After a backward step, a jump or a lost index
// the firing/gas-exchange phase is decided again from the edges after the next index (NaN until then). The
// part revolution after a (re)start is held likewise and goes out with angles only when its closing index
// confirms the count (the counter counts from the last index the card saw); deliver(ring, true) releases what
// is held with NaN crank. Before the first phase lock (and pegging) after a (re)start nothing goes out.
//
// The microphone scans on the card's timer go through drivers/timed_stream.hpp, as every timed stream does.
//
// Time base: a stream's origin_utime is the host time of its first scan; epoch_utime is the source's frame 0. Nothing
// allocates after construction except restart() (after an overrun, never on the per-sample path) and, with the encoder
// checks, the soft restart of the pressure resampler when no edge came for 50 ms (the engine stopped: the stream has a
// gap there instead of pressure interpolated across it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "drivers/block_writer.hpp"
#include "drivers/source.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers::comedi {

enum class PhaseSource : std::uint8_t {
  kPressure,  // firing TDC is the TDC whose pressure rises more (compression vs gas exchange)
  kCam,       // a cam sensor's rising edge at a known crank angle
};

enum class TimestampMode : std::uint8_t {
  kAbsolute,  // free-running timebase count latched at each edge (counts from the command start, wraps)
  kPeriod,    // timebase ticks since the previous edge (the first: since the command start)
};

// Where a value sits in the encoder-clocked scans: which subdevice's scan, which entry of its channel list.
struct ScanSlot {
  std::uint32_t stream = 0;
  std::uint32_t channel = 0;
};

struct EdgeStreamConfig {
  std::vector<std::uint32_t> stream_channels;  // channel-list length of each encoder-clocked subdevice, in order
  ScanSlot pressure;                           // Pa
  ScanSlot position;                           // raw position count
  ScanSlot timestamp;                          // raw timebase count (TimestampMode)
  std::optional<ScanSlot> cam;                 // V (PhaseSource::kCam)

  std::uint32_t counts_per_rev = 3600;  // position counts per crank revolution
  double index_angle_deg = 0.0;         // crank angle at position 0 (the index), degrees after a TDC
  double timebase_hz = 80e6;
  std::uint32_t timestamp_bits = 32;  // the timebase counter wraps at 2^bits
  TimestampMode timestamp_mode = TimestampMode::kAbsolute;

  PhaseSource phase = PhaseSource::kPressure;
  double cam_threshold_v = 2.5;
  double cam_edge_deg = 0.0;  // crank angle of the cam signal's rising edge, 0 = firing TDC, within +-180 deg

  double peg_pa = 0.0;            // > 0: the pressure at peg_angle_deg is set to this every cycle (relative sensor)
  double peg_angle_deg = -180.0;  // intake BDC
  double peg_window_deg = 10.0;   // mean over this crank-angle width around peg_angle_deg

  std::size_t max_scan_skew = 65536;  // scans one subdevice may run ahead of another before it is an error

  // The index resets the position counter to 0 (quadrature counters with Z-index reset, e.g. NI's): every
  // revolution is checked at its closing index and held until then (see above). false: the position is taken
  // modulo counts_per_rev, nothing is checked or held (the behaviour before the checks).
  bool index_resets_counter = true;
  std::uint32_t counts_per_edge = 1;  // counter counts per clocking edge (counts_per_rev a multiple of it)
  // The highest engine speed, rpm: sizes the resampler's fine grid to the highest edge rate (cheaper for slow
  // engines and coarse encoders; see dsp::NonuniformResampler). 0: any encoder up to 600 kHz of edges.
  double max_rpm = 0.0;
};

// The highest encoder edge rate of an engine at max_rpm (edges per revolution = counts_per_rev / counts_per_edge);
// with max_rpm 0 (not known) the most the crank-angle resampler accepts from any encoder (600 kHz).
double max_edge_rate_hz(std::uint32_t counts_per_rev, std::uint32_t counts_per_edge, double max_rpm);

struct EdgeStreamCounters {
  std::uint64_t edges = 0;              // paired encoder-clocked scans
  std::uint64_t edges_before_lock = 0;  // not output: cam phase (or the first pegging) not known yet
  std::uint64_t encoder_errors = 0;     // position stepping backwards (or jumping), timestamps not increasing
  std::uint64_t phase_corrections = 0;  // firing/gas-exchange TDC re-decided while running
  std::uint64_t frames = 0;             // 40 kHz frames written
  // index_resets_counter only:
  std::uint64_t revolutions_checked = 0;  // revolutions from one index to the next whose count was checked
  std::uint64_t revolutions_flagged = 0;  // of those, failed a check (NaN crank)
  std::uint64_t missing_or_extra = 0;     // count not counts_per_rev at the closing index (edges missed/spurious)
  std::uint64_t lost_index = 0;           // index pulses missed (the counter ran on past counts_per_rev)
  std::uint64_t reverse_steps = 0;        // edges at which the counter stepped backwards
};

class EdgeStreamAssembler {
 public:
  // Throws std::invalid_argument for an inconsistent configuration.
  EdgeStreamAssembler(const EdgeStreamConfig& config, std::int64_t epoch_utime);
  ~EdgeStreamAssembler();

  // Starts over at a new origin (the command was (re)started): partial scans, phase, pegging and held edges
  // (deliver(ring, true) first releases them) are forgotten.
  void restart(std::int64_t origin_utime);
  // One decoded scan of subdevice `stream` (its channel-list values, SI). Pairs it with the other subdevices'
  // scans of the same edge. Throws std::runtime_error when one subdevice runs max_scan_skew scans ahead.
  void add_scan(std::uint32_t stream, const double* values, BlockRing& ring);
  // Resamples the edges gathered so far and pushes finished blocks (a partial block only when at least half
  // full, or when `all`: at stop and before a restart; `all` also releases the held edges, with NaN crank,
  // and the rest of their revolution follows with NaN crank).
  void deliver(BlockRing& ring, bool all);

  // Also writes each edge's sample, as it goes into the resampler, to this ring (the crank-angle stream of
  // drivers/source.hpp; flushed by deliver()). nullptr: not written.
  // Needs an encoder step of kMinAngleStepDeg ... kMaxAngleStepDeg (counts_per_edge of counts_per_rev); throws
  // std::invalid_argument otherwise.
  void set_angle_ring(BlockRing* ring);

  bool locked() const { return locked_ && peg_known_; }
  const EdgeStreamCounters& counters() const { return counters_; }
  std::uint64_t blocks_written() const { return writer_.blocks_written(); }

 private:
  void add_edge(std::uint64_t position, std::uint64_t ticks, double pressure, double cam, BlockRing& ring);
  bool advance_time(std::uint64_t ticks_raw);
  void count_plain(std::uint64_t position);
  bool count_checked(std::uint32_t raw, bool first, BlockRing& ring);
  bool close_revolution(std::uint32_t raw, std::uint32_t prev, BlockRing& ring);
  bool snap_to_index(std::uint32_t raw);
  void count_fault(BlockRing& ring);
  void sync_fault(BlockRing& ring);
  void lose_phase();
  void track_phase(double psi, double pressure, double cam, bool continuous);
  void vote(int phase);
  bool gate(double psi, double pressure);
  void peg(double theta, double pressure);
  void hold(double t, double x, double psi, BlockRing& ring);
  void release_held(std::size_t n, bool angles, BlockRing& ring);
  void emit(double t, double x, double theta, BlockRing& ring);
  void feed(double t, double x, double theta, BlockRing& ring);
  double peg_offset_of(double theta) const;
  void release_pegged(BlockRing& ring);
  void restart_resampler(BlockRing& ring);
  void run_batch(BlockRing& ring);
  double crank_at(double t);

  EdgeStreamConfig config_;
  std::int64_t epoch_utime_;
  double origin_s_ = 0.0;  // origin - epoch, s

  // Pairing: one FIFO of scans per subdevice.
  struct Fifo {
    std::vector<double> values;
    std::size_t channels = 0, head = 0, count = 0;
  };
  std::vector<Fifo> fifos_;

  // Edge state.
  bool have_prev_ = false;
  std::uint64_t prev_ticks_raw_ = 0, prev_position_ = 0;  // prev_position_: modulo counts_per_rev, or raw
  std::uint64_t ticks_ = 0;                               // unwrapped timebase count since the origin
  std::int64_t count_ = 0;                                // unwrapped position count
  std::uint64_t tick_mask_;
  double prev_psi_ = 0.0, prev_cam_ = 0.0;

  // Phase: crank angle theta = psi + 360 * phase_, psi = position angle (TDC at multiples of 360).
  bool locked_ = false;
  int phase_ = 0;
  int mismatches_ = 0;
  struct Window {
    std::int64_t tdc = 0;
    double lo = 0, hi = 0;
    bool open = false, complete = false;
  } window_;
  struct Tdc {
    std::int64_t index = 0;
    double rise = 0;
    bool valid = false;
  } last_tdc_;

  // Encoder checks (index_resets_counter). The revolution being counted: opened by an index (or the part one
  // after a (re)start); `bad` once a check failed or its edges were released unconfirmed: its edges then go
  // out at once with NaN crank instead of being held.
  struct Revolution {
    bool by_index = false, bad = false, fault = false, extra = false, sync_lost = false, stepped_back = false;
  } rev_;
  std::uint64_t slack_ = 0;           // counts: an index edge reads below it; a lost index is this past a revolution
  std::uint64_t lost_threshold_ = 0;  // raw position at which the next index counts as lost
  bool psi_valid_ = true;             // the unwrapped count follows the crank (false from a sync fault to an index)
  bool output_ = false;               // the first lock (and pegging) since the (re)start is done: edges go out
  bool release_on_lock_ = false;      // the phase was just decided again: release the confirmed revolution
  struct Held {
    double t, x, psi;
  };
  std::vector<Held> held_;  // ring: a confirmed revolution awaiting its phase, then the open one
  std::size_t held_head_ = 0, held_n_ = 0, confirmed_n_ = 0;

  // Pegging: peg_offset_ is cycle peg_cycle_'s, peg_prev_offset_ the cycle's before; edges of a later cycle wait.
  bool peg_known_ = false;
  double peg_offset_ = 0.0, peg_prev_offset_ = 0.0, peg_sum_ = 0.0;
  std::int64_t peg_cycle_ = INT64_MIN;
  std::vector<Held> peg_wait_;  // ring (psi holds the crank angle theta here)
  std::size_t peg_wait_head_ = 0, peg_wait_n_ = 0;
  std::size_t peg_n_ = 0;

  // Resampling.
  dsp::NonuniformResampler resampler_;
  std::vector<double> t_, x_, out_;
  std::size_t batch_ = 0;
  struct Edge {
    double t, theta;
  };
  std::vector<Edge> history_;  // ring of recent edges for the crank-angle interpolation
  std::uint64_t history_end_ = 0, cursor_ = 0;
  bool have_fed_ = false;  // the resampler has had an edge (since the last (soft) restart)
  double last_fed_t_ = 0.0;
  BlockWriter writer_;
  BlockRing* angle_ring_ = nullptr;
  BlockWriter angle_writer_{kAngleStreamChannels};
  std::uint32_t angle_block_edges_ = 0;  // max_edges_per_angle_block of the encoder
  EdgeStreamCounters counters_;
};

}  // namespace noisemon::drivers::comedi
