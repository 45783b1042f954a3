// The DBC reader on real DBC files of another project (tests/data/dbc: cantools' test files, MIT, with its licence),
// held to what those files and cantools' documentation say, to Debian's canmatrix decoding the same random frames
// (tests/drivers/dbc_reference.py), and through the configuration to a candump line.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "drivers/formats/can_signal_map.hpp"
#include "drivers/formats/candump.hpp"
#include "drivers/formats/dbc.hpp"
#include "tests/support/required.hpp"
#include "tests/support/unique_temp.hpp"

namespace fs = std::filesystem;
using namespace noisemon::drivers::formats;

namespace {

const fs::path kDbcDir = fs::path(NOISEMON_SOURCE_DIR) / "tests/data/dbc";

CanFrame frame_of(const CanSignal& s, std::initializer_list<int> bytes) {
  CanFrame f{s.id, s.extended, static_cast<std::uint8_t>(bytes.size()), {}};
  int i = 0;
  for (int b : bytes) f.data[i++] = static_cast<std::uint8_t>(b);
  return f;
}

TEST(Dbc, ReadsTheJ1939EngineSpeedAsTheFileDeclaresIt) {
  const DbcFile f = read_dbc(kDbcDir / "CSS-Electronics-SAE-J1939-DEMO.dbc");
  ASSERT_EQ(f.messages.size(), 2u);
  const DbcMessage& eec1 = f.messages[0];
  EXPECT_EQ(eec1.name, "EEC1");
  EXPECT_TRUE(eec1.extended);  // 2364540158 = 0x8CF004FE: bit 31 marks a 29-bit id
  EXPECT_EQ(eec1.id, 0x0CF004FEu);
  EXPECT_EQ(eec1.dlc, 8u);
  const DbcSignal* speed = eec1.signal("EngineSpeed");
  ASSERT_NE(speed, nullptr);
  EXPECT_EQ(speed->start_bit, 24u);
  EXPECT_EQ(speed->length, 16u);
  EXPECT_EQ(speed->byte_order, CanByteOrder::kIntel);
  EXPECT_FALSE(speed->is_signed);
  EXPECT_DOUBLE_EQ(speed->factor, 0.125);
  EXPECT_DOUBLE_EQ(speed->maximum, 8031.875);
  // The comment after the messages, with a non-ASCII character in it, is skipped.
  const CanSignal s = f.can_signal("EngineSpeed", "", OperatingPointField::kSpeedRpm);
  EXPECT_DOUBLE_EQ(can_signal_value(s, frame_of(s, {0xFF, 0xFF, 0xFF, 0x40, 0x1F, 0xFF, 0xFF, 0xFF}).data), 1000.0);
}

// An engine sends EEC1 from its own source address and priority; the demo file names address 0xFE. A J1939
// parameter group (VFrameFormat J1939PG) is matched by its PGN; an ExtendedCAN or 11-bit message by its whole id.
TEST(Dbc, J1939GroupsMatchByPgnWhateverThePriorityAndAddresses) {
  const DbcFile f = read_dbc(kDbcDir / "CSS-Electronics-SAE-J1939-DEMO.dbc");
  EXPECT_TRUE(f.messages[0].j1939);
  CanSignalMap speed({f.can_signal("EngineSpeed", "", OperatingPointField::kSpeedRpm)});
  noisemon::drivers::OperatingPoint op;
  EXPECT_EQ(speed.decode(CanFrame{0x0CF00400, true, 8, {0xFF, 0xFF, 0xFF, 0x40, 0x38, 0xFF, 0xFF, 0xFF}}, op), 1);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 1800.0);  // priority 3, address 0: 0x3840 * 0.125
  EXPECT_EQ(speed.decode(CanFrame{0x18F00417, true, 8, {0xFF, 0xFF, 0xFF, 0x80, 0x0C, 0xFF, 0xFF, 0xFF}}, op), 1);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 400.0);                              // priority 6, address 0x17
  EXPECT_EQ(speed.decode(CanFrame{0x0CF00500, true, 8, {}}, op), 0);  // PGN 0xF005: another group

  const DbcFile j = read_dbc(kDbcDir / "j1939.dbc");  // Message1's own J1939PG, Message2's by default
  EXPECT_TRUE(j.messages[0].j1939);
  EXPECT_TRUE(j.messages[1].j1939);
  CanSignalMap pdu1({j.can_signal("Signal1", "", OperatingPointField::kLoadNm)});  // id 0x15340201, format 0x34
  EXPECT_EQ(pdu1.decode(CanFrame{0x0D347F22, true, 8, {5}}, op), 1);  // another priority, destination and source
  EXPECT_EQ(op.load_nm, 5.0);
  EXPECT_EQ(pdu1.decode(CanFrame{0x15350201, true, 8, {5}}, op), 0);                          // format 0x35
  EXPECT_FALSE(read_dbc(kDbcDir / "issue_184_extended_mux_cascaded.dbc").messages[0].j1939);  // ExtendedCAN
  EXPECT_FALSE(read_dbc(kDbcDir / "motohawk.dbc").messages[0].j1939);                         // 11-bit
}

// cantools' documentation decodes this frame of motohawk.dbc (Motorola, signed, an offset) to these values.
TEST(Dbc, DecodesCantoolsDocumentedMotorolaExample) {
  const DbcFile f = read_dbc(kDbcDir / "motohawk.dbc");
  const CanFrame frame{496, false, 8, {0xC0, 0x06, 0xE0, 0x00, 0x00, 0x00, 0x00, 0x00}};
  const auto value = [&](const char* name) {
    return can_signal_value(f.can_signal(name, "", OperatingPointField::kLoadNm), frame.data);
  };
  EXPECT_NEAR(value("Temperature"), 250.55, 1e-9);
  EXPECT_NEAR(value("AverageRadius"), 3.2, 1e-9);
  EXPECT_EQ(value("Enable"), 1.0);
}

TEST(Dbc, ExtendedMultiplexingFollowsSgMulValRanges) {
  const DbcFile f = read_dbc(kDbcDir / "multiplex.dbc");
  const CanSignal j = f.can_signal("BIT_J", "", OperatingPointField::kMotored);  // m8, present for 8, 16 and 24
  const CanSignal a = f.can_signal("BIT_A", "", OperatingPointField::kMotored);  // m24, present for 24 only
  ASSERT_EQ(j.multiplexors.size(), 1u);
  const auto with_mux = [](int mux) { return CanFrame{0x123456, true, 8, {static_cast<std::uint8_t>(mux << 2)}}; };
  for (int mux : {8, 16, 24}) EXPECT_TRUE(can_signal_present(j, with_mux(mux).data)) << mux;
  for (int mux : {0, 9, 25}) EXPECT_FALSE(can_signal_present(j, with_mux(mux).data)) << mux;
  EXPECT_TRUE(can_signal_present(a, with_mux(24).data));
  EXPECT_FALSE(can_signal_present(a, with_mux(8).data));
}

TEST(Dbc, CascadedMultiplexorsMustAllHold) {
  const DbcFile f = read_dbc(kDbcDir / "issue_184_extended_mux_cascaded.dbc");
  const CanSignal b1 = f.can_signal("muxed_B_1", "", OperatingPointField::kLoadNm);
  ASSERT_EQ(b1.multiplexors.size(), 2u);  // muxed_A_2_MUX_B = 1, itself present while MUX_A = 2
  CanSignalMap map({b1});
  noisemon::drivers::OperatingPoint op;
  EXPECT_EQ(map.decode(frame_of(b1, {2, 1, 6, 7, 0, 0, 0, 0}), op), 1);
  EXPECT_EQ(op.load_nm, 7.0);
  EXPECT_EQ(map.decode(frame_of(b1, {1, 1, 6, 7, 0, 0, 0, 0}), op), 0);  // MUX_A = 1: no B level at all
  EXPECT_EQ(map.decode(frame_of(b1, {2, 0, 6, 7, 0, 0, 0, 0}), op), 0);  // MUX_B = 0: muxed_B_0's turn
}

// Every signal of every file against canmatrix on random frames: the same value where both decode it, and the same
// frames carrying it, except in multiplex.dbc, whose message mixes simple (m24) and extended (SG_MUL_VAL_) multiplexed
// signals: canmatrix drops the simple ones at 24, which the DBC format and cantools carry (the test above holds them).
TEST(Dbc, AgreesWithCanmatrixOnRandomFramesOfEveryFile) {
  NOISEMON_REQUIRE(fs::exists("/usr/lib/python3/dist-packages/canmatrix"), "python3-canmatrix (Debian's)");
  const std::string script = std::string(NOISEMON_SOURCE_DIR) + "/tests/drivers/dbc_reference.py";
  int files = 0, compared = 0;
  for (const auto& entry : fs::directory_iterator(kDbcDir)) {
    if (entry.path().extension() != ".dbc") continue;
    ++files;
    const DbcFile f = read_dbc(entry.path());
    const bool canmatrix_drops_mul_val = entry.path().filename() == "multiplex.dbc";
    const std::string out = (noisemon::test::unique_temp_dir() + "/") + entry.path().stem().string() + ".jsonl";
    const std::string command =
        "/usr/bin/python3 " + script + " '" + entry.path().string() + "' 7 20 > '" + out + "' 2>/dev/null";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
    std::ifstream in(out);
    std::string line;
    while (std::getline(in, line)) {
      const nlohmann::json j = nlohmann::json::parse(line);
      const DbcMessage* m = nullptr;
      for (const DbcMessage& candidate : f.messages)
        if (candidate.name == j["message"]) m = &candidate;
      ASSERT_NE(m, nullptr) << j["message"];
      EXPECT_EQ(m->id, j["id"].get<std::uint32_t>()) << m->name;
      EXPECT_EQ(m->extended, j["extended"].get<bool>()) << m->name;
      const std::string hex = j["data"];  // as many bytes as the message declares
      CanFrame frame{m->id, m->extended, static_cast<std::uint8_t>(hex.size() / 2), {}};
      for (std::size_t i = 0; i < frame.dlc; ++i)
        frame.data[i] = static_cast<std::uint8_t>(std::stoi(hex.substr(2 * i, 2), nullptr, 16));
      for (const DbcSignal& d : m->signals) {
        const CanSignal s = f.can_signal(d.name, m->name, OperatingPointField::kLoadNm);
        const bool ours = frame.dlc >= can_signal_min_dlc(s) && can_signal_present(s, frame.data);
        const bool theirs = j["values"].contains(d.name);
        if (!(canmatrix_drops_mul_val && ours && !theirs)) {
          EXPECT_EQ(ours, theirs) << entry.path().filename() << " " << m->name << "." << d.name << " " << hex;
        }
        if (!ours || !theirs) continue;
        const double expected = j["values"][d.name];
        EXPECT_NEAR(can_signal_value(s, frame.data), expected, 1e-9 * std::max(1.0, std::abs(expected)))
            << entry.path().filename() << " " << m->name << "." << d.name << " " << hex;
        ++compared;
      }
    }
  }
  std::printf("dbc: %d values in %d files equal to canmatrix's\n", compared, files);
  EXPECT_EQ(files, 6);
  EXPECT_GT(compared, 9000);  // vehicle.dbc alone: 217 messages, 462 signals, 20 frames each
}

struct Configured {
  std::string dir;
  std::string config_path;
};

Configured configure(const std::string& can_toml) {
  Configured c{noisemon::test::unique_temp_dir(), ""};
  fs::copy_file(kDbcDir / "CSS-Electronics-SAE-J1939-DEMO.dbc", c.dir + "/engine.dbc",
                fs::copy_options::overwrite_existing);
  c.config_path = c.dir + "/cell.toml";
  std::ofstream(c.config_path) << can_toml;
  return c;
}

CandumpRecord candump(const std::string& line) {
  CandumpRecord r;
  std::string error;
  EXPECT_TRUE(parse_candump_line(line, 1, r, error)) << error;
  return r;
}

CanSignalMap map_of(const Configured& c) {
  return parse_can_signal_map(toml::parse_file(c.config_path), c.config_path);
}

TEST(Dbc, ConfigurationPicksSignalsByNameAndDecodesACandumpLine) {
  const Configured c = configure(
      "[can]\ndbc = \"engine.dbc\"\n"
      "[[can.signal]]\nfield = \"speed_rpm\"\ndbc_signal = \"EngineSpeed\"\n"
      "[[can.signal]]\nfield = \"load_nm\"\ndbc_signal = \"WheelBasedVehicleSpeed\"\ndbc_message = \"CCVS1\"\n"
      "scale = 2.0\nadd = 1.0\nunit = \"N m\"\n");
  const CanSignalMap map = map_of(c);
  ASSERT_EQ(map.signals().size(), 2u);
  EXPECT_EQ(map.signals()[1].unit, "N m");
  noisemon::drivers::OperatingPoint op;
  const CandumpRecord eec1 = candump("(1700000000.000100) can0 0CF004FE#FFFFFF401FFFFFFF");
  EXPECT_EQ(map.decode(eec1.frame, op), 1);
  EXPECT_DOUBLE_EQ(op.speed_rpm, 1000.0);  // 0x1F40 * 0.125 rpm
  const CandumpRecord ccvs1 = candump("(1700000000.000200) can0 18FEF1FE#FF0032FFFFFFFFFF");
  EXPECT_EQ(map.decode(ccvs1.frame, op), 1);
  EXPECT_DOUBLE_EQ(op.load_nm, 0x3200 * 0.00390625 * 2.0 + 1.0);  // 50 km/h, scaled
}

void expect_config_error(const std::string& can_toml, const std::string& says) {
  const Configured c = configure(can_toml);
  try {
    (void)map_of(c);
    ADD_FAILURE() << "accepted: " << can_toml;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(c.config_path), std::string::npos) << e.what();
  }
}

TEST(Dbc, ConfigurationErrorsNameTheFileTheEntryAndTheSignal) {
  expect_config_error("[can]\ndbc = \"engine.dbc\"\n[[can.signal]]\nfield = \"speed_rpm\"\ndbc_signal = \"RPM\"\n",
                      "can.signal[0].dbc_signal: ");
  expect_config_error("[can]\ndbc = \"engine.dbc\"\n[[can.signal]]\nfield = \"speed_rpm\"\ndbc_signal = \"RPM\"\n",
                      "no signal 'RPM'");
  expect_config_error("[[can.signal]]\nfield = \"speed_rpm\"\ndbc_signal = \"EngineSpeed\"\n", "needs can.dbc");
  expect_config_error(
      "[can]\ndbc = \"engine.dbc\"\n[[can.signal]]\nfield = \"speed_rpm\"\ndbc_signal = \"EngineSpeed\"\nlength = 8\n",
      "can.signal[0].length: not beside dbc_signal");
  expect_config_error("[can]\ndbc = \"missing.dbc\"\n", "missing.dbc: cannot read");
  expect_config_error(
      "[can]\ndbc = \"engine.dbc\"\n[[can.signal]]\nfield = \"speed_rpm\"\ndbc_signal = \"EngineSpeed\"\n"
      "dbc_message = \"EEC2\"\n",
      "no message 'EEC2'");
}

TEST(Dbc, MalformedStatementsAreRejectedWithFileAndLine) {
  const auto error_of = [](const std::string& text) {
    try {
      (void)parse_dbc(text, "cell.dbc");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(error_of("BO_ 100 M: 8 X\n SG_ S : 0|8@2+ (1,0) [0|0] \"\" X\n").find("cell.dbc:2: byte order '2'"),
            std::string::npos);
  EXPECT_NE(error_of("BO_ 100 M: 8 X\n SG_ S : 0|8@1+ (1;0) [0|0] \"\" X\n").find("cell.dbc:2: expected ','"),
            std::string::npos);
  EXPECT_NE(error_of("\n SG_ S : 0|8@1+ (1,0) [0|0] \"\" X\n").find("cell.dbc:2: SG_ before any BO_"),
            std::string::npos);
  EXPECT_NE(error_of("BO_ 100 M: 8 X\n SG_ S m : 0|8@1+ (1,0) [0|0] \"\" X\n").find("multiplex indicator 'm'"),
            std::string::npos);
  // A multi-line comment whose second line looks like a statement is a comment.
  EXPECT_EQ(error_of("BO_ 100 M: 8 X\nCM_ BO_ 100 \"first line\nSG_ not a signal\";\n"), "accepted");
}

TEST(Dbc, FloatSignalsAreRefusedByName) {
  const DbcFile f =
      parse_dbc("BO_ 100 M: 8 X\n SG_ Torque : 0|32@1- (1,0) [0|0] \"N m\" X\nSIG_VALTYPE_ 100 Torque : 1;\n", "f.dbc");
  try {
    (void)f.can_signal("Torque", "", OperatingPointField::kLoadNm);
    ADD_FAILURE() << "a float signal accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("f.dbc:2: signal 'Torque' is an IEEE float32"), std::string::npos) << e.what();
  }
}

}  // namespace
