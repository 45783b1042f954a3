// Statistics over cycles against values worked out by hand: the energy mean of two levels, a sample standard
// deviation, Leq over cycles of unequal length; flagged cycles counted and left out.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "daemon/cycle_statistics.hpp"

using namespace noisemon;

namespace {

noisemon::cycle_report_t report(double lpa, double imep, double duration, std::int32_t flags = 0) {
  noisemon::cycle_report_t r{};
  r.duration_s = duration;
  r.speed_rpm = 120.0 / duration;
  r.lpa_measured_db = lpa;
  r.lpa_predicted_db = lpa + 1.0;
  r.lwa_measured_db = r.lwa_predicted_db = lpa + 12.8;
  r.imep_net_bar = imep;
  r.ca50_deg = imep + 10.0;  // angles with a mean away from 0: a COV could be computed, and must not be
  r.peak_pressure_deg = imep;
  r.pegging_offset_bar = imep - 6.0;  // -1 and +1 in the two valid cycles: both signs
  r.load_nm = r.soi_deg_btdc = r.rail_pressure_bar = std::numeric_limits<double>::quiet_NaN();
  r.nbands = 2;
  r.band_hz = {1000.f, 2000.f};
  r.spl_a_measured_db = {static_cast<float>(lpa), 70.f};
  r.spl_a_predicted_db = {static_cast<float>(lpa), 70.f};
  r.cpl_db = {150.f, 140.f};
  r.band_flags = {0, 0};
  r.flags = flags;
  return r;
}

const daemon::ScalarStats& scalar(const daemon::CycleStatistics& s, const std::string& name) {
  for (const auto& v : s.scalars)
    if (v.name == name) return v;
  throw std::runtime_error("no scalar " + name);
}

}  // namespace

TEST(CycleStatistics, LevelsAreEnergyMeansAndOtherScalarsArithmetic) {
  const auto s = daemon::statistics_of({report(80.0, 5.0, 0.04), report(90.0, 7.0, 0.04),
                                        report(120.0, 100.0, 0.04, noisemon::cycle_report_t::CYCLE_GAP)});
  EXPECT_EQ(s.cycles, 3);
  EXPECT_EQ(s.valid, 2);
  EXPECT_EQ(s.flagged, 1);
  // 10 lg((10^8 + 10^9) / 2) = 87.404 dB; never the 85 dB of the arithmetic mean.
  const auto& lpa = scalar(s, "lpa_measured_db");
  EXPECT_NEAR(lpa.mean, 87.4036, 1e-4);
  EXPECT_TRUE(lpa.level);
  EXPECT_NEAR(lpa.min, 80.0, 1e-12);
  EXPECT_NEAR(lpa.max, 90.0, 1e-12);
  const auto& imep = scalar(s, "imep_net_bar");
  EXPECT_NEAR(imep.mean, 6.0, 1e-12);
  EXPECT_NEAR(imep.std, std::sqrt(2.0), 1e-12);  // sample standard deviation of {5, 7}
  EXPECT_NEAR(imep.cov, std::sqrt(2.0) / 6.0, 1e-12);
  EXPECT_NEAR(imep.lnv, 5.0 / 6.0, 1e-12);  // the lowest normalised value: 5 of a mean of 6
  // A crank angle has a spread but no COV: its zero is TDC by convention. Nor has a level.
  EXPECT_TRUE(std::isnan(scalar(s, "ca50_deg").cov));
  EXPECT_TRUE(std::isnan(scalar(s, "peak_pressure_deg").cov));
  EXPECT_TRUE(std::isnan(lpa.cov));
  EXPECT_TRUE(std::isnan(scalar(s, "pegging_offset_bar").cov));  // values of both signs: no COV
  EXPECT_NEAR(scalar(s, "pegging_offset_bar").std, std::sqrt(2.0), 1e-12);
  // Unknown values: no statistics, not zeros.
  EXPECT_EQ(scalar(s, "load_nm").n, 0);
  EXPECT_TRUE(std::isnan(scalar(s, "load_nm").mean));
  // Band spectra: energy means per band.
  ASSERT_EQ(s.spl_a_measured_db.size(), 2u);
  EXPECT_NEAR(s.spl_a_measured_db[0], 87.4036, 1e-4);
  EXPECT_NEAR(s.spl_a_measured_db[1], 70.0, 1e-5);
}

TEST(CycleStatistics, LeqWeightsEachCycleByItsDuration) {
  // 0.03 s at 80 dB and 0.09 s at 90 dB: 10 lg((0.03 * 10^8 + 0.09 * 10^9) / 0.12) = 10 lg(7.75e8) = 88.893 dB.
  const auto s = daemon::statistics_of({report(80.0, 5.0, 0.03), report(90.0, 5.0, 0.09)});
  EXPECT_NEAR(s.seconds, 0.12, 1e-12);
  EXPECT_NEAR(s.leq_a_measured_db, 88.8930, 1e-4);
  EXPECT_NEAR(s.leq_a_predicted_db, 89.8930, 1e-4);
  // The energy mean per cycle weights them equally instead: 87.404 dB.
  EXPECT_NEAR(scalar(s, "lpa_measured_db").mean, 87.4036, 1e-4);
}

TEST(CycleStatistics, LeqCoversOnlyTheTimeOfTheCyclesThatHaveTheLevel) {
  // A cycle whose pressure was faulty has no prediction (NaN): its 0.09 s are not silence. Predicted Leq is that
  // of the 0.03 s cycle alone (81 dB); measured Leq covers both, as above. An encoder-flagged cycle (uncertain
  // boundaries: not one cycle's numbers) is counted and left out, like one with a gap.
  auto faulty = report(90.0, 5.0, 0.09, noisemon::cycle_report_t::CYCLE_PRESSURE_FAULT);
  faulty.lpa_predicted_db = faulty.lwa_predicted_db = std::numeric_limits<double>::quiet_NaN();
  const auto s = daemon::statistics_of(
      {report(80.0, 5.0, 0.03), faulty, report(120.0, 5.0, 0.05, noisemon::cycle_report_t::CYCLE_ENCODER)});
  EXPECT_EQ(s.valid, 2);
  EXPECT_EQ(s.flagged, 1);
  EXPECT_NEAR(s.seconds, 0.12, 1e-12);
  EXPECT_NEAR(s.leq_a_measured_db, 88.8930, 1e-4);
  EXPECT_NEAR(s.leq_a_predicted_db, 81.0, 1e-9);
  EXPECT_EQ(scalar(s, "lpa_predicted_db").n, 1);
}

TEST(CycleStatistics, TextJsonAndCsvCarryEveryScalar) {
  const auto s = daemon::statistics_of({report(80.0, 5.0, 0.04), report(90.0, 7.0, 0.04)});
  const std::string text = daemon::statistics_text(s), json = daemon::statistics_json(s),
                    csv = daemon::statistics_csv_rows(s, "run1");
  for (const auto& v : s.scalars) {
    EXPECT_NE(text.find(v.name), std::string::npos) << v.name;
    EXPECT_NE(json.find("\"" + v.name + "\""), std::string::npos) << v.name;
    EXPECT_NE(csv.find("run1," + v.name + ","), std::string::npos) << v.name;
  }
  EXPECT_EQ(csv.find("-nan"), std::string::npos);
  EXPECT_NE(json.find("null"), std::string::npos);  // the unknown load
}

// ISO 3744:2010 over the cycles, by hand: the 1 kHz band's energy mean is 87.404 dB(A) (80 and 90); its background,
// given unweighted, sits 8 dB below it in A-weighted terms: K1 = -10 lg(1 - 10^-0.8) = 0.7494 dB. The 2 kHz band
// holds 70 dB(A) against a background 30 dB under it: uncorrected. A third band is BELOW_FIRING in one valid cycle:
// out. A fourth is 3 dB above its background: K1 = 1.3 dB, and the result an upper bound. A fifth, 12.5 kHz, lies
// outside the standard's 100 Hz ... 10 kHz: out. LW = 10 lg(10^((87.404 - 0.7494) / 10) + 10^7 + 10^((50 - 1.3) / 10))
// - K2 + 10 lg(2 pi r^2) + C1 + C2.
TEST(CycleStatistics, SoundPowerOverTheCyclesCorrectsTheEnergyMeanBandsForTheBackground) {
  const double a_1k = 0.0, a_2k = 1.2016;  // IEC 61672-1 A-weighting at the exact mid-bands 1000 and 1995.3 Hz
  auto with_background = [&](double lpa, std::int8_t third_band_flags) {
    noisemon::cycle_report_t r = report(lpa, 5.0, 0.04);
    r.nbands = 5;
    r.band_hz = {1000.f, 2000.f, 20.f, 4000.f, 12500.f};
    r.spl_a_measured_db = {static_cast<float>(lpa), 70.f, 60.f, 50.f, 60.f};
    r.spl_a_predicted_db = {static_cast<float>(lpa), 70.f, 60.f, 50.f, 60.f};
    r.cpl_db = {150.f, 140.f, 150.f, 140.f, 120.f};
    r.band_flags = {0, 0, third_band_flags, 0, 0};
    r.background_db = {static_cast<float>(87.4036 - 8.0 - a_1k), static_cast<float>(40.0 - a_2k), NAN,
                       static_cast<float>(47.0 - 0.9642), NAN};
    r.k2_db = 1.5;
    r.c1_db = -0.13;
    r.c2_db = 0.01;
    r.lw_low_hz = 100.f;
    r.lw_high_hz = 10000.f;
    r.radius_m = 1.75;
    return r;
  };
  const auto s = daemon::statistics_of(
      {with_background(80.0, 0), with_background(90.0, noisemon::cycle_report_t::BAND_BELOW_FIRING)});
  ASSERT_EQ(s.band_validity.size(), 5u);
  EXPECT_EQ(s.band_validity[0], daemon::kBandCorrected);
  EXPECT_EQ(s.band_validity[1], daemon::kBandUncorrected);
  EXPECT_EQ(s.band_validity[2], daemon::kBandNotInOverall);
  EXPECT_EQ(s.band_validity[3], daemon::kBandUpperBound);
  EXPECT_EQ(s.band_validity[4], daemon::kBandOutsideLwRange);
  const double k1 = -10 * std::log10(1 - std::pow(10, -0.8));
  EXPECT_NEAR(s.k1_db[0], k1, 1e-3);
  EXPECT_EQ(s.k1_db[1], 0.0);
  EXPECT_EQ(s.k1_db[3], 1.3);
  EXPECT_TRUE(std::isnan(s.k1_db[4]));
  EXPECT_TRUE(s.lwa_run_upper_bound);
  const double surface = 10 * std::log10(2 * 3.141592653589793 * 1.75 * 1.75), c = -0.13 + 0.01;
  EXPECT_NEAR(s.lwa_run_measured_db,
              10 * std::log10(std::pow(10, (87.4036 - k1) / 10) + 1e7 + std::pow(10, 4.87)) - 1.5 + surface + c, 2e-3);
  EXPECT_NEAR(s.lwa_run_predicted_db, 10 * std::log10(std::pow(10, 8.74036) + 1e7 + 1e5) - 1.5 + surface + c, 2e-3);
  // The text names the corrected and the bounding bands, the range and the corrections; the message carries them.
  const std::string text = daemon::statistics_text(s);
  EXPECT_NE(text.find("corrected for the background (K1): 1000 Hz (0.75 dB)"), std::string::npos) << text;
  EXPECT_NE(text.find("(K1 1.3 dB, LW an upper bound): 4000 Hz"), std::string::npos) << text;
  EXPECT_NE(text.find("100 Hz ... 10 kHz"), std::string::npos) << text;
  EXPECT_NE(text.find("(an upper bound)"), std::string::npos) << text;
  const auto back = daemon::from_message(daemon::to_message(s, 100, 0));
  EXPECT_EQ(back.lwa_run_measured_db, s.lwa_run_measured_db);
  EXPECT_EQ(back.band_validity, s.band_validity);
  EXPECT_EQ(back.lwa_run_upper_bound, true);
  EXPECT_EQ(back.c1_db, -0.13);
}
