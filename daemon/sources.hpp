// Builds the daemon's source from its configuration: the stream source [daemon] source names (one of
// stream_sources()), with its microphones replaced by the one [daemon] microphones names (one of mic_sources()) and
// its operating points by the [can] source when [can] is configured; each driver thread gets its policy from
// [threads].
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "daemon/config.hpp"
#include "drivers/source.hpp"

namespace noisemon::daemon {

// What clocks the pressure. kEncoder: the engine's own edges, as the daemon runs. kAtRest: the engine is stopped and
// is to stay so (`noisemon calibrate --pressure`, the pressure row of `noisemon check`): a source whose pressure the
// encoder's edges clock (comedi) samples it on its card's timer instead, the crank angle NaN; the others are as
// configured (the virtual engine rests when [sim] stopped says so; lcm carries what another process sends).
enum class PressureClock : std::uint8_t { kEncoder, kAtRest };

// A stream source the daemon can run on: the name [daemon] source and --source take, what it is (for --help), and
// how it is built. The one list of them: the configuration, the command line and make_source read it.
struct StreamSourceKind {
  std::string_view name;
  std::string_view what;
  std::unique_ptr<drivers::Source> (*make)(const Config&, PressureClock);
};
std::span<const StreamSourceKind> stream_sources();

// The kind named, or nullptr; and the names for a message ("sim, lcm, comedi").
const StreamSourceKind* find_stream_source(std::string_view name);
std::string stream_source_names();

// A microphone source the daemon can compose with the stream source ([daemon] microphones): its name, what it is,
// and how it is built. The one list of them.
struct MicSourceKind {
  std::string_view name;
  std::string_view what;
  std::unique_ptr<drivers::MicSource> (*make)(const Config&);
};
std::span<const MicSourceKind> mic_sources();
const MicSourceKind* find_mic_source(std::string_view name);
std::string mic_source_names();

// Opens devices, sockets and files now: a missing comedi device, audio interface, CAN interface or candump file, or
// an lcm source without a session within [lcm] session_timeout_s, throws with a message naming it.
std::unique_ptr<drivers::Source> make_source(const Config& config, PressureClock clock = PressureClock::kEncoder);

// What the comedi source is built from: [comedi] with the threads' policies, at rest for kAtRest.
drivers::comedi::ComediSourceConfig comedi_source_config(const Config& config, PressureClock clock);

}  // namespace noisemon::daemon
