// `noisemon check` on the virtual engine as a cell would meet it: a healthy chain passes (ten microphones at their
// level, the encoder turning, no errors), and a microphone unplugged from the start (the sim's fault, acting where
// the real one does: on the converter's input) is named, with exit status 1 for the test bed to stop on.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

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
