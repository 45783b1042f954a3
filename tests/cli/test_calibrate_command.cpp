// `noisemon calibrate` on an audio interface carrying a calibrator's tone (the tests' virtual interface through
// alsa-lib: a 1 kHz sine of 0.1 of full scale on every channel, 1 V of full scale). The sensitivity it must find is
// worked out here from those definitions: 0.1 / sqrt 2 V rms against the 1.00238 Pa rms of 94 dB is 70.545 mV/Pa.
// Checked: the one value written into the file (every other byte kept), the history and its warning when a
// sensitivity moves, and a tone that is not the calibrator's (wrong frequency) refused with the file untouched.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "tests/cli/run_command.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using noisemon::test::kNoisemon;

constexpr const char* kConfig =
    "# cell 3: microphones on the audio interface\n"
    "[daemon]\nmicrophones = \"alsa\"\n\n"
    "[alsa]\npcm = \"cell\"\nconfig_file = \"cell.asoundrc\"   # the interface\nrate_hz = 48000\n"
    "channels = [0, 1, 2, 3]\n"
    "sensitivity_mv_per_pa = 50.0     # until calibrated\n"
    "full_scale_v = 1.0\nperiod_frames = 480\nperiods = 100\n\n"
    "[sim]\nspeed_rpm = 1500.0\n";

struct Cell {
  std::string dir, config, history;
};

Cell make_cell() {
  Cell c;
  c.dir = noisemon::test::unique_temp_dir();
  c.config = c.dir + "/cell.toml";
  c.history = c.dir + "/cell.calibrations.csv";
  std::ofstream(c.dir + "/cell.asoundrc")
      << "pcm_type.nmtimed { lib \"" NOISEMON_ALSA_TIMED_DEVICE "\" }\n"
      << "pcm.cell { type nmtimed rate 48000 channels 4 tone_hz 1000 amplitude 0.1 }\n";
  std::ofstream(c.config) << kConfig;
  return c;
}

double expected_mv_per_pa(double level_db) {
  return 1000.0 * (0.1 / std::sqrt(2.0)) / (20e-6 * std::pow(10.0, level_db / 20.0));
}

// The value written for microphone `mic` (1-based) into the sensitivity array.
double written(const std::string& text, int mic) {
  const std::size_t at = text.find("sensitivity_mv_per_pa = [");
  if (at == std::string::npos) return NAN;
  std::istringstream values(text.substr(at + 25));
  double v = NAN;
  char comma;
  for (int i = 0; i < mic; ++i) values >> v >> comma;
  return v;
}

}  // namespace

TEST(CalibrateCommand, WritesTheSensitivityTheToneGivesAndKeepsEveryOtherLine) {
  const Cell c = make_cell();
  const auto out = noisemon::test::run_command(kNoisemon + " calibrate --config " + c.config +
                                               " --mic 2 --level 94 --seconds 1.5 --serial 3021456");
  ASSERT_EQ(out.status, 0) << out.text;
  const std::string text = noisemon::test::slurp(c.config);
  EXPECT_NEAR(written(text, 2), expected_mv_per_pa(94.0), 0.01 * expected_mv_per_pa(94.0) / 8.686) << text;  // 0.01 dB
  EXPECT_DOUBLE_EQ(written(text, 1), 50.0);
  EXPECT_DOUBLE_EQ(written(text, 4), 50.0);
  // Only the sensitivity line changed, and its comment stayed.
  std::string expected = kConfig;
  const std::size_t from = expected.find("sensitivity_mv_per_pa = 50.0"), to = expected.find('\n', from);
  const std::size_t line_from = text.find("sensitivity_mv_per_pa = ["), line_to = text.find('\n', line_from);
  expected.replace(from, to - from, text.substr(line_from, line_to - line_from));
  EXPECT_EQ(text, expected);
  EXPECT_NE(text.find("]  # until calibrated"), std::string::npos) << text;
  const std::string history = noisemon::test::slurp(c.history);
  EXPECT_NE(history.find(",2,3021456,70.5"), std::string::npos) << history;
  // 70.5 mV/Pa against the configured 50: a first calibration that moves it 3 dB is worth a look too.
  EXPECT_NE(out.text.find("warning: microphone 2's sensitivity moved +2.99 dB since the configured value"),
            std::string::npos)
      << out.text;
}

TEST(CalibrateCommand, ASensitivityThatMovedSinceTheLastCalibrationIsAWarning) {
  const Cell c = make_cell();
  ASSERT_EQ(noisemon::test::run_command(kNoisemon + " calibrate --config " + c.config + " --mic 3 --seconds 1").status,
            0);
  // The same tone said to be 1 dB louder: the sensitivity comes out 1 dB lower than the last calibration's.
  const auto again =
      noisemon::test::run_command(kNoisemon + " calibrate --config " + c.config + " --mic 3 --level 95 --seconds 1");
  ASSERT_EQ(again.status, 0) << again.text;
  EXPECT_NE(again.text.find("warning: microphone 3's sensitivity moved -1.00 dB"), std::string::npos) << again.text;
  EXPECT_NEAR(written(noisemon::test::slurp(c.config), 3), expected_mv_per_pa(95.0), 0.01);
  std::istringstream history(noisemon::test::slurp(c.history));
  std::string line;
  int rows = 0;
  while (std::getline(history, line)) rows += line.find(",3,") != std::string::npos;
  EXPECT_EQ(rows, 2);
}

TEST(CalibrateCommand, AToneThatIsNotTheCalibratorsIsRefusedAndNothingWritten) {
  const Cell c = make_cell();
  const auto out =
      noisemon::test::run_command(kNoisemon + " calibrate --config " + c.config + " --mic 1 --freq 250 --seconds 1");
  EXPECT_NE(out.status, 0);
  EXPECT_NE(out.text.find("no calibrator tone near 250 Hz on microphone 1"), std::string::npos) << out.text;
  EXPECT_EQ(noisemon::test::slurp(c.config), kConfig);
  EXPECT_FALSE(std::ifstream(c.history).good());
  const auto sim = noisemon::test::run_command(kNoisemon + " calibrate --config /dev/null --mic 1");
  EXPECT_NE(sim.status, 0);
  EXPECT_NE(sim.text.find("calibrate on the front-end they are wired to"), std::string::npos) << sim.text;
  const auto beyond =
      noisemon::test::run_command(kNoisemon + " calibrate --config " + c.config + " --mic 5 --seconds 1");
  EXPECT_NE(beyond.status, 0);
  EXPECT_NE(beyond.text.find("--mic 5, but the configuration has 4 microphones"), std::string::npos) << beyond.text;
}
