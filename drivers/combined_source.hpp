// Sources composed from parts: one source's pressure and microphone streams with another source's operating points
// (the comedi DAQ or the sim, plus the engine controller's CAN bus); and one source's pressure and crank angle with
// the microphones of a front-end of their own (an audio interface). What a part makes that the other replaces (the
// stream source's own operating points or microphones) goes to a private ring nobody reads.
#pragma once

#include <memory>

#include "drivers/source.hpp"

namespace noisemon::drivers {

// name() is "<streams>+<operating_point>"; info() and exhausted() are the stream source's; threads and counters are
// both sources'.
std::unique_ptr<Source> combine_sources(std::unique_ptr<Source> streams,
                                        std::unique_ptr<OperatingPointSource> operating_point);

// name() is "<streams>+<mics>"; info() is the stream source's with the microphone fields of the microphone source;
// exhausted() the stream source's; threads and counters are both sources'. The microphone source starts first, on
// the stream source's epoch.
std::unique_ptr<Source> compose_microphones(std::unique_ptr<Source> streams, std::unique_ptr<MicSource> mics);

}  // namespace noisemon::drivers
