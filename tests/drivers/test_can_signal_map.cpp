// CAN signal extraction against hand-worked DBC examples and a bit-by-bit walk of the DBC bit numbering.
#include "drivers/formats/can_signal_map.hpp"

#include <gtest/gtest.h>

#include <random>

namespace noisemon::drivers {
namespace {

formats::CanSignal signal(std::uint32_t start, std::uint32_t length, formats::CanByteOrder order,
                          bool is_signed = false, double factor = 1.0, double offset = 0.0) {
  formats::CanSignal s;
  s.id = 0x100;
  s.start_bit = start;
  s.length = length;
  s.byte_order = order;
  s.is_signed = is_signed;
  s.factor = factor;
  s.offset = offset;
  return s;
}

// J1939 EEC1 (PGN 61444, ID 0x0CF00400), SPN 190 engine speed: bytes 4-5 (J1939 counts from 1), Intel,
// 0.125 rpm/bit; DBC: SG_ EngineSpeed : 24|16@1+ (0.125,0). 1500 rpm = 12000 = 0x2EE0 -> byte[3] = E0,
// byte[4] = 2E. Unrelated bytes are 0xFF ("not available") to prove masking.
TEST(CanSignalMap, J1939EngineSpeed) {
  formats::CanSignal s = signal(24, 16, formats::CanByteOrder::kIntel, false, 0.125, 0.0);
  s.id = 0x0CF00400;
  s.extended = true;
  formats::CanSignalMap map({s});
  formats::CanFrame f{0x0CF00400, true, 8, {0xFF, 0xFF, 0xFF, 0xE0, 0x2E, 0xFF, 0xFF, 0xFF}};
  OperatingPoint op;
  EXPECT_EQ(map.decode(f, op), 1);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 1500.0);
}

// Motorola, DBC "7|12@0+": MSB is byte 0 bit 7, then byte 0 bits 6..0, then byte 1 bits 7..4.
// data AB CD -> 0xAB followed by the high nibble C -> 0xABC.
TEST(CanSignalMap, MotorolaAcrossByteBoundary) {
  const std::uint8_t d[8] = {0xAB, 0xCD, 0, 0, 0, 0, 0, 0};
  EXPECT_EQ(formats::extract_can_raw(d, 7, 12, formats::CanByteOrder::kMotorola), 0xABCU);
}

// Motorola "12|10@0+": MSB byte 1 bit 4; byte 1 bits 4..0 then byte 2 bits 7..3.
// byte1 = F6 = 1111'0110 -> bits 4..0 = 10110; byte2 = CF = 1100'1111 -> bits 7..3 = 11001.
// raw = 10110'11001b = 0x2D9 = 729.
TEST(CanSignalMap, MotorolaMidFrame) {
  const std::uint8_t d[8] = {0xFF, 0xF6, 0xCF, 0xFF, 0, 0, 0, 0};
  EXPECT_EQ(formats::extract_can_raw(d, 12, 10, formats::CanByteOrder::kMotorola), 729U);
  formats::CanSignal s = signal(12, 10, formats::CanByteOrder::kMotorola);
  EXPECT_EQ(formats::can_signal_min_dlc(s), 3U);
}

// Intel "4|12@1-" (x0.5, +10): low nibble of the signal in byte 0 bits 7..4, high 8 bits in byte 1.
// byte0 = 05 (signal nibble 0, noise below), byte1 = 80 -> raw 0x800 -> -2048 -> -2048*0.5+10 = -1014.
// raw 0xFFF (byte0 F5, byte1 FF) -> -1 -> 9.5.  raw 0x7FF (byte0 F5, byte1 7F) -> 2047 -> 1033.5.
TEST(CanSignalMap, IntelSignExtensionFactorOffset) {
  const formats::CanSignal s = signal(4, 12, formats::CanByteOrder::kIntel, true, 0.5, 10.0);
  const std::uint8_t a[8] = {0x05, 0x80};
  const std::uint8_t b[8] = {0xF5, 0xFF};
  const std::uint8_t c[8] = {0xF5, 0x7F};
  EXPECT_DOUBLE_EQ(formats::can_signal_value(s, a), -1014.0);
  EXPECT_DOUBLE_EQ(formats::can_signal_value(s, b), 9.5);
  EXPECT_DOUBLE_EQ(formats::can_signal_value(s, c), 1033.5);
  formats::CanSignal u = s;
  u.is_signed = false;
  EXPECT_DOUBLE_EQ(formats::can_signal_value(u, a), 2048 * 0.5 + 10.0);
}

// Motorola signed byte "15|8@0-" (x0.1): byte 1 = F6 = -10 -> -1.0 degree.
TEST(CanSignalMap, MotorolaSigned) {
  const std::uint8_t d[8] = {0x00, 0xF6};
  EXPECT_DOUBLE_EQ(formats::can_signal_value(signal(15, 8, formats::CanByteOrder::kMotorola, true, 0.1), d), -10 * 0.1);
}

TEST(CanSignalMap, FullSixtyFourBits) {
  const std::uint8_t d[8] = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x88};
  EXPECT_EQ(formats::extract_can_raw(d, 0, 64, formats::CanByteOrder::kIntel), 0x8807060504030201ULL);
  EXPECT_EQ(formats::extract_can_raw(d, 7, 64, formats::CanByteOrder::kMotorola), 0x0102030405060788ULL);
  // Signed 64-bit: 0x8807... is negative as two's complement.
  EXPECT_DOUBLE_EQ(formats::can_signal_value(signal(0, 64, formats::CanByteOrder::kIntel, true), d),
                   static_cast<double>(static_cast<std::int64_t>(0x8807060504030201ULL)));
}

// Second method: walk the signal bit by bit in DBC numbering (bit i = byte i/8, bit i%8). Intel walks up from
// the LSB; Motorola walks down from the MSB, wrapping from bit 0 of a byte to bit 7 of the next (i + 15).
std::uint64_t walk(const std::uint8_t d[8], std::uint32_t start, std::uint32_t length, formats::CanByteOrder order) {
  std::uint64_t v = 0;
  if (order == formats::CanByteOrder::kIntel) {
    for (std::uint32_t k = 0; k < length; ++k) {
      const std::uint32_t bit = start + k;
      v |= static_cast<std::uint64_t>((d[bit / 8] >> (bit % 8)) & 1U) << k;
    }
    return v;
  }
  std::uint32_t bit = start;
  for (std::uint32_t k = 0; k < length; ++k) {
    v = (v << 1) | ((d[bit / 8] >> (bit % 8)) & 1U);
    bit = (bit % 8 == 0) ? bit + 15 : bit - 1;
  }
  return v;
}

TEST(CanSignalMap, MatchesBitWalkForRandomSignals) {
  std::mt19937_64 rng(7);
  int checked = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    std::uint8_t d[8];
    const std::uint64_t r = rng();
    for (int i = 0; i < 8; ++i) d[i] = static_cast<std::uint8_t>(r >> (8 * i));
    const auto order = (rng() & 1) ? formats::CanByteOrder::kIntel : formats::CanByteOrder::kMotorola;
    const formats::CanSignal s =
        signal(static_cast<std::uint32_t>(rng() % 64), 1 + static_cast<std::uint32_t>(rng() % 64), order);
    try {
      formats::validate_can_signal(s);
    } catch (const std::invalid_argument&) {
      continue;
    }
    ASSERT_EQ(formats::extract_can_raw(d, s.start_bit, s.length, order), walk(d, s.start_bit, s.length, order))
        << "start " << s.start_bit << " length " << s.length
        << (order == formats::CanByteOrder::kIntel ? " intel" : " motorola");
    ++checked;
  }
  EXPECT_GT(checked, 5000);
}

TEST(CanSignalMap, RejectsSignalsOutsideTheFrame) {
  EXPECT_NO_THROW(formats::validate_can_signal(signal(56, 8, formats::CanByteOrder::kIntel)));
  EXPECT_THROW(formats::validate_can_signal(signal(57, 8, formats::CanByteOrder::kIntel)), std::invalid_argument);
  EXPECT_NO_THROW(formats::validate_can_signal(signal(63, 8, formats::CanByteOrder::kMotorola)));  // byte 7 bits 7..0
  EXPECT_THROW(formats::validate_can_signal(signal(63, 9, formats::CanByteOrder::kMotorola)), std::invalid_argument);
  EXPECT_NO_THROW(
      formats::validate_can_signal(signal(0, 57, formats::CanByteOrder::kMotorola)));  // byte 0 bit 0 .. byte 7 bit 0
  EXPECT_THROW(formats::validate_can_signal(signal(0, 58, formats::CanByteOrder::kMotorola)), std::invalid_argument);
  EXPECT_THROW(formats::validate_can_signal(signal(0, 0, formats::CanByteOrder::kIntel)), std::invalid_argument);
  EXPECT_THROW(formats::validate_can_signal(signal(0, 65, formats::CanByteOrder::kIntel)), std::invalid_argument);
  formats::CanSignal s = signal(0, 8, formats::CanByteOrder::kIntel);
  s.id = 0x800;
  EXPECT_THROW(formats::validate_can_signal(s), std::invalid_argument);
  s.extended = true;
  EXPECT_NO_THROW(formats::validate_can_signal(s));
  s.id = 0x20000000;
  EXPECT_THROW(formats::validate_can_signal(s), std::invalid_argument);
}

TEST(CanSignalMap, DecodeMatchesIdWidthAndDlc) {
  formats::CanSignal speed = signal(24, 16, formats::CanByteOrder::kIntel, false, 0.125);
  speed.id = 0x123;
  formats::CanSignal motored = signal(0, 1, formats::CanByteOrder::kIntel);
  motored.id = 0x123;
  motored.field = formats::OperatingPointField::kMotored;
  formats::CanSignalMap map({speed, motored});
  OperatingPoint op;
  op.speed_rpm = 42;
  formats::CanFrame f{0x123, true, 8, {0x01, 0, 0, 0xE0, 0x2E}};
  EXPECT_EQ(map.decode(f, op), 0);  // same number, 29-bit: a different frame
  f.extended = false;
  f.dlc = 4;  // speed needs 5 bytes: only motored is present
  EXPECT_EQ(map.decode(f, op), 1);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 42.0);
  EXPECT_TRUE(op.motored);
  f.dlc = 5;
  f.data[0] = 0;
  EXPECT_EQ(map.decode(f, op), 2);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 1500.0);
  EXPECT_FALSE(op.motored);
}

constexpr const char* kGoodConfig = R"(
[[can.signal]]
field = "speed_rpm"
id = 0x0CF00400
extended = true
start_bit = 24
length = 16
byte_order = "intel"
signed = false
factor = 0.125
offset = 0
unit = "rpm"

[[can.signal]]
field = "soi_deg_btdc"
id = 0x321
start_bit = 15
length = 8
byte_order = "motorola"
signed = true
factor = 0.1
unit = "deg"
)";

TEST(CanSignalMapToml, ParsesSignals) {
  const formats::CanSignalMap map = formats::parse_can_signal_map(toml::parse(kGoodConfig), "cell.toml");
  ASSERT_EQ(map.signals().size(), 2U);
  const formats::CanSignal& a = map.signals()[0];
  EXPECT_EQ(a.id, 0x0CF00400U);
  EXPECT_TRUE(a.extended);
  EXPECT_EQ(a.unit, "rpm");
  EXPECT_DOUBLE_EQ(a.factor, 0.125);
  const formats::CanSignal& b = map.signals()[1];
  EXPECT_EQ(b.field, formats::OperatingPointField::kSoiDegBtdc);
  EXPECT_EQ(b.byte_order, formats::CanByteOrder::kMotorola);
  EXPECT_TRUE(b.is_signed);
  EXPECT_DOUBLE_EQ(b.offset, 0.0);
  OperatingPoint op;
  EXPECT_EQ(map.decode(formats::CanFrame{0x321, false, 2, {0x00, 0xF6}}, op), 1);
  EXPECT_DOUBLE_EQ(op.soi_deg_btdc, -1.0);
}

TEST(CanSignalMapToml, NoCanTableIsEmpty) {
  EXPECT_TRUE(formats::parse_can_signal_map(toml::parse("[daemon]\nsource = \"sim\"\n"), "x").signals().empty());
}

std::string parse_error(const std::string& second_signal) {
  const std::string text = std::string(kGoodConfig).substr(0, std::string(kGoodConfig).find("[[can.signal]]", 10)) +
                           "[[can.signal]]\n" + second_signal;
  try {
    formats::parse_can_signal_map(toml::parse(text), "cell.toml");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no error";
}

TEST(CanSignalMapToml, ErrorsNameSignalAndKey) {
  const std::string base = "field = \"load_nm\"\nid = 0x100\nstart_bit = 0\nbyte_order = \"intel\"\n";
  EXPECT_EQ(parse_error(base + "length = 16\n"), "no error");
  EXPECT_NE(parse_error(base).find("cell.toml: can.signal[1].length: missing"), std::string::npos) << parse_error(base);
  EXPECT_NE(parse_error(base + "length = 65\n").find("can.signal[1].length: value 65 out of range"), std::string::npos);
  EXPECT_NE(parse_error(base + "length = 16\ncolour = 1\n").find("can.signal[1].colour: unknown key"),
            std::string::npos);
  EXPECT_NE(parse_error(base + "length = 16\nfactor = \"x\"\n").find("can.signal[1].factor: expected a number"),
            std::string::npos);
  const std::string order = "field = \"load_nm\"\nid = 0x100\nstart_bit = 0\nlength = 8\n";
  EXPECT_NE(parse_error(order + "byte_order = \"big\"\n").find("can.signal[1].byte_order"), std::string::npos);
  const std::string field = "id = 0x100\nstart_bit = 0\nlength = 8\nbyte_order = \"intel\"\n";
  EXPECT_NE(parse_error(field + "field = \"torque\"\n").find("can.signal[1].field: unknown field 'torque'"),
            std::string::npos);
  // Fits the key ranges but not the frame: bits 60..67.
  const std::string over = "field = \"load_nm\"\nid = 0x100\nstart_bit = 60\nlength = 8\nbyte_order = \"intel\"\n";
  EXPECT_NE(parse_error(over).find("can.signal[1]: intel signal (start_bit 60, length 8) runs past"), std::string::npos)
      << parse_error(over);
  const std::string wide = "field = \"load_nm\"\nid = 0x1000\nstart_bit = 0\nlength = 8\nbyte_order = \"intel\"\n";
  EXPECT_NE(parse_error(wide).find("can.signal[1]: id 0x1000 exceeds 11 bits"), std::string::npos) << parse_error(wide);
}

}  // namespace
}  // namespace noisemon::drivers
