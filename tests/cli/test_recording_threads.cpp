// to_recording resamples the pressure and the microphones on two threads: the result must not depend on it, an
// exception of either thread must reach the caller (the pressure's first, as when they ran one after the other),
// and to_recording(RunDir&&) must give the same recording while freeing the run's columns. The log writer
// reuses its raw block messages: the log must read back to the recording's frames.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "cli/formats/recording.hpp"
#include "tests/support/unique_temp.hpp"

using namespace noisemon::drivers;
using namespace noisemon::cli::formats;
namespace fs = std::filesystem;

namespace {

// 0.2 s of a 0.5 deg encoder at 3000 rpm (a pressure peak every cycle) and two 51.2 kHz microphones.
formats::RunDir small_run(bool mics = true) {
  formats::RunDir run;
  run.condition = {"threads", 3000.0, 10.0, 12.0, 900.0, false};
  for (int i = 0;; ++i) {
    const double crank = -360.0 + 0.5 * i, t = (crank + 360.0) / 18000.0 + 0.001;
    if (t > 0.2) break;
    const double c = crank - 720.0 * std::round(crank / 720.0);
    run.time_s.push_back(t);
    run.crank_deg.push_back(crank);
    run.pressure_pa.push_back(1e5 + 4e6 * std::exp(-0.5 * (c / 25.0) * (c / 25.0)));
  }
  if (mics) {
    run.mic_count = 2;
    run.mic_rate_hz = 51200;
    for (int k = 0; k < 51200 / 5; ++k)
      for (int ch = 0; ch < 2; ++ch) run.mic_pa.push_back(static_cast<float>(0.3 * std::sin(0.01 * k * (ch + 1))));
    run.mic_positions_m = {{1.0, 0.0, 1.4}, {0.0, 1.0, 1.4}};
  }
  return run;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  // memcmp must not see the null data() of an empty vector (UBSan), even for a size of 0.
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

std::string error_of(formats::RunDir run) {
  try {
    to_recording(run, 0);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(RecordingThreads, AMovedRunGivesTheSameRecordingAndIsFreed) {
  for (const bool mics : {true, false}) {
    const formats::RunDir run = small_run(mics);
    const Recording a = to_recording(run, 1'000'000);
    formats::RunDir moved = run;
    const Recording b = to_recording(std::move(moved), 1'000'000);
    EXPECT_EQ(a.first_index, b.first_index);
    EXPECT_GT(a.frames(), 7000u);
    EXPECT_TRUE(same_bits(a.pressure_pa, b.pressure_pa));
    EXPECT_TRUE(same_bits(a.crank_deg, b.crank_deg));
    EXPECT_TRUE(same_bits(a.mics_pa, b.mics_pa));
    EXPECT_EQ(a.mics_pa.size(), mics ? 2 * a.frames() : 0u);
    ASSERT_EQ(b.operating_points.size(), 1u);
    EXPECT_EQ(a.operating_points[0].utime, b.operating_points[0].utime);
    EXPECT_EQ(a.operating_points[0].speed_rpm, b.operating_points[0].speed_rpm);
    EXPECT_EQ(a.info.pressure_edges_per_rev, b.info.pressure_edges_per_rev);
    EXPECT_EQ(a.info.mic_passband_hz, b.info.mic_passband_hz);
    // What was moved keeps its condition and layout; its sample columns are gone.
    EXPECT_TRUE(moved.time_s.empty() && moved.crank_deg.empty() && moved.pressure_pa.empty() && moved.mic_pa.empty());
    EXPECT_EQ(moved.condition.name, "threads");
    EXPECT_EQ(moved.mic_count, mics ? 2u : 0u);
  }
}

TEST(RecordingThreads, AnUnknownSpeedIsMeasuredBeforeTheColumnsAreFreed) {
  formats::RunDir run = small_run();
  run.condition.speed_rpm = std::nan("");
  const Recording rec = to_recording(std::move(run), 0);
  EXPECT_NEAR(rec.operating_points.at(0).speed_rpm, 3000.0, 1e-6);
}

TEST(RecordingThreads, EitherThreadsErrorReachesTheCallerThePressuresFirst) {
  formats::RunDir bad_mics = small_run();
  bad_mics.mic_rate_hz = 44100.5;
  EXPECT_NE(error_of(bad_mics).find("RationalResampler"), std::string::npos) << error_of(bad_mics);
  formats::RunDir bad_pressure = small_run();
  std::swap(bad_pressure.time_s[100], bad_pressure.time_s[101]);
  EXPECT_NE(error_of(bad_pressure).find("strictly increasing"), std::string::npos) << error_of(bad_pressure);
  formats::RunDir both = bad_pressure;
  both.mic_rate_hz = 44100.5;
  EXPECT_NE(error_of(both).find("strictly increasing"), std::string::npos) << error_of(both);
}

TEST(RecordingThreads, TheLogReadsBackToTheRecordingsFrames) {
  // A partial last block and a stream of 2 channels next to one of 2 microphones: the reused messages resize.
  const Recording rec = to_recording(small_run(), 2'000'000);
  ASSERT_NE(rec.frames() % 256, 0u);
  const fs::path log = fs::path(noisemon::test::unique_temp_dir()) / "threads.lcmlog";
  write_recordings_log(log, {rec});
  const std::vector<Recording> back = read_recordings_log(log);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].first_index, rec.first_index);
  EXPECT_TRUE(same_bits(back[0].pressure_pa, rec.pressure_pa));
  EXPECT_TRUE(same_bits(back[0].crank_deg, rec.crank_deg));
  EXPECT_TRUE(same_bits(back[0].mics_pa, rec.mics_pa));
}
