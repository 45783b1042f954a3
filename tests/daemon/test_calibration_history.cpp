// The calibration history with the pressure chain's rows beside the microphones': each read back as written, a file
// from before the pressure rows (seven columns, its own header) read the same, the latest zero found, and the
// microphones' ages blind to the pressure rows.
#include "daemon/calibration_history.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "tests/support/unique_temp.hpp"

namespace nd = noisemon::daemon;

TEST(CalibrationHistory, PressureRowsSitBesideTheMicrophonesAndAnOlderFileStillReads) {
  const std::string path = noisemon::test::unique_temp("cell.calibrations.csv").string();
  std::ofstream(path) << "utc,microphone,serial,sensitivity_mv_per_pa,change_db,level_db,frequency_hz\n"
                         "2026-03-01T08:00:00Z,2,3021456,50.2000,0.010,94.00,1000.10\n";
  nd::CalibrationRecord zero;
  zero.utime = 1'780'000'000'000'000, zero.serial = "7113", zero.sensitivity = 10.0;
  zero.pressure_step = "zero", zero.reference_bar = 1.013, zero.offset_bar = 0.41051;
  nd::append_calibration(path, zero);
  nd::CalibrationRecord gain = zero;
  gain.utime += 60'000'000, gain.pressure_step = "gain", gain.sensitivity = 10.4, gain.change_db = 0.341;
  gain.reference_bar = 20.0, gain.offset_bar = 0.35576;
  nd::append_calibration(path, gain);
  std::size_t skipped = 0;
  const auto rows = nd::read_calibration_history(path, &skipped);
  EXPECT_EQ(skipped, 0u);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].microphone, 2);
  EXPECT_DOUBLE_EQ(rows[0].sensitivity, 50.2);
  EXPECT_DOUBLE_EQ(rows[0].frequency_hz, 1000.1);
  EXPECT_EQ(rows[1].microphone, 0);
  EXPECT_EQ(rows[1].pressure_step, "zero");
  EXPECT_EQ(rows[1].serial, "7113");
  EXPECT_DOUBLE_EQ(rows[1].reference_bar, 1.013);
  EXPECT_DOUBLE_EQ(rows[1].offset_bar, 0.41051);
  EXPECT_EQ(rows[2].pressure_step, "gain");
  EXPECT_DOUBLE_EQ(rows[2].sensitivity, 10.4);
  const nd::CalibrationRecord* last_zero = nd::last_pressure_calibration(rows, "zero");
  ASSERT_NE(last_zero, nullptr);
  EXPECT_EQ(last_zero->utime, zero.utime);
  EXPECT_EQ(nd::last_pressure_calibration(rows, "gain")->utime, gain.utime);
  const auto ages = nd::last_calibrations(rows, 2);
  EXPECT_EQ(ages[0], 0);  // the pressure rows are no microphone's
  EXPECT_EQ(ages[1], rows[0].utime);
  // A mistyped step is a bad row, counted, never fatal.
  std::ofstream(path, std::ios::app) << "2026-03-02T08:00:00Z,pressure-span,,10.0,0.0,,,20.0,0.1\n";
  EXPECT_EQ(nd::read_calibration_history(path, &skipped).size(), 3u);
  EXPECT_EQ(skipped, 1u);
}
