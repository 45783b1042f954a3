// The socketcan read loop, fed struct can_frame bytes through an AF_UNIX seqpacket socketpair (this machine
// has no CAN), and the raw-socket open's error path.
#include "drivers/can/socketcan_reader.hpp"

#include <gtest/gtest.h>

#include <linux/can.h>
#include <linux/can/error.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>
#include <cstring>
#include <ctime>

namespace noisemon::drivers {
namespace {

std::int64_t realtime_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

class SocketPair : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, fds_), 0); }
  void TearDown() override {
    for (int fd : fds_)
      if (fd >= 0) close(fd);
  }
  void send_frame(canid_t id, std::initializer_list<std::uint8_t> bytes) {
    can_frame f{};
    f.can_id = id;
    f.len = static_cast<std::uint8_t>(bytes.size());
    std::copy(bytes.begin(), bytes.end(), f.data);
    ASSERT_EQ(send(fds_[0], &f, sizeof f, 0), static_cast<ssize_t>(sizeof f));
  }
  int fds_[2] = {-1, -1};
};

formats::CanSignalMap engine_map() {
  formats::CanSignal speed;  // J1939 EEC1 engine speed: bytes 4-5 Intel, 0.125 rpm/bit
  speed.id = 0x0CF00400;
  speed.extended = true;
  speed.start_bit = 24;
  speed.length = 16;
  speed.factor = 0.125;
  formats::CanSignal load;  // 11-bit frame 0x321, Motorola "7|16@0-" 0.5 Nm/bit
  load.field = formats::OperatingPointField::kLoadNm;
  load.id = 0x321;
  load.start_bit = 7;
  load.length = 16;
  load.byte_order = formats::CanByteOrder::kMotorola;
  load.is_signed = true;
  load.factor = 0.5;
  return formats::CanSignalMap({speed, load});
}

TEST_F(SocketPair, DecodesDataFramesAndCountsErrorFrames) {
  const int one = 1;
  ASSERT_EQ(setsockopt(fds_[1], SOL_SOCKET, SO_TIMESTAMP, &one, sizeof one), 0);
  const formats::CanSignalMap map = engine_map();
  can::SocketCanReader reader(fds_[1]);
  OperatingPoint op;

  const std::int64_t before = realtime_us();
  send_frame(0x0CF00400 | CAN_EFF_FLAG, {0xFF, 0xFF, 0xFF, 0xE0, 0x2E, 0xFF, 0xFF, 0xFF});  // 1500 rpm
  send_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  send_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_RX_OVERFLOW, 0, 0, 0, 0, 0, 0});
  send_frame(0x321, {0xFF, 0x38});                   // 0xFF38 = -200 -> -100 Nm
  send_frame(0x0CF00400, {0, 0, 0, 0, 0, 0, 0, 0});  // no CAN_EFF_FLAG: an 11-bit id, 0x400
  send_frame(0x0CF00400 | CAN_EFF_FLAG | CAN_RTR_FLAG, {});
  const std::int64_t after = realtime_us();

  ASSERT_EQ(reader.read_operating_point(1000, map, op), can::CanReadResult::kDataFrame);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 1500.0);
  EXPECT_GE(op.utime, before);
  EXPECT_LE(op.utime, after);
  EXPECT_EQ(reader.read_operating_point(1000, map, op), can::CanReadResult::kErrorFrame);
  EXPECT_EQ(reader.read_operating_point(1000, map, op), can::CanReadResult::kErrorFrame);
  ASSERT_EQ(reader.read_operating_point(1000, map, op), can::CanReadResult::kDataFrame);
  EXPECT_DOUBLE_EQ(op.load_nm, -100.0);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 1500.0);                                               // untouched by the load frame
  EXPECT_EQ(reader.read_operating_point(1000, map, op), can::CanReadResult::kIgnored);  // not in the map
  EXPECT_EQ(reader.read_operating_point(1000, map, op), can::CanReadResult::kIgnored);  // remote frame
  EXPECT_EQ(reader.read_operating_point(20, map, op), can::CanReadResult::kTimeout);

  const can::SocketCanStats& s = reader.stats();
  EXPECT_EQ(s.data_frames, 3U);
  EXPECT_EQ(s.remote_frames, 1U);
  EXPECT_EQ(s.error_frames, 2U);
  EXPECT_EQ(s.bus_off, 1U);
  EXPECT_EQ(s.controller_problems, 1U);
  EXPECT_EQ(s.fallback_timestamps, 0U);  // AF_UNIX honours SO_TIMESTAMP

  close(fds_[0]);
  fds_[0] = -1;
  EXPECT_EQ(reader.read_operating_point(1000, map, op), can::CanReadResult::kClosed);
}

TEST_F(SocketPair, ErrorFrameCarriesClassAndShortReadsAreMalformed) {
  can::SocketCanReader reader(fds_[1]);
  send_frame(CAN_ERR_FLAG | CAN_ERR_CRTL | CAN_ERR_RESTARTED, {0, CAN_ERR_CRTL_TX_PASSIVE});
  const char junk[5] = {1, 2, 3, 4, 5};
  ASSERT_EQ(send(fds_[0], junk, sizeof junk, 0), 5);
  const std::int64_t before = realtime_us();
  can::ReceivedCanFrame rx;
  ASSERT_EQ(reader.read(1000, rx), can::CanReadResult::kErrorFrame);
  EXPECT_EQ(rx.error_class, CAN_ERR_CRTL | CAN_ERR_RESTARTED);
  EXPECT_EQ(rx.frame.data[1], CAN_ERR_CRTL_TX_PASSIVE);
  // Without SO_TIMESTAMP the reader times the frame itself.
  EXPECT_GE(rx.utime, before);
  EXPECT_LE(rx.utime, realtime_us());
  EXPECT_EQ(reader.read(1000, rx), can::CanReadResult::kIgnored);
  EXPECT_EQ(reader.stats().malformed, 1U);
  EXPECT_EQ(reader.stats().restarts, 1U);
  EXPECT_EQ(reader.stats().fallback_timestamps, 2U);
}

// Ancillary data laid out by hand as the kernel does for a raw CAN socket with SO_TIMESTAMP and SO_RXQ_OVFL.
TEST(SocketCanAncillary, ReadsTimestampAndDropCounter) {
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timeval)) + CMSG_SPACE(sizeof(std::uint32_t))] = {};
  msghdr msg{};
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  cmsghdr* c = CMSG_FIRSTHDR(&msg);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SCM_TIMESTAMP;
  c->cmsg_len = CMSG_LEN(sizeof(timeval));
  const timeval tv{1700000000, 250};
  std::memcpy(CMSG_DATA(c), &tv, sizeof tv);
  c = CMSG_NXTHDR(&msg, c);
  ASSERT_NE(c, nullptr);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SO_RXQ_OVFL;
  c->cmsg_len = CMSG_LEN(sizeof(std::uint32_t));
  const std::uint32_t drops = 42;
  std::memcpy(CMSG_DATA(c), &drops, sizeof drops);

  std::int64_t utime = 0;
  bool have_drops = false;
  std::uint32_t got = 0;
  EXPECT_TRUE(can::parse_can_ancillary(msg, utime, have_drops, got));
  EXPECT_EQ(utime, 1700000000LL * 1000000 + 250);
  EXPECT_TRUE(have_drops);
  EXPECT_EQ(got, 42U);

  msg.msg_controllen = 0;
  EXPECT_FALSE(can::parse_can_ancillary(msg, utime, have_drops, got));
  EXPECT_FALSE(have_drops);
}

std::string open_error(const std::string& interface) {
  try {
    const int fd = can::open_socketcan(interface, engine_map());
    close(fd);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "opened";
}

TEST(OpenSocketCan, MissingInterfaceIsNamed) {
  EXPECT_NE(open_error("nmcan_missing0").find("CAN interface 'nmcan_missing0': no such network interface"),
            std::string::npos)
      << open_error("nmcan_missing0");
  EXPECT_NE(open_error("a_name_longer_than_ifnamsiz").find("invalid interface name"), std::string::npos);
}

// "lo" exists but is not CAN: without kernel CAN support (this machine) the socket itself fails; with it,
// binding a raw CAN socket to a non-CAN device does. Either way the error names the interface.
TEST(OpenSocketCan, NonCanInterfaceOrMissingKernelSupportIsNamed) {
  const int probe = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  const bool kernel_can = probe >= 0;
  if (probe >= 0) close(probe);
  const std::string e = open_error("lo");
  EXPECT_NE(e.find("CAN interface 'lo': "), std::string::npos) << e;
  EXPECT_NE(e.find(kernel_can ? "bind" : "kernel CAN support missing"), std::string::npos) << e;
}

}  // namespace
}  // namespace noisemon::drivers
