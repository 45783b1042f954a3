// One source's pressure and microphone streams with another source's operating points: the comedi DAQ (or the
// sim) plus the engine controller's CAN bus. The stream source's own operating points, if it makes any, go to
// a private ring nobody reads.
#pragma once

#include <memory>

#include "drivers/source.hpp"

namespace noisemon::drivers {

// name() is "<streams>+<operating_point>"; info() and exhausted() are the stream source's; threads and counters are
// both sources'.
std::unique_ptr<Source> combine_sources(std::unique_ptr<Source> streams,
                                        std::unique_ptr<OperatingPointSource> operating_point);

}  // namespace noisemon::drivers
