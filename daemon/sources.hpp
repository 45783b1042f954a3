// Builds the daemon's source from its configuration: the stream source of [daemon] source (sim, lcm, comedi),
// with its operating points replaced by the [can] source when [can] is configured; each driver thread gets its
// policy from [threads].
#pragma once

#include <memory>

#include "daemon/config.hpp"
#include "drivers/source.hpp"

namespace noisemon::daemon {

// Opens devices, sockets and files now: a missing comedi device, CAN interface or candump file, or an lcm
// source without a session within [lcm] session_timeout_s, throws with a message naming it.
std::unique_ptr<drivers::Source> make_source(const Config& config);

}  // namespace noisemon::daemon
