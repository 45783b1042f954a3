// The read loop of a socketcan source: struct can_frame records off a file descriptor (a raw CAN socket in
// service, any datagram socket carrying the same bytes in tests), with the kernel's receive timestamp and
// drop counter, error frames recognised and counted, data frames decoded through a CanSignalMap.
#pragma once

#include <sys/socket.h>
#include <cstdint>
#include <string>
#include <vector>

#include "drivers/formats/can_signal_map.hpp"

namespace noisemon::drivers::can {

struct SocketCanStats {
  std::uint64_t data_frames = 0;
  std::uint64_t remote_frames = 0;        // ignored
  std::uint64_t malformed = 0;            // reads that were not one struct can_frame
  std::uint64_t error_frames = 0;         // every CAN_ERR_FLAG frame
  std::uint64_t bus_off = 0;              // error frames with CAN_ERR_BUSOFF
  std::uint64_t controller_problems = 0;  // error frames with CAN_ERR_CRTL
  std::uint64_t restarts = 0;             // error frames with CAN_ERR_RESTARTED
  std::uint32_t kernel_drops = 0;         // latest SO_RXQ_OVFL counter (cumulative in the kernel)
  std::uint64_t fallback_timestamps = 0;  // frames timed with clock_gettime (no kernel timestamp)
};

struct ReceivedCanFrame {
  formats::CanFrame frame;
  std::int64_t utime = 0;
  std::uint32_t error_class = 0;  // CAN_ERR_* bits of an error frame, 0 for data
};

enum class CanReadResult : std::uint8_t { kDataFrame, kErrorFrame, kIgnored, kTimeout, kClosed };

// Kernel receive metadata found in a message's ancillary data (SCM_TIMESTAMP / SCM_TIMESTAMPNS,
// SO_RXQ_OVFL). Returns true when a timestamp was present.
bool parse_can_ancillary(const msghdr& msg, std::int64_t& utime, bool& have_drops, std::uint32_t& drops);

class SocketCanReader {
 public:
  explicit SocketCanReader(int fd);  // does not own fd

  // Waits up to timeout_ms (-1: forever) for one frame. Throws std::system_error on a socket error.
  CanReadResult read(int timeout_ms, ReceivedCanFrame& out);

  // Reads one frame; a data frame is decoded into op (utime set to the frame's receive time when any field
  // changed). Returns kDataFrame only when op was updated; data frames the map ignores give kIgnored.
  CanReadResult read_operating_point(int timeout_ms, const formats::CanSignalMap& map, OperatingPoint& op);

  const SocketCanStats& stats() const { return stats_; }

 private:
  int fd_;
  SocketCanStats stats_;
};

// Opens a raw CAN socket bound to the interface, receiving only the signal map's frame ids (CAN_RAW_FILTER)
// plus bus-off / controller / restart error frames, with SO_TIMESTAMP and SO_RXQ_OVFL enabled. Throws
// std::runtime_error naming the interface when it does not exist, the kernel lacks CAN support, or it is
// not a CAN device. The caller closes the returned fd.
int open_socketcan(const std::string& interface, const formats::CanSignalMap& map);

}  // namespace noisemon::drivers::can
