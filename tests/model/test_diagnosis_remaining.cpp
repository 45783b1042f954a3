// What the verdict leaves, on a hand-made dataset whose answer is known by construction: a remaining gap that grows
// by 0.5 dB per 1000 rpm, is largest in one band with its neighbours above half of it, and is mostly in the crank
// windows.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr std::size_t kRemainingBands = 6;
constexpr double kNominal[kRemainingBands] = {500, 630, 800, 1000, 1250, 1600};

struct RemainingCell {
  fit::BandDataset data;
  DiagnosisOptions opt;
  Context cx;

  // Held-out conditions at these speeds (one load) and these input levels (cycle-mean CPL, Pa^2 per band).
  RemainingCell(const std::vector<double>& rpm, const std::vector<double>& cpl_ms_per_band) {
    for (double f : kNominal) {
      dsp::ThirdOctaveBand b;
      b.nominal_hz = b.exact_mid_hz = f;
      data.bands.push_back(b);
    }
    for (std::size_t k = 0; k < rpm.size(); ++k) {
      fit::ConditionData d;
      d.info.name = "fired_" + std::to_string(k);
      d.info.load_nm = 40.0;
      d.bands = kRemainingBands;
      d.cycles = {fit::CycleInfo{120.0 / rpm[k], rpm[k]}, fit::CycleInfo{120.0 / rpm[k], rpm[k]}};
      d.cpl_ms.assign(2 * kRemainingBands, cpl_ms_per_band[k]);
      data.conditions.push_back(d);
      cx.heldout.push_back(k);
    }
    cx.data = &data;
    cx.opt = &opt;
  }
};

TEST(Remaining, ItsTrendWithSpeedIsTheSlopeOfTheMeanGapPerHeldOutCondition) {
  const std::vector<double> rpm{1500, 2000, 2600};
  RemainingCell cell(rpm, {1e6, 2e6, 4e6});
  ModelScore after;
  after.name = "second_mode";
  after.heldout_gap_db = 0.8;
  after.part_band_ms = 0.1;
  after.part_window_ms = 0.5;
  for (double r : rpm) {  // mean over the finite bands: 0.5 dB per krpm, the same spread around it
    const double mean = 0.5 * r / 1000.0;
    after.gaps.push_back({mean - 0.2, mean + 0.2, NAN, mean, mean - 0.1, mean + 0.1});
  }
  const std::vector<double> band_rms{0.1, 0.6, 1.0, 0.7, 0.4, NAN};
  const RemainingGap r = describe_remaining(cell.cx, after, band_rms);
  EXPECT_EQ(r.model, "second_mode");
  EXPECT_DOUBLE_EQ(r.gap_db, 0.8);
  EXPECT_EQ(r.part, "crank windows");
  ASSERT_EQ(r.mean_gap_db.size(), 3u);
  EXPECT_NEAR(r.mean_gap_db[1], 1.0, 1e-12);
  EXPECT_NEAR(r.speed_slope_db_per_krpm, 0.5, 1e-9);
  EXPECT_TRUE(std::isnan(r.load_slope_db_per_nm));  // one load: no trend to read
  // Input levels 3 dB apart per step (1e6, 2e6, 4e6 Pa^2 per band), mean gaps 0.25, 0.25 and 0.3 dB apart:
  // the least-squares slope through (0, 0.75), (3.01, 1.0), (6.02, 1.3).
  const double x1 = 10 * std::log10(2.0), x2 = 10 * std::log10(4.0);
  const double mx = (x1 + x2) / 3, my = (0.75 + 1.0 + 1.3) / 3;
  const double slope = ((0 - mx) * (0.75 - my) + (x1 - mx) * (1.0 - my) + (x2 - mx) * (1.3 - my)) /
                       (mx * mx + (x1 - mx) * (x1 - mx) + (x2 - mx) * (x2 - mx));
  EXPECT_NEAR(r.level_slope_db_per_db, slope, 1e-9);
  // Largest at 800 Hz; 630 and 1000 Hz above half of it, 500 and 1250 Hz not.
  EXPECT_DOUBLE_EQ(r.largest_band_hz, 800.0);
  EXPECT_DOUBLE_EQ(r.largest_band_db, 1.0);
  EXPECT_DOUBLE_EQ(r.from_hz, 630.0);
  EXPECT_DOUBLE_EQ(r.to_hz, 1000.0);
  EXPECT_NE(r.summary.find("0.50 dB per krpm"), std::string::npos) << r.summary;
  EXPECT_NE(r.summary.find("630 Hz to 1.0 kHz"), std::string::npos) << r.summary;
}

TEST(Remaining, AGapWithinTheToleranceIsSaidToBeAndTheMicrophonesCanBeItsLargestPart) {
  RemainingCell cell({1800, 2200}, {1e6, 1e6});
  ModelScore after;
  after.name = "baseline";
  after.heldout_gap_db = 0.3;
  after.part_band_ms = 0.01;
  after.part_mic = 0.08;
  after.part_window_ms = 0.005;
  after.gaps = {std::vector<double>(kRemainingBands, 0.1), std::vector<double>(kRemainingBands, 0.1)};
  const RemainingGap r = describe_remaining(cell.cx, after, std::vector<double>(kRemainingBands, 0.1));
  EXPECT_EQ(r.part, "microphones");
  EXPECT_NEAR(r.speed_slope_db_per_krpm, 0.0, 1e-12);
  EXPECT_NE(r.summary.find("within the tolerance"), std::string::npos) << r.summary;
  // Equal bands: the first is the largest and every band is in its range.
  EXPECT_DOUBLE_EQ(r.from_hz, 500.0);
  EXPECT_DOUBLE_EQ(r.to_hz, 1600.0);
}

}  // namespace
}  // namespace noisemon::model::diagnosis
