// `noisemon check` on the virtual engine as a cell would meet it: a healthy chain passes (ten microphones at their
// level, the encoder turning, no errors), and a microphone unplugged from the start (the sim's fault, acting where
// the real one does: on the converter's input) is named, with exit status 1 for the test bed to stop on.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "drivers/formats/lcm_log_reader.hpp"
#include "noisemon/check_t.hpp"
#include "tests/cli/run_command.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using noisemon::test::kNoisemon;

// The table's row for `item` ("microphone 3").
std::string row(const std::string& text, const std::string& item) {
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line))
    if (line.rfind(item + " ", 0) == 0) return line;
  return "";
}

}  // namespace

TEST(CheckCommand, AHealthyChainIsReadyAndAnUnpluggedMicrophoneIsNamed) {
  const auto healthy = noisemon::test::run_command(kNoisemon + " check --seconds 1");
  ASSERT_EQ(healthy.status, 0) << healthy.text;
  for (int m = 1; m <= 10; ++m) {
    const std::string r = row(healthy.text, "microphone " + std::to_string(m));
    EXPECT_NE(r.find(" ok"), std::string::npos) << r << "\n" << healthy.text;
  }
  EXPECT_NE(row(healthy.text, "encoder").find(" ok"), std::string::npos) << healthy.text;
  EXPECT_NE(row(healthy.text, "clock drift").find("one clock"), std::string::npos) << healthy.text;  // the sim's
  EXPECT_NE(healthy.text.find("the measurement chain is ready"), std::string::npos);

  const std::string config = noisemon::test::unique_temp("unplugged.toml").string();
  std::ofstream(config)
      << "[[sim.faults]]\nkind = \"unplugged\"\nchannel = \"mic3\"\nat_s = 0.0\nduration_s = 1000.0\n";
  const auto broken = noisemon::test::run_command(kNoisemon + " check --config " + config + " --seconds 1");
  EXPECT_EQ(broken.status, 1) << broken.text;
  EXPECT_NE(row(broken.text, "microphone 3").find("FAIL"), std::string::npos) << broken.text;
  EXPECT_EQ(row(broken.text, "microphone 2").find("FAIL"), std::string::npos) << broken.text;
  EXPECT_NE(broken.text.find("1 problems"), std::string::npos) << broken.text;
}

// --publish sends the same table on LCM for the dashboard: LCM's own file provider (file://...?mode=w, no network)
// records what a subscriber would get; every row, verdict and the summary match the printed table.
TEST(CheckCommand, PublishSendsThePrintedTableOnTheConfiguredChannel) {
  const std::string log = noisemon::test::unique_temp("check.lcmlog").string();
  const std::string config = noisemon::test::unique_temp("publish.toml").string();
  std::ofstream(config)
      << "[lcm]\nurl = \"file://" << log << "?mode=w\"\ncell = \"c7\"\n"
      << "[[sim.faults]]\nkind = \"unplugged\"\nchannel = \"mic5\"\nat_s = 0.0\nduration_s = 1000.0\n";
  const auto run = noisemon::test::run_command(kNoisemon + " check --publish --config " + config + " --seconds 1");
  ASSERT_EQ(run.status, 1) << run.text;

  noisemon::drivers::formats::LcmLogReader reader(log);
  noisemon::drivers::formats::LcmLogEvent e;
  std::vector<noisemon::check_t> published;
  while (reader.next(e)) {
    EXPECT_EQ(e.channel, "NOISEMON_CHECK_c7");  // the cell's suffix, as every channel
    noisemon::check_t m;
    ASSERT_GT(m.decode(e.data, 0, e.datalen), 0);
    published.push_back(m);
  }
  ASSERT_EQ(published.size(), 1u);
  const noisemon::check_t& m = published[0];
  EXPECT_EQ(m.problems, 1);
  EXPECT_EQ(m.seconds, 1.0);
  ASSERT_GE(m.nrows, 12);  // ten microphones, the pressure, the encoder, ...
  for (int i = 0; i < m.nrows; ++i) {
    const std::string printed = row(run.text, m.item[i]);
    EXPECT_NE(printed.find(m.value[i]), std::string::npos) << m.item[i] << ": " << printed;
    EXPECT_NE(printed.find(m.verdict[i]), std::string::npos) << m.item[i] << ": " << printed;
    EXPECT_EQ(printed.find("FAIL") != std::string::npos, m.failed[i] != 0) << printed;
    EXPECT_EQ(m.failed[i] != 0, m.item[i] == "microphone 5") << m.item[i];
  }
  EXPECT_NE(run.text.find(m.summary), std::string::npos) << m.summary;
}
