// `noisemon calibrate --pressure` and `noisemon check` on a comedi card with the engine stopped. Each builds its
// source as the daemon's registry does (daemon::comedi_source_config at PressureClock::kAtRest) on the fake card's
// pipes (tests/drivers/comedi_fake_card.hpp): no encoder edge comes, the pressure comes on the card's timer, and the
// zero it writes is the one a hand computation from the card's raw code gives. Through the real binary, on a machine
// without the card, the same configuration is an error naming the missing device.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "cli/chain_check.hpp"
#include "cli/pressure_calibration.hpp"
#include "daemon/calibration_history.hpp"
#include "daemon/config.hpp"
#include "daemon/sources.hpp"
#include "tests/cli/run_command.hpp"
#include "tests/drivers/comedi_fake_card.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace nd = noisemon::drivers;
namespace calib_card = comedi_fake;

namespace {

namespace nmd = noisemon::daemon;

constexpr double kCardAmbientBar = 1.013;    // the barometer's reading
constexpr double kCardReadsHighBar = 0.42;   // the chain's zero error the calibration finds
constexpr double kCardMvPerBar = 100.0;      // [comedi.pressure] sensitivity_mv_per_bar
constexpr double kCardRestRateHz = 10000.0;  // [comedi.pressure] rest_scan_rate_hz
constexpr double kCardPipeSeconds = 2.5;     // what each pipe carries (within its 1 MiB)

// The cell: the fake card's devices, a voltage chain from its sheet, not yet zeroed (or `chain` in its place).
std::string comedi_cell(
    const std::string& chain = "sensitivity_mv_per_bar = 100.0   # from the sheet\noffset_bar = 0.0\n") {
  return "# the cell's DAQ card\n[daemon]\nsource = \"comedi\"\n\n"
         "[comedi.pressure]\ndevice = \"/dev/test-pressure\"\nsubdevice = 0\nchannel = 0\n" +
         chain +
         "rest_scan_rate_hz = 10000\n\n"
         "[comedi.encoder]\ndevice = \"/dev/test-counter\"\nsubdevice = 11\ncounts_per_rev = 1440\n\n"
         "[comedi.mics]\ndevice = \"/dev/test-mics\"\nsubdevice = 0\nscan_rate_hz = 50000.0\nchannels = [0, 1, 2]\n"
         "range = 1\nsensitivity_mv_per_pa = [50.0, 12.5, 31.6]\n";
}

// The card's one code for the ambient pressure read kCardReadsHighBar high (range 0, +-10 V).
std::uint16_t ambient_code() {
  return calib_card::code16((kCardAmbientBar + kCardReadsHighBar) * kCardMvPerBar * 1e-3, 0);
}

// The comedi source the daemon's registry builds from the configuration, its acquisitions the fake card's pipes: the
// pressure on its timer (at rest) reads ambient_code(), the encoder sees no edge, the microphones their tones.
std::unique_ptr<nd::Source> piped_card(const nmd::Config& config, nmd::PressureClock clock, bool& at_rest) {
  const nd::comedi::ComediSourceConfig comedi = nmd::comedi_source_config(config, clock);
  at_rest = comedi.at_rest;
  return nd::comedi::make_comedi_source(
      comedi,
      [](const nd::comedi::ComediAcquisitionConfig& a) {
        auto pipe = std::make_unique<calib_card::PipeAcquisition>(a, calib_card::kEpoch + calib_card::kMicOriginUs);
        if (a.device_path == "/dev/test-mics") pipe->feed(calib_card::mic_bytes(kCardPipeSeconds));
        if (a.device_path == "/dev/test-pressure" && a.clock == nd::comedi::ScanClock::kTimed) {
          std::vector<std::byte> codes;
          for (auto n = static_cast<std::size_t>(kCardPipeSeconds * a.scan_rate_hz); n > 0; --n)
            calib_card::append(codes, ambient_code());
          pipe->feed(std::move(codes));
        }
        return pipe;
      },
      calib_card::kEpoch);
}

}  // namespace

TEST(CalibratePressureComedi, ZeroAtRestOnTheCardsTimerWritesTheHandComputedOffset) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string config = dir + "/card.toml", history = dir + "/card.calibrations.csv";
  std::ofstream(config) << comedi_cell();
  const nmd::Config parsed = nmd::load_config(config);
  EXPECT_DOUBLE_EQ(parsed.comedi.pressure.rest_scan_rate_hz, kCardRestRateHz);

  noisemon::cli::PressureCalibration request;
  request.config_path = config;
  request.reference_bar = kCardAmbientBar;
  request.seconds = 1.0;
  request.serial = "7113";
  bool at_rest = false;
  ASSERT_EQ(noisemon::cli::calibrate_pressure(
                request, [&](const nmd::Config& c, nmd::PressureClock clock) { return piped_card(c, clock, at_rest); }),
            0);
  EXPECT_TRUE(at_rest);  // the calibration asked for the pressure on the card's timer

  // By hand: the code's volts through 100 mV/bar, less the barometer's reading.
  const std::uint16_t code = ambient_code();
  const double volts = calib_card::kRangeLo[0] + code * (calib_card::kRangeHi[0] - calib_card::kRangeLo[0]) / 65535.0;
  const double expected_offset = volts / (kCardMvPerBar * 1e-3) - kCardAmbientBar;
  EXPECT_NEAR(expected_offset, kCardReadsHighBar, 0.004);  // one code is 3 mbar
  const nmd::Config written = nmd::load_config(config);
  EXPECT_NEAR(written.comedi.pressure.offset_bar, expected_offset, 1e-5);  // written to 5 decimals
  const std::string text = noisemon::test::slurp(config);
  EXPECT_EQ(text.find("# the cell's DAQ card\n"), 0u) << text;
  EXPECT_NE(text.find("sensitivity_mv_per_bar = 100.0   # from the sheet"), std::string::npos) << text;
  const auto rows = nmd::read_calibration_history(history);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].pressure_step, "zero");
  EXPECT_NEAR(rows[0].offset_bar, expected_offset, 1e-5);
}

TEST(CalibratePressureComedi, MissingCardIsAnErrorNamingTheDevice) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string config = dir + "/card.toml";
  std::ofstream(config) << comedi_cell();
  const auto out = noisemon::test::run_command(noisemon::test::kNoisemon + " calibrate --config " + config +
                                               " --pressure --reference-bar 1.013 --seconds 1");
  EXPECT_NE(out.status, 0) << out.text;
  EXPECT_NE(out.text.find("/dev/test-pressure"), std::string::npos) << out.text;
  EXPECT_EQ(out.text.find("no pressure samples"), std::string::npos) << out.text;
}

// The pressure row of `noisemon check` with the engine stopped, on the configuration `chain` (the card reads the
// ambient pressure kCardReadsHighBar high); at_rest: whether any listen asked for the pressure on the card's timer.
noisemon::cli::CheckRow card_pressure_row(const std::string& chain, bool& at_rest) {
  const std::string config = noisemon::test::unique_temp("check-card.toml").string();
  std::ofstream(config) << comedi_cell(chain);
  at_rest = false;
  const auto rows = noisemon::cli::check_measurement_chain(nmd::load_config(config), 1.0,
                                                           [&](const nmd::Config& c, nmd::PressureClock clock) {
                                                             bool rest = false;
                                                             auto source = piped_card(c, clock, rest);
                                                             at_rest = at_rest || rest;
                                                             return source;
                                                           });
  for (const auto& r : rows)
    if (r.item == "pressure") return r;
  ADD_FAILURE() << "no pressure row";
  return {};
}

// No edge comes, so the encoder-clocked pressure is silent; check listens again on the card's timer and compares
// the mean with the atmosphere: 0.42 bar high fails, the same card with that offset configured passes, and a charge
// chain (no absolute zero) is shown but not judged.
TEST(CheckComedi, PressureOffsetAtRestIsReadOnTheCardsTimer) {
  bool at_rest = false;
  const auto unzeroed = card_pressure_row("sensitivity_mv_per_bar = 100.0\noffset_bar = 0.0\n", at_rest);
  EXPECT_TRUE(at_rest);
  EXPECT_TRUE(unzeroed.failed) << unzeroed.value << " " << unzeroed.verdict;
  EXPECT_NE(unzeroed.value.find(std::to_string(kCardAmbientBar + kCardReadsHighBar).substr(0, 4)), std::string::npos)
      << unzeroed.value;

  const auto zeroed = card_pressure_row("sensitivity_mv_per_bar = 100.0\noffset_bar = 0.42\n", at_rest);
  EXPECT_FALSE(zeroed.failed) << zeroed.value << " " << zeroed.verdict;
  EXPECT_EQ(zeroed.verdict, "ok");

  const auto charge = card_pressure_row("sensitivity_pc_per_bar = 10.0\namplifier_mv_per_pc = 10.0\n", at_rest);
  EXPECT_TRUE(at_rest);
  EXPECT_FALSE(charge.failed) << charge.value << " " << charge.verdict;
  EXPECT_NE(charge.verdict.find("charge chain"), std::string::npos) << charge.verdict;
}
