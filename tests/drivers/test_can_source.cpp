// The CAN operating-point source: a candump fixture decoded into the operating points worked out by hand from
// its bytes (below, independent of the decoder), replayed as fast as possible and at its recorded pace; the live
// path through a seqpacket socketpair carrying struct can_frame (this machine's kernel has no CAN) with error
// frames counted; the errors for a missing interface; and the combination with a stream source.
#include "drivers/can/can_source.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <toml++/toml.h>
#include <chrono>
#include <cmath>
#include <fstream>
#include <thread>

#include "drivers/combined_source.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/driver_counters.hpp"
#include "tests/support/unique_temp.hpp"

namespace nd = noisemon::drivers;
using noisemon::test::allowance;

namespace {

// The map of the README's example: J1939 EEC1 engine speed, a test-cell frame 0x321 with load (Motorola, signed)
// and injection timing, 0x322 with rail pressure and a motored flag.
constexpr const char* kMap = R"(
[[can.signal]]
field = "speed_rpm"
id = 0x0CF00400
extended = true
start_bit = 24
length = 16
byte_order = "intel"
factor = 0.125
unit = "rpm"

[[can.signal]]
field = "load_nm"
id = 0x321
start_bit = 7
length = 16
byte_order = "motorola"
signed = true
factor = 0.1
unit = "N m"

[[can.signal]]
field = "soi_deg_btdc"
id = 0x321
start_bit = 16
length = 8
byte_order = "intel"
signed = true
factor = 0.25
unit = "deg BTDC"

[[can.signal]]
field = "rail_pressure_bar"
id = 0x322
start_bit = 0
length = 16
byte_order = "intel"
factor = 0.05
unit = "bar"

[[can.signal]]
field = "motored"
id = 0x322
start_bit = 16
length = 1
byte_order = "intel"
)";

nd::formats::CanSignalMap example_map() { return nd::formats::parse_can_signal_map(toml::parse(kMap), "test map"); }

// A recorded bus. Expected values by hand:
//  EEC1 data "FF FF FF 40 5F FF FF FF": bytes 3-4 little-endian 0x5F40 = 24384 * 0.125 = 3048 rpm;
//             "FF FF FF 00 64 ...": 0x6400 = 25600 * 0.125 = 3200 rpm.
//  0x321 "00 C8 48": bits 7.. Motorola = bytes 0-1 big-endian 0x00C8 = 200 * 0.1 = 20 N m; byte 2 = 0x48 =
//             72 * 0.25 = 18 deg.  "FF 38 E8": 0xFF38 = -200 -> -20 N m; 0xE8 = -24 -> -6 deg.
//  0x322 "D0 07 00": 0x07D0 = 2000 * 0.05 = 100 bar, bit 16 = 0 (fired); "E8 03 01": 0x03E8 = 1000 -> 50 bar, motored.
constexpr const char* kLog =
    "(1700000000.000000) can0 0CF00400#FFFFFF405FFFFFFF\n"  // speed only: not yet complete
    "(1700000000.010000) can0 321#00C848\n"                 // + load, soi: rail, motored still missing
    "(1700000000.020000) can1 322#D00700\n"                 // other interface: skipped
    "(1700000000.030000) can0 322#D00700\n"                 // complete -> op 1: 3048, 20, 18, 100, fired
    "this is not a candump line\n"                          // malformed
    "(1700000000.040000) can0 7FF#0102\n"                   // unmapped id: ignored
    "(1700000000.050000) can0 321#R\n"                      // remote frame: ignored
    "\n"
    "(1700000000.060000) can0 0CF00400#FFFFFF00640000FF\n"  // op 2: 3200 rpm
    "(1700000000.070000) can0 321#FF38E8\n"                 // op 3: -20 N m, -6 deg
    "(1700000000.080000) can0 322#E80301\n"                 // op 4: 50 bar, motored
    "(1700000000.090000) can0 321#FF\n"                     // too short for load/soi: ignored
    "(17000x0000.1) can0 321#FF38E8\n";                     // malformed

struct Expected {
  std::int64_t utime;
  double speed, load, soi, rail;
  bool motored;
};
const Expected kExpected[] = {{1700000000030000, 3048, 20, 18, 100, false},
                              {1700000000060000, 3200, 20, 18, 100, false},
                              {1700000000070000, 3200, -20, -6, 100, false},
                              {1700000000080000, 3200, -20, -6, 50, true}};

std::string write_log() {
  const std::string path = noisemon::test::unique_temp_dir() + "/can_source_fixture.log";
  std::ofstream(path) << kLog;
  return path;
}

std::vector<nd::OperatingPoint> drain(nd::OperatingPointRing& ring) {
  std::vector<nd::OperatingPoint> out;
  nd::OperatingPoint op;
  while (ring.read(&op, 1) == 1) out.push_back(op);
  return out;
}

using noisemon::test::counter;

void wait_until_stopped(const nd::SourceBase& s) {
  const auto deadline = std::chrono::steady_clock::now() + allowance(std::chrono::seconds(1));  // a thread ending
  while (s.thread_status().at(0).state == nd::ThreadState::kRunning && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
}

}  // namespace

TEST(CandumpSource, FixtureDecodesToTheHandComputedOperatingPoints) {
  nd::can::CanSourceConfig c;
  c.candump_path = write_log();
  c.interface = "can0";
  c.paced = false;
  c.map = example_map();
  auto source = nd::can::make_can_source(c);
  nd::OperatingPointRing ring(64);
  source->start(ring);
  wait_until_stopped(*source);
  source->stop();
  const auto ops = drain(ring);
  ASSERT_EQ(ops.size(), std::size(kExpected));
  for (std::size_t i = 0; i < ops.size(); ++i) {
    const Expected& e = kExpected[i];
    EXPECT_EQ(ops[i].utime, e.utime) << i;  // as fast as possible: the recorded times are kept
    EXPECT_DOUBLE_EQ(ops[i].speed_rpm, e.speed) << i;
    EXPECT_DOUBLE_EQ(ops[i].load_nm, e.load) << i;
    EXPECT_DOUBLE_EQ(ops[i].soi_deg_btdc, e.soi) << i;
    EXPECT_DOUBLE_EQ(ops[i].rail_pressure_bar, e.rail) << i;
    EXPECT_EQ(ops[i].motored, e.motored) << i;
  }
  EXPECT_EQ(counter(*source, "candump.malformed_lines"), 2);
  EXPECT_EQ(counter(*source, "candump.other_interface"), 1);
  EXPECT_EQ(counter(*source, "candump.records"), 10);  // good lines, the skipped and ignored ones included
  EXPECT_EQ(counter(*source, "candump.decoded_frames"), 4);
  EXPECT_EQ(source->thread_status().at(0).state, nd::ThreadState::kStopped);  // end of file is not a failure
}

TEST(CandumpSource, PacedReplayKeepsTheRecordedSpacing) {
  nd::can::CanSourceConfig c;
  c.candump_path = write_log();
  c.paced = true;  // all interfaces: the can1 frame counts too
  c.map = example_map();
  auto source = nd::can::make_can_source(c);
  nd::OperatingPointRing ring(64);
  const std::int64_t t0 = nd::wall_utime();
  source->start(ring);
  std::vector<std::pair<std::int64_t, nd::OperatingPoint>> arrivals;                            // wall time seen, op
  const auto deadline = std::chrono::steady_clock::now() + allowance(std::chrono::seconds(1));  // 80 ms of frames
  while (arrivals.size() < 5 && std::chrono::steady_clock::now() < deadline) {
    nd::OperatingPoint op;
    if (ring.read(&op, 1) == 1)
      arrivals.emplace_back(nd::wall_utime(), op);
    else
      std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  source->stop();
  // With can1's frame the operating point completes at 20 ms; then 30, 60, 70, 80 ms.
  ASSERT_EQ(arrivals.size(), 5u);
  const std::int64_t recorded[] = {20000, 30000, 60000, 70000, 80000};
  const std::int64_t start = arrivals[0].second.utime - recorded[0];  // re-timed: the replay's own start
  EXPECT_NEAR(static_cast<double>(start - t0), 0.0, 20000.0);
  for (std::size_t i = 0; i < arrivals.size(); ++i) {
    EXPECT_EQ(arrivals[i].second.utime - start, recorded[i]) << i;
    // Delivered at (not before) its recorded offset; a loaded machine may be a little late.
    EXPECT_GE(arrivals[i].first - start, recorded[i] - 1000) << i;
    EXPECT_LT(arrivals[i].first - start, recorded[i] + 30000) << i;
  }
}

TEST(CandumpSource, MissingFileAndEmptyMapAreErrorsNamingThem) {
  nd::can::CanSourceConfig c;
  c.candump_path = "/nonexistent/bus.log";
  c.map = example_map();
  try {
    nd::can::make_can_source(c);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/bus.log"), std::string::npos) << e.what();
  }
  c.map = {};
  EXPECT_THROW(nd::can::make_can_source(c), std::invalid_argument);
}

TEST(SocketCanSource, MissingInterfaceIsAnErrorNamingIt) {
  nd::can::CanSourceConfig c;
  c.interface = "nmcan7";
  c.map = example_map();
  try {
    nd::can::make_can_source(c);
    FAIL() << "opened a CAN interface that does not exist";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'nmcan7'"), std::string::npos) << e.what();
  }
  // An interface that exists but is no CAN device (or a kernel without CAN): still named.
  c.interface = "lo";
  try {
    nd::can::make_can_source(c);
    FAIL() << "opened loopback as a CAN interface";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'lo'"), std::string::npos) << e.what();
    std::printf("lo: %s\n", e.what());
  }
}

class SocketCanPair : public ::testing::Test {
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

TEST_F(SocketCanPair, FramesBecomeOperatingPointsAndErrorsAreCounted) {
  auto source = nd::can::make_socketcan_source_on_fd(fds_[1], example_map(), "pair");
  nd::OperatingPointRing ring(64);
  source->start(ring);
  send_frame(0x0CF00400 | CAN_EFF_FLAG, {0xFF, 0xFF, 0xFF, 0x40, 0x5F, 0xFF, 0xFF, 0xFF});  // 3048 rpm
  send_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  send_frame(0x321, {0x00, 0xC8, 0x48});  // 20 N m, 18 deg
  send_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_RX_OVERFLOW, 0, 0, 0, 0, 0, 0});
  send_frame(0x322, {0xE8, 0x03, 0x01});                                                    // 50 bar, motored
  send_frame(0x0CF00400 | CAN_EFF_FLAG, {0xFF, 0xFF, 0xFF, 0x00, 0x64, 0x00, 0x00, 0xFF});  // 3200 rpm
  ASSERT_EQ(::write(fds_[0], "x", 1), 1);  // not a can_frame: malformed
  close(fds_[0]);                          // the peer goes away: the thread ends
  fds_[0] = -1;
  wait_until_stopped(*source);
  source->stop();
  const auto ops = drain(ring);
  ASSERT_EQ(ops.size(), 2u);
  EXPECT_DOUBLE_EQ(ops[0].speed_rpm, 3048.0);
  EXPECT_DOUBLE_EQ(ops[0].load_nm, 20.0);
  EXPECT_DOUBLE_EQ(ops[0].soi_deg_btdc, 18.0);
  EXPECT_DOUBLE_EQ(ops[0].rail_pressure_bar, 50.0);
  EXPECT_TRUE(ops[0].motored);
  EXPECT_DOUBLE_EQ(ops[1].speed_rpm, 3200.0);
  EXPECT_NEAR(static_cast<double>(ops[1].utime), static_cast<double>(nd::wall_utime()), 5e6);
  EXPECT_EQ(counter(*source, "can.data_frames"), 4);
  EXPECT_EQ(counter(*source, "can.error_frames"), 2);
  EXPECT_EQ(counter(*source, "can.bus_off"), 1);
  EXPECT_EQ(counter(*source, "can.controller_problems"), 1);
  EXPECT_EQ(counter(*source, "can.malformed"), 1);
  EXPECT_EQ(counter(*source, "can.decoded_frames"), 2);
}

namespace {
// A stream source that writes one marker operating point into whatever ring it is given.
class StubStreams final : public nd::Source {
 public:
  std::string name() const override { return "stub"; }
  nd::StreamInfo info() const override {
    nd::StreamInfo i;
    i.mic_count = 3;
    return i;
  }
  void start(const nd::Streams& s) override {
    pressure = s.pressure;
    nd::OperatingPoint op;
    op.speed_rpm = -1;
    (void)s.operating_point->push(op);
  }
  void stop() override {}
  bool running() const override { return true; }
  std::vector<nd::DriverThreadStatus> thread_status() const override {
    return {{"stub.thread", nd::ThreadState::kRunning, 1, ""}};
  }
  std::vector<nd::DriverCounter> counters() const override { return {{"stub.events", 7}}; }
  nd::BlockRing* pressure = nullptr;
};
}  // namespace

TEST_F(SocketCanPair, CombinedSourceTakesStreamsFromOneAndOperatingPointsFromTheOther) {
  auto stub = std::make_unique<StubStreams>();
  StubStreams* stub_ptr = stub.get();
  auto combined =
      nd::combine_sources(std::move(stub), nd::can::make_socketcan_source_on_fd(fds_[1], example_map(), "pair"));
  EXPECT_EQ(combined->name(), "stub+socketcan");
  EXPECT_EQ(combined->info().mic_count, 3u);
  nd::BlockRing pressure(4), mics(4);
  nd::OperatingPointRing ring(16);
  combined->start(nd::Streams{&pressure, &mics, &ring});
  EXPECT_EQ(stub_ptr->pressure, &pressure);
  send_frame(0x0CF00400 | CAN_EFF_FLAG, {0xFF, 0xFF, 0xFF, 0x40, 0x5F, 0xFF, 0xFF, 0xFF});
  send_frame(0x321, {0x00, 0xC8, 0x48});
  send_frame(0x322, {0xE8, 0x03, 0x01});
  const auto deadline = std::chrono::steady_clock::now() + allowance(std::chrono::seconds(1));  // 80 ms of frames
  std::vector<nd::OperatingPoint> ops;
  while (ops.empty() && std::chrono::steady_clock::now() < deadline) {
    ops = drain(ring);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  combined->stop();
  ASSERT_EQ(ops.size(), 1u);  // the stub's own operating point went elsewhere
  EXPECT_DOUBLE_EQ(ops[0].speed_rpm, 3048.0);
  const auto threads = combined->thread_status();
  ASSERT_EQ(threads.size(), 2u);
  EXPECT_EQ(threads[0].name, "stub.thread");
  EXPECT_EQ(threads[1].name, "socketcan.pair");
  const auto counters = combined->counters();
  ASSERT_FALSE(counters.empty());
  EXPECT_EQ(counters[0].name, "stub.events");
  EXPECT_EQ(counter(*combined, "can.data_frames"), 3);
}
