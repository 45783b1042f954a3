// `noisemon dbc` on real DBC files (tests/data/dbc): the names, ids, PGNs, layouts and multiplexing a test engineer
// needs for [[can.signal]] dbc_signal, as the file declares them; a missing file named.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/cli/run_command.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using noisemon::test::kNoisemon;
const std::string kDbcDir = std::string(NOISEMON_SOURCE_DIR) + "/tests/data/dbc/";

TEST(DbcCommand, ListsTheJ1939DemoWithItsPgnAndLayout) {
  const auto out = noisemon::test::run_command(kNoisemon + " dbc " + kDbcDir + "CSS-Electronics-SAE-J1939-DEMO.dbc");
  ASSERT_EQ(out.status, 0) << out.text;
  // EEC1 is 0x8CF004FE in the file: a 29-bit id of PGN 0xF004 (61444), SPN 190 at bytes 3-4, 0.125 rpm a bit.
  EXPECT_NE(out.text.find("EEC1  0x0CF004FE ext, J1939 PGN 0xF004 (61444)  8 bytes"), std::string::npos) << out.text;
  EXPECT_NE(out.text.find("EngineSpeed"), std::string::npos);
  EXPECT_NE(out.text.find("24|16 intel    unsigned x 0.125"), std::string::npos) << out.text;
  EXPECT_NE(out.text.find("2 messages, 2 signals"), std::string::npos) << out.text;
}

TEST(DbcCommand, GrepPicksSignalsAndShowsTheirMultiplexors) {
  const auto out = noisemon::test::run_command(kNoisemon + " dbc " + kDbcDir + "multiplex.dbc --grep bit_j");
  ASSERT_EQ(out.status, 0) << out.text;
  EXPECT_NE(out.text.find("BIT_J"), std::string::npos) << out.text;
  EXPECT_NE(out.text.find("when Multiplexor is 8,16,24"), std::string::npos) << out.text;
  EXPECT_EQ(out.text.find("BIT_A"), std::string::npos) << out.text;
  EXPECT_NE(out.text.find("1 messages, 1 signals with 'bit_j'"), std::string::npos) << out.text;
}

TEST(DbcCommand, AMissingOrBrokenFileIsNamed) {
  const auto missing = noisemon::test::run_command(kNoisemon + " dbc /nonexistent/engine.dbc");
  EXPECT_NE(missing.status, 0);
  EXPECT_NE(missing.text.find("/nonexistent/engine.dbc"), std::string::npos) << missing.text;
  const std::string notes = noisemon::test::unique_temp_dir() + "/notes.dbc";
  std::ofstream(notes) << "EEC1 is the engine's speed message\n";
  const auto not_dbc = noisemon::test::run_command(kNoisemon + " dbc " + notes);
  EXPECT_EQ(not_dbc.status, 1);
  EXPECT_NE(not_dbc.text.find("notes.dbc: no messages (BO_): not a DBC file?"), std::string::npos) << not_dbc.text;
}

}  // namespace
