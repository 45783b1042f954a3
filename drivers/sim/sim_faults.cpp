#include "drivers/sim/sim_faults.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace noisemon::drivers::sim {
namespace {

constexpr std::array<std::pair<SimFaultKind, std::string_view>, 11> kNames{{
    {SimFaultKind::kMissingEdges, "missing_edges"},
    {SimFaultKind::kExtraEdges, "extra_edges"},
    {SimFaultKind::kLostIndex, "lost_index"},
    {SimFaultKind::kReverse, "reverse"},
    {SimFaultKind::kFlat, "flat"},
    {SimFaultKind::kOverload, "overload"},
    {SimFaultKind::kNan, "nan"},
    {SimFaultKind::kUnplugged, "unplugged"},
    {SimFaultKind::kStall, "stall"},
    {SimFaultKind::kOverrun, "overrun"},
    {SimFaultKind::kFail, "fail"},
}};

constexpr double kOverrunPeriodS = 0.1;  // an overrun burst loses the first kOverrunLostS of every period
constexpr double kOverrunLostS = 0.02;

}  // namespace

std::optional<SimFaultKind> parse_fault_kind(std::string_view name) {
  for (const auto& [kind, n] : kNames)
    if (n == name) return kind;
  return std::nullopt;
}

std::string_view fault_kind_name(SimFaultKind kind) {
  for (const auto& [k, n] : kNames)
    if (k == kind) return n;
  return "?";
}

bool is_encoder_fault(SimFaultKind kind) { return kind <= SimFaultKind::kReverse; }
bool is_stream_fault(SimFaultKind kind) {
  return kind == SimFaultKind::kStall || kind == SimFaultKind::kOverrun || kind == SimFaultKind::kFail;
}

int parse_fault_target(SimFaultKind kind, std::string_view name, std::uint32_t mic_count) {
  const std::string what = "fault '" + std::string(fault_kind_name(kind)) + "': ";
  if (is_encoder_fault(kind)) {
    if (name.empty() || name == "encoder") return kPressureTarget;
    throw std::invalid_argument(what + "acts on the encoder; channel must be \"encoder\" or left out, not '" +
                                std::string(name) + "'");
  }
  if (name == "pressure") return kPressureTarget;
  if (is_stream_fault(kind)) {
    if (name == "mics") return kMicsTarget;
    throw std::invalid_argument(what + "channel '" + std::string(name) +
                                "' is not a stream; expected \"pressure\" or \"mics\"");
  }
  int mic = 0;
  if (name.size() > 3 && name.substr(0, 3) == "mic") {
    const auto [end, ec] = std::from_chars(name.data() + 3, name.data() + name.size(), mic);
    if (ec == std::errc() && end == name.data() + name.size() && mic >= 1 && mic <= static_cast<int>(mic_count))
      return mic - 1;
  }
  throw std::invalid_argument(what + "unknown channel '" + std::string(name) +
                              "'; expected \"pressure\" or \"mic1\" ... \"mic" + std::to_string(mic_count) + "\"");
}

void validate_faults(const std::vector<SimFault>& faults, std::uint32_t mic_count) {
  for (const SimFault& f : faults) {
    const std::string what = "fault '" + std::string(fault_kind_name(f.kind)) + "': ";
    if (!(f.at_s >= 0.0) || !(f.duration_s > 0.0))
      throw std::invalid_argument(what + "at_s must be >= 0 and duration_s > 0");
    if (f.kind == SimFaultKind::kUnplugged && f.target == kPressureTarget)
      throw std::invalid_argument(what + "applies to microphones; an unplugged pressure channel is a 'flat' fault");
    if (f.target >= static_cast<int>(mic_count) || f.target < kMicsTarget)
      throw std::invalid_argument(what + "microphone " + std::to_string(f.target + 1) + " does not exist");
    if (f.target == kMicsTarget && !is_stream_fault(f.kind))
      throw std::invalid_argument(what + "\"mics\" is a stream, not a channel");
    if ((f.kind == SimFaultKind::kMissingEdges || f.kind == SimFaultKind::kExtraEdges) &&
        !(f.per_rev >= 1.0 && f.per_rev <= 100.0))
      throw std::invalid_argument(what + "per_rev must be in [1, 100]");
    if (f.kind == SimFaultKind::kOverload && !(f.gain > 1.0 && f.gain <= 1e6))
      throw std::invalid_argument(what + "gain must be in (1, 1e6]");
  }
}

const SimFault* active_fault(const std::vector<SimFault>& faults, SimFaultKind kind, int target,
                             double t_since_start_s) {
  for (const SimFault& f : faults)
    if (f.kind == kind && (is_encoder_fault(kind) || f.target == target) && f.active(t_since_start_s)) return &f;
  return nullptr;
}

bool stream_delivers(const std::vector<SimFault>& faults, int stream_target, double t_since_start_s) {
  if (active_fault(faults, SimFaultKind::kStall, stream_target, t_since_start_s)) return false;
  if (const SimFault* f = active_fault(faults, SimFaultKind::kOverrun, stream_target, t_since_start_s))
    return std::fmod(t_since_start_s - f->at_s, kOverrunPeriodS) >= kOverrunLostS;
  return true;
}

}  // namespace noisemon::drivers::sim
