// Faults the virtual engine injects, as a test cell produces them ([[sim.faults]] in the configuration).
//
// Each fault is a window of simulated time after the source's first frame on one channel, stream or the encoder.
// They act where the real fault happens, so the daemon meets them through the code a real device goes through:
//  - encoder (the DAQ's position counter, clocked by the encoder's edges and reset by its index; decoded by
//    EdgeStreamAssembler exactly as for a comedi card):
//      missing_edges  per_rev edges a revolution are not counted (a dirty disc, a weak signal)
//      extra_edges    per_rev spurious counts a revolution (electrical noise on the encoder line)
//      lost_index     the index pulse does not reset the counter
//      reverse        the counter counts down (a direction fault, or the crank turning backwards)
//  - one channel, "pressure" or "mic<N>" (1-based), on the converter's samples before resampling:
//      flat           the converter is stuck: every sample repeats the last one
//      overload       the signal is gain times too large for the converter, which clips at its rails
//      nan            the samples are NaN (a broken scaling, a decoding error upstream)
//      unplugged      the input is open: only the converter's own noise (microphones only)
//  - one stream, "pressure" (encoder and pressure) or "mics", between the device and its ring:
//      stall          the device delivers nothing, then resumes at the present (like a card that stopped)
//      overrun        bursts of lost blocks: 20 ms lost every 100 ms (the driver's buffer overran)
//      fail           the device fails for good (an I/O error): its driver thread ends with an error naming it
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace noisemon::drivers::sim {

enum class SimFaultKind : std::uint8_t {
  kMissingEdges,
  kExtraEdges,
  kLostIndex,
  kReverse,  // encoder
  kFlat,
  kOverload,
  kNan,
  kUnplugged,  // one channel
  kStall,
  kOverrun,
  kFail,  // one stream
};

inline constexpr int kPressureTarget = -1;  // SimFault::target: the pressure channel / the encoder-clocked stream
inline constexpr int kMicsTarget = -2;      // SimFault::target: the microphone stream (stall, overrun)

struct SimFault {
  SimFaultKind kind = SimFaultKind::kFlat;
  int target = kPressureTarget;  // kPressureTarget, kMicsTarget or a microphone (0-based); ignored by encoder faults
  double at_s = 0.0;             // start, s after the source's first frame
  double duration_s = 1.0;
  double per_rev = 3.0;  // missing_edges, extra_edges: edges per revolution
  double gain = 4.0;     // overload: factor on the signal before the converter

  bool active(double t_since_start_s) const { return t_since_start_s >= at_s && t_since_start_s < at_s + duration_s; }
};

// Names as the configuration writes them: "missing_edges", ..., "overrun".
std::optional<SimFaultKind> parse_fault_kind(std::string_view name);
std::string_view fault_kind_name(SimFaultKind kind);
bool is_encoder_fault(SimFaultKind kind);
bool is_stream_fault(SimFaultKind kind);
// The target of a channel or stream fault from its name ("pressure", "mics", "mic1" ... "mic<mic_count>").
// Throws std::invalid_argument naming the fault kind, the name given and the valid names.
int parse_fault_target(SimFaultKind kind, std::string_view name, std::uint32_t mic_count);
// Checks a list against the configuration (targets in range, positive durations, sensible per_rev and gain).
void validate_faults(const std::vector<SimFault>& faults, std::uint32_t mic_count);

// The faults of one kind and target active at t (s after the first frame): the first, or nullptr.
const SimFault* active_fault(const std::vector<SimFault>& faults, SimFaultKind kind, int target,
                             double t_since_start_s);

// Whether a stream delivers what it produced at t: false inside a stall, and in the lost part of an overrun burst.
bool stream_delivers(const std::vector<SimFault>& faults, int stream_target, double t_since_start_s);

}  // namespace noisemon::drivers::sim
