// The cell id ([lcm] cell): a suffix on every channel, so several daemons share one multicast group.
#include <gtest/gtest.h>

#include "daemon/config.hpp"

using noisemon::daemon::ConfigError;
using noisemon::daemon::parse_config;

TEST(CellConfig, EmptyKeepsTodaysChannelNames) {
  const auto c = parse_config("[lcm]\ncell = \"\"\n", "t.toml");
  EXPECT_EQ(c.lcm.report_channel, "NOISEMON_CYCLE");
  EXPECT_EQ(c.lcm.session_channel, "NOISEMON_SESSION");
}

TEST(CellConfig, SuffixesEveryChannelIncludingConfiguredNames) {
  const auto c = parse_config("[lcm]\ncell = \"bay-2\"\nreport_channel = \"CYC\"\n", "t.toml");
  EXPECT_EQ(c.lcm.cell, "bay-2");
  EXPECT_EQ(c.lcm.report_channel, "CYC_bay-2");
  EXPECT_EQ(c.lcm.status_channel, "NOISEMON_STATUS_bay-2");
  EXPECT_EQ(c.lcm.raw_channel, "NOISEMON_RAW_bay-2");
  EXPECT_EQ(c.lcm.operating_point_channel, "NOISEMON_OP_bay-2");
  EXPECT_EQ(c.lcm.session_channel, "NOISEMON_SESSION_bay-2");
}

TEST(CellConfig, AnotherCellReplacesTheSuffix) {
  auto lcm = parse_config("[lcm]\ncell = \"A\"\n", "t.toml").lcm;
  noisemon::daemon::set_cell(lcm, "B7");
  EXPECT_EQ(lcm.report_channel, "NOISEMON_CYCLE_B7");
  noisemon::daemon::set_cell(lcm, "");
  EXPECT_EQ(lcm.report_channel, "NOISEMON_CYCLE");
}

TEST(CellConfig, AnIdOutsideLettersDigitsAndDashIsAnErrorNamingTheField) {
  try {
    parse_config("[lcm]\ncell = \"bay 2\"\n", "t.toml");
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("t.toml: lcm.cell"), std::string::npos) << e.what();
  }
  noisemon::daemon::LcmConfig lcm;
  EXPECT_THROW(noisemon::daemon::set_cell(lcm, "a_b"), ConfigError);
  EXPECT_THROW(noisemon::daemon::set_cell(lcm, "a.b"), ConfigError);
}
