// `noisemon calibrate --pressure` on the virtual engine at rest, whose pressure chain is given an error chosen here:
// it reads 0.37 bar high and 4 % steep against its 10 mV/bar sheet, and the card converts it as [comedi.pressure]
// says (sensitivity_mv_per_bar, offset_bar). A zero at ambient, then a gain at a dead-weight tester's 20 bar, must
// leave a configuration under which the sim reads the true pressure: at ambient, at 20 bar and at 60 bar, to within
// what the chain's own noise floor allows the means (their standard error, five times, carried through the two-point
// line). Refused, with the file and history untouched: a charge chain's zero (no absolute zero), a turning engine,
// an unsteady reading, a gain below 5 bar or before any zero, and a bad --reference-bar (the option named).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include "model/engine/pressure_chain.hpp"
#include "tests/cli/run_command.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using noisemon::test::kNoisemon;

constexpr double kAmbientBar = 1.013, kTesterBar = 20.0;
constexpr double kChosenOffsetBar = 0.37, kChosenGainError = 0.04, kSheetMvPerBar = 10.0;
constexpr double kMeasureS = 2.0;

// The sim at rest at `static_bar`, its chain off by the chosen errors; [comedi.pressure] as the sheet gives it.
std::string pressure_cell(double static_bar, const std::string& extra_sim = "") {
  std::ostringstream s;
  s << "# cell 3: the pressure chain, engine stopped\n[sim]\nstopped = true\nstatic_pressure_bar = " << static_bar
    << "   # the transducer's reference\npressure_offset_bar = 0.37\npressure_gain_error = 0.04\n"
    << "pressure_nominal_mv_per_bar = 10.0\nmic_count = 2\n"
    << extra_sim << "\n[comedi.pressure]\nsensitivity_mv_per_bar = 10.0   # from the sheet\nchannel = 0\n";
  return s.str();
}

struct PressureCell {
  std::string dir, config, history;
};

PressureCell make_pressure_cell(const std::string& text) {
  PressureCell c;
  c.dir = noisemon::test::unique_temp_dir();
  c.config = c.dir + "/cell.toml";
  c.history = c.dir + "/cell.calibrations.csv";
  std::ofstream(c.config) << text;
  return c;
}

// The config file with the sim's static pressure changed (the tester connected, or disconnected), and its seed:
// each measurement its own noise (the sim's noise is counter-based from its start, the same every run otherwise,
// and would cancel between the calibration and the check).
void set_static_pressure(const PressureCell& c, double bar, int seed) {
  std::string text = noisemon::test::slurp(c.config);
  const std::size_t at = text.find("static_pressure_bar = "), end = text.find(' ', at + 22);
  text.replace(at + 22, end - at - 22, std::to_string(bar));
  const std::size_t seed_at = text.find("seed = ");
  if (seed_at != std::string::npos) text.erase(seed_at, text.find('\n', seed_at) + 1 - seed_at);
  text.insert(text.find("[sim]\n") + 6, "seed = " + std::to_string(seed) + "\n");
  std::ofstream(c.config) << text;
}

noisemon::test::CommandOutput calibrate(const PressureCell& c, const std::string& args) {
  return noisemon::test::run_command(kNoisemon + " calibrate --config " + c.config + " --pressure --seconds " +
                                     std::to_string(kMeasureS) + " " + args);
}

// A number that follows `key` in `text` (NaN when it is not there).
double number_after(const std::string& text, const std::string& key) {
  const std::size_t at = text.find(key);
  return at == std::string::npos ? NAN : std::stod(text.substr(at + key.size()));
}

// The standard error of one mean: the chain's white floor (noise and quantisation) over the samples of the
// measurement, independent on the card's 40 kHz timer.
double standard_error_bar() {
  return noisemon::model::engine::PressureChainConfig{}.floor_bar() / std::sqrt(kMeasureS * 40000.0);
}

// Five standard errors of the corrected reading at p: its own mean's, and those of the zero (at ambient) and the
// gain (at the tester) carried along the two-point line to p.
double tolerance_bar(double p) {
  const double span = kTesterBar - kAmbientBar;
  const double a = (kTesterBar - p) / span, b = (p - kAmbientBar) / span;
  return 5.0 * standard_error_bar() * std::sqrt(1.0 + a * a + b * b);
}

}  // namespace

TEST(CalibratePressure, ZeroThenGainCorrectTheChainsChosenErrorToItsNoiseFloor) {
  const PressureCell c = make_pressure_cell(pressure_cell(kAmbientBar));
  const auto zero = calibrate(c, "--reference-bar 1.013 --serial 7113");
  ASSERT_EQ(zero.status, 0) << zero.text;
  // The chain read 1.013 * 1.04 + 0.37 at ambient: the zero takes the difference.
  const double zero_offset = kAmbientBar * (1 + kChosenGainError) + kChosenOffsetBar - kAmbientBar;
  EXPECT_NEAR(number_after(noisemon::test::slurp(c.config), "\noffset_bar = "), zero_offset,
              tolerance_bar(kAmbientBar));

  set_static_pressure(c, kTesterBar, 2);
  const auto gain = calibrate(c, "--reference-bar 20 --gain --serial 7113");
  ASSERT_EQ(gain.status, 0) << gain.text;
  std::printf("%s%s", zero.text.c_str(), gain.text.c_str());
  const std::string text = noisemon::test::slurp(c.config);
  // The sensitivity 4 % up, and the offset rescaled to the transducer's own: 0.37 bar of its 4 % steeper scale.
  const double sensitivity = number_after(text, "sensitivity_mv_per_bar = ");
  EXPECT_NEAR(sensitivity, kSheetMvPerBar * (1 + kChosenGainError),
              kSheetMvPerBar * tolerance_bar(kTesterBar) / (kTesterBar - kAmbientBar));
  EXPECT_NEAR(number_after(text, "\noffset_bar = "), kChosenOffsetBar / (1 + kChosenGainError), tolerance_bar(0.0));
  EXPECT_NE(text.find("  # from the sheet"), std::string::npos) << text;  // the comment kept
  EXPECT_EQ(text.find("# cell 3: the pressure chain, engine stopped\n[sim]\n"), 0u) << text;

  // Under the written configuration the chain reads the true pressure (a dry run of the zero measures and reports).
  int seed = 3;
  for (const double p : {kAmbientBar, kTesterBar, 60.0}) {
    set_static_pressure(c, p, seed++);
    const auto check = calibrate(c, "--dry-run --reference-bar " + std::to_string(p));
    ASSERT_EQ(check.status, 0) << check.text;
    const double read = number_after(check.text, "pressure chain: ");
    std::printf("at %.3f bar the calibrated chain reads %.5f bar (tolerance %.5f bar)\n", p, read, tolerance_bar(p));
    EXPECT_NEAR(read, p, tolerance_bar(p)) << check.text;
  }
  const std::string history = noisemon::test::slurp(c.history);
  EXPECT_NE(history.find(",pressure-zero,7113,10.0000,0.000,,,1.0130,0.410"), std::string::npos) << history;
  EXPECT_NE(history.find(",pressure-gain,7113,10.4"), std::string::npos) << history;
  EXPECT_NE(gain.text.find("warning: the pressure chain's sensitivity moved +4.0 %"), std::string::npos) << gain.text;
}

TEST(CalibratePressure, AChargeChainsZeroIsRefusedSayingWhyAndItsGainAllowed) {
  const std::string charge =
      "# a piezoelectric transducer\n[sim]\nstopped = true\nstatic_pressure_bar = 20.0\n"
      "pressure_gain_error = 0.04\nmic_count = 2\n\n[comedi.pressure]\n"
      "sensitivity_pc_per_bar = 16.2\namplifier_mv_per_pc = 5.0\n";
  const PressureCell c = make_pressure_cell(charge);
  const auto zero = calibrate(c, "--reference-bar 1.013");
  EXPECT_EQ(zero.status, 1);
  EXPECT_NE(zero.text.find("a charge chain (sensitivity_pc_per_bar behind a charge amplifier) has no absolute zero: "
                           "the amplifier drifts"),
            std::string::npos)
      << zero.text;
  EXPECT_NE(zero.text.find("pegging ([comedi.pressure] peg_pa)"), std::string::npos) << zero.text;
  EXPECT_EQ(noisemon::test::slurp(c.config), charge);
  EXPECT_FALSE(std::ifstream(c.history).good());
  // The gain, from the amplifier's reset (0 bar): 20.8 read at 20 applied.
  const auto gain = calibrate(c, "--gain --reference-bar 20");
  ASSERT_EQ(gain.status, 0) << gain.text;
  const std::string text = noisemon::test::slurp(c.config);
  EXPECT_NEAR(number_after(text, "sensitivity_pc_per_bar = "), 16.2 * 1.04, 16.2 * 5.0 * standard_error_bar() / 20.0)
      << text;
  EXPECT_EQ(text.find("\noffset_bar"), std::string::npos) << text;
}

TEST(CalibratePressure, ATurningEngineOrAnUnsteadyReadingIsRefusedAndNothingWritten) {
  std::string turning = pressure_cell(kAmbientBar);
  turning.replace(turning.find("stopped = true"), 14, "speed_rpm = 1500.0");
  const PressureCell t = make_pressure_cell(turning);
  const auto moving = calibrate(t, "--reference-bar 1.013");
  EXPECT_EQ(moving.status, 1);
  EXPECT_NE(moving.text.find("the engine is turning ("), std::string::npos) << moving.text;
  EXPECT_NE(moving.text.find("rpm while measuring): the pressure chain is calibrated with the engine stopped"),
            std::string::npos)
      << moving.text;
  EXPECT_EQ(noisemon::test::slurp(t.config), turning);
  EXPECT_FALSE(std::ifstream(t.history).good());

  const std::string noisy = pressure_cell(kAmbientBar, "pressure_noise_bar = 0.3\n");
  const PressureCell n = make_pressure_cell(noisy);
  const auto unsteady = calibrate(n, "--reference-bar 1.013");
  EXPECT_EQ(unsteady.status, 1);
  EXPECT_NE(unsteady.text.find("the reading is not steady: its standard deviation over 2 s is 0.30"), std::string::npos)
      << unsteady.text;
  EXPECT_EQ(noisemon::test::slurp(n.config), noisy);
  EXPECT_FALSE(std::ifstream(n.history).good());
}

TEST(CalibratePressure, ABadReferenceIsAnErrorNamingTheOption) {
  const std::string text = pressure_cell(kTesterBar);
  const PressureCell c = make_pressure_cell(text);
  for (const char* bad : {"abc", "-1", "1e9"}) {
    const auto out = calibrate(c, std::string("--reference-bar ") + bad);
    EXPECT_NE(out.status, 0);
    EXPECT_NE(out.text.find("--reference-bar"), std::string::npos) << bad << ": " << out.text;
  }
  const auto missing = calibrate(c, "");
  EXPECT_NE(missing.status, 0);
  EXPECT_NE(missing.text.find("--pressure requires --reference-bar"), std::string::npos) << missing.text;
  const auto low = calibrate(c, "--gain --reference-bar 2");
  EXPECT_EQ(low.status, 1);
  EXPECT_NE(low.text.find("--reference-bar 2 is below 5 bar"), std::string::npos) << low.text;
  const auto unzeroed = calibrate(c, "--gain --reference-bar 20");
  EXPECT_EQ(unzeroed.status, 1);
  EXPECT_NE(unzeroed.text.find("the history holds no zero of the pressure chain: zero it first"), std::string::npos)
      << unzeroed.text;
  EXPECT_EQ(noisemon::test::slurp(c.config), text);
  EXPECT_FALSE(std::ifstream(c.history).good());
}
