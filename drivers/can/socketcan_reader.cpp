#include "drivers/can/socketcan_reader.hpp"

#include "drivers/source.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/time.h>
#include <unistd.h>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <stdexcept>
#include <system_error>

namespace noisemon::drivers::can {
namespace {}  // namespace

bool parse_can_ancillary(const msghdr& msg, std::int64_t& utime, bool& have_drops, std::uint32_t& drops) {
  bool have_time = false;
  have_drops = false;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(const_cast<msghdr*>(&msg), c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMP && c->cmsg_len >= CMSG_LEN(sizeof(timeval))) {
      timeval tv;
      std::memcpy(&tv, CMSG_DATA(c), sizeof tv);
      utime = static_cast<std::int64_t>(tv.tv_sec) * 1000000 + tv.tv_usec;
      have_time = true;
    } else if (c->cmsg_type == SCM_TIMESTAMPNS && c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec ts;
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      utime = static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
      have_time = true;
    } else if (c->cmsg_type == SO_RXQ_OVFL && c->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
      std::memcpy(&drops, CMSG_DATA(c), sizeof drops);
      have_drops = true;
    }
  }
  return have_time;
}

SocketCanReader::SocketCanReader(int fd) : fd_(fd) {}

CanReadResult SocketCanReader::read(int timeout_ms, ReceivedCanFrame& out) {
  pollfd p{fd_, POLLIN, 0};
  const int ready = ::poll(&p, 1, timeout_ms);
  if (ready < 0) {
    if (errno == EINTR) return CanReadResult::kTimeout;
    throw std::system_error(errno, std::generic_category(), "socketcan poll");
  }
  if (ready == 0) return CanReadResult::kTimeout;

  can_frame raw{};
  iovec iov{&raw, sizeof raw};
  alignas(cmsghdr) char
      control[CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(timeval)) + CMSG_SPACE(sizeof(std::uint32_t))];
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return CanReadResult::kTimeout;
    throw std::system_error(errno, std::generic_category(), "socketcan recvmsg");
  }
  // Zero bytes after poll said readable: the peer of a seqpacket test socket closed (a raw CAN socket never
  // delivers an empty record).
  if (n == 0) return CanReadResult::kClosed;

  std::int64_t utime = 0;
  bool have_drops = false;
  std::uint32_t drops = 0;
  if (!parse_can_ancillary(msg, utime, have_drops, drops)) {
    utime = wall_utime();
    ++stats_.fallback_timestamps;
  }
  if (have_drops) stats_.kernel_drops = drops;

  if (n != static_cast<ssize_t>(sizeof raw) || (msg.msg_flags & MSG_TRUNC)) {
    ++stats_.malformed;
    return CanReadResult::kIgnored;
  }
  out.utime = utime;
  out.frame.extended = (raw.can_id & CAN_EFF_FLAG) != 0;
  out.frame.id = raw.can_id & (out.frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
  out.frame.dlc = raw.len > 8 ? 8 : raw.len;
  std::memcpy(out.frame.data, raw.data, 8);

  if (raw.can_id & CAN_ERR_FLAG) {
    out.error_class = raw.can_id & CAN_ERR_MASK;
    ++stats_.error_frames;
    if (out.error_class & CAN_ERR_BUSOFF) ++stats_.bus_off;
    if (out.error_class & CAN_ERR_CRTL) ++stats_.controller_problems;
    if (out.error_class & CAN_ERR_RESTARTED) ++stats_.restarts;
    return CanReadResult::kErrorFrame;
  }
  out.error_class = 0;
  if (raw.can_id & CAN_RTR_FLAG) {
    ++stats_.remote_frames;
    return CanReadResult::kIgnored;
  }
  ++stats_.data_frames;
  return CanReadResult::kDataFrame;
}

CanReadResult SocketCanReader::read_operating_point(int timeout_ms, const formats::CanSignalMap& map,
                                                    OperatingPoint& op) {
  ReceivedCanFrame rx;
  const CanReadResult r = read(timeout_ms, rx);
  if (r != CanReadResult::kDataFrame) return r;
  if (map.decode(rx.frame, op) == 0) return CanReadResult::kIgnored;
  op.utime = rx.utime;
  return CanReadResult::kDataFrame;
}

int open_socketcan(const std::string& interface, const formats::CanSignalMap& map) {
  const std::string where = "CAN interface '" + interface + "': ";
  if (interface.empty() || interface.size() >= IFNAMSIZ)
    throw std::runtime_error(where + "invalid interface name (1.." + std::to_string(IFNAMSIZ - 1) + " characters)");
  const unsigned index = if_nametoindex(interface.c_str());
  if (index == 0) throw std::runtime_error(where + "no such network interface (" + std::strerror(errno) + ")");

  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    const int e = errno;
    throw std::runtime_error(where +
                             (e == EAFNOSUPPORT || e == EPROTONOSUPPORT
                                  ? "kernel CAN support missing (load the can and can_raw modules): "
                                  : "cannot open a raw CAN socket: ") +
                             std::strerror(e));
  }
  auto fail = [&](const std::string& what) {
    const int e = errno;
    ::close(fd);
    throw std::runtime_error(where + what + ": " + std::strerror(e));
  };

  std::vector<can_filter> filters;
  for (const formats::CanSignal& s : map.signals()) {
    can_filter f{};
    f.can_id = s.extended ? (s.id | CAN_EFF_FLAG) : s.id;
    f.can_mask = CAN_EFF_FLAG | CAN_RTR_FLAG | (s.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    bool dup = false;
    for (const can_filter& g : filters) dup = dup || (g.can_id == f.can_id && g.can_mask == f.can_mask);
    if (!dup) filters.push_back(f);
  }
  // An empty filter list receives no data frames, which is what an empty map asks for.
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.empty() ? nullptr : filters.data(),
                   static_cast<socklen_t>(filters.size() * sizeof(can_filter))) < 0)
    fail("setting CAN_RAW_FILTER");
  const can_err_mask_t err_mask = CAN_ERR_BUSOFF | CAN_ERR_CRTL | CAN_ERR_RESTARTED | CAN_ERR_TX_TIMEOUT;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0)
    fail("setting CAN_RAW_ERR_FILTER");
  const int one = 1;
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &one, sizeof one) < 0) fail("enabling SO_TIMESTAMP");
  if (::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one) < 0) fail("enabling SO_RXQ_OVFL");

  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(index);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) fail("bind (is it a CAN device?)");
  return fd;
}

}  // namespace noisemon::drivers::can
