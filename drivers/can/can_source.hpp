// Operating points from the engine controller's CAN bus: a raw SocketCAN socket on a live interface, or a
// candump log replayed (at its recorded pace, or as fast as the pipeline takes it). Frames are decoded through
// the [[can.signal]] map (can_signal_map.hpp) into Streams::operating_point.
//
// It is an OperatingPointSource: it has no streams; combine it with a source of pressure and microphones
// (combined_source.hpp). An operating point is pushed on every frame that
// changes a mapped field, once every mapped field has been received at least once (before that it would carry
// made-up values for the missing ones). Fields the map does not set stay at 0 (rail pressure: NaN).
#pragma once

#include <memory>
#include <string>

#include "drivers/formats/can_signal_map.hpp"
#include "drivers/source.hpp"
#include "drivers/worker_thread.hpp"

namespace noisemon::drivers::can {

struct CanSourceConfig {
  std::string interface;     // live: the SocketCAN interface (e.g. "can0"); with a candump file: only its frames
                             // from this interface are used ("" = all)
  std::string candump_path;  // non-empty: replay this candump -l log instead of a live bus
  bool paced = true;         // candump: at the recorded pace (re-timed to now); false: as fast as taken, recorded times
  formats::CanSignalMap map;
  ThreadPolicy thread;  // scheduling of the thread nm-can (the daemon's [threads.can])

  bool configured() const { return !interface.empty() || !candump_path.empty(); }
};

// Opens the socket (open_socketcan: kernel filters for the map's ids) or the candump file now; throws
// std::runtime_error naming the interface or the file when it cannot, std::invalid_argument for an empty map.
std::unique_ptr<OperatingPointSource> make_can_source(const CanSourceConfig& config);

// The live path on a descriptor the caller owns and keeps open (tests: one end of a socketpair carrying struct
// can_frame records). `label` names it in messages.
std::unique_ptr<OperatingPointSource> make_socketcan_source_on_fd(int fd, const formats::CanSignalMap& map,
                                                                  const std::string& label,
                                                                  const ThreadPolicy& policy = {});

}  // namespace noisemon::drivers::can
