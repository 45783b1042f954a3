// candump log parsing against lines written by hand in the can-utils `candump -l` format.
#include "drivers/formats/candump.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdio>
#include <fstream>

namespace noisemon::drivers {
namespace {

formats::CandumpRecord parse_ok(const std::string& line) {
  formats::CandumpRecord r;
  std::string error;
  EXPECT_TRUE(formats::parse_candump_line(line, 1, r, error)) << line << ": " << error;
  return r;
}

std::string parse_err(const std::string& line, std::size_t line_number = 7) {
  formats::CandumpRecord r;
  std::string error;
  EXPECT_FALSE(formats::parse_candump_line(line, line_number, r, error)) << line;
  return error;
}

TEST(Candump, StandardDataFrame) {
  const formats::CandumpRecord r = parse_ok("(1700000000.123456) can0 123#DEADBEEF");
  EXPECT_EQ(r.utime, 1700000000LL * 1000000 + 123456);
  EXPECT_EQ(r.interface, "can0");
  EXPECT_EQ(r.frame.id, 0x123U);
  EXPECT_FALSE(r.frame.extended);
  EXPECT_FALSE(r.remote);
  ASSERT_EQ(r.frame.dlc, 4);
  EXPECT_EQ(r.frame.data[0], 0xDE);
  EXPECT_EQ(r.frame.data[1], 0xAD);
  EXPECT_EQ(r.frame.data[2], 0xBE);
  EXPECT_EQ(r.frame.data[3], 0xEF);
}

TEST(Candump, ExtendedFrameDecodesThroughSignalMap) {
  const formats::CandumpRecord r = parse_ok("(1700000001.000001) vcan1 0CF00400#ffffffe02effffff\r");
  EXPECT_EQ(r.utime, 1700000001000001LL);
  EXPECT_EQ(r.frame.id, 0x0CF00400U);
  EXPECT_TRUE(r.frame.extended);
  EXPECT_EQ(r.frame.dlc, 8);
  // J1939 EEC1 engine speed, bytes 4-5 at 0.125 rpm/bit: 0x2EE0 = 12000 -> 1500 rpm.
  formats::CanSignal s;
  s.id = 0x0CF00400;
  s.extended = true;
  s.start_bit = 24;
  s.length = 16;
  s.factor = 0.125;
  OperatingPoint op;
  EXPECT_EQ(formats::CanSignalMap({s}).decode(r.frame, op), 1);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 1500.0);
}

TEST(Candump, EmptyRemoteAndShortFraction) {
  const formats::CandumpRecord e = parse_ok("(1.5) can0 7FF#");
  EXPECT_EQ(e.utime, 1500000);
  EXPECT_EQ(e.frame.dlc, 0);
  const formats::CandumpRecord r = parse_ok("(2.000000) can0 123#R");
  EXPECT_TRUE(r.remote);
  EXPECT_EQ(r.frame.dlc, 0);
  const formats::CandumpRecord r3 = parse_ok("(2.000000) can0 123#R3");
  EXPECT_TRUE(r3.remote);
  EXPECT_EQ(r3.frame.dlc, 3);
  const formats::CandumpRecord dotted = parse_ok("(3.1234567) can0 001#11.22.33");
  EXPECT_EQ(dotted.utime, 3123456);  // sub-microsecond digits truncated
  EXPECT_EQ(dotted.frame.dlc, 3);
  EXPECT_EQ(dotted.frame.data[2], 0x33);
}

TEST(Candump, BadLinesNameLineAndExpectation) {
  auto has = [](const std::string& error, const std::string& part) { return error.find(part) != std::string::npos; };
  EXPECT_TRUE(has(parse_err("(1.0) can0 123##1DEADBEEF"), "line 7: CAN FD"));
  EXPECT_TRUE(has(parse_err("1.0 can0 123#00"), "line 7: expected '('"));
  EXPECT_TRUE(has(parse_err("(1) can0 123#00"), "expected '.'"));
  EXPECT_TRUE(has(parse_err("(1.0 can0 123#00"), "expected ')'"));
  EXPECT_TRUE(has(parse_err("(1.0) can0"), "expected '<id>#<data>'"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 12#00"), "3 hex digits (11-bit) or 8 hex digits (29-bit)"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 800#00"), "11-bit"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 20000000#00"), "29-bit"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 123 00"), "followed by '#'"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 123#DEA"), "pairs of hex digits"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 123#0G"), "pairs of hex digits"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 123#000102030405060708"), "at most 8 data bytes"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 123#0001020304050607_9"), "len8_dlc"));
  EXPECT_TRUE(has(parse_err("(1.0) can0 123#R9"), "dlc digit"));
  EXPECT_TRUE(has(parse_err("(99999999999999999999.0) can0 123#00", 12), "line 12: timestamp seconds out of range"));
}

TEST(CandumpReader, SkipsAndCountsBadLines) {
  char path[] = "/tmp/noisemon_candump_XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  close(fd);
  {
    std::ofstream f(path);
    f << "(1700000000.000100) can0 123#0102\n"
         "\n"
         "(1700000000.000200) can0 123##1DEADBEEF\n"
         "(1700000000.000300) can0 0CF00400#FFFFFFE02EFFFFFF\n"
         "garbage\n"
         "(1700000000.000400) can1 321#R\n";
  }
  formats::CandumpReader reader(path);
  formats::CandumpRecord r;
  std::vector<std::int64_t> times;
  while (reader.next(r)) times.push_back(r.utime);
  std::remove(path);
  EXPECT_EQ(times, (std::vector<std::int64_t>{1700000000000100, 1700000000000300, 1700000000000400}));
  EXPECT_EQ(reader.bad_lines(), 2U);
  EXPECT_NE(reader.last_error().find("line 5: expected '('"), std::string::npos) << reader.last_error();
  EXPECT_EQ(r.interface, "can1");
}

TEST(CandumpReader, MissingFileNamesPath) {
  try {
    formats::CandumpReader reader("/nonexistent/noisemon.log");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/noisemon.log"), std::string::npos);
  }
}

}  // namespace
}  // namespace noisemon::drivers
