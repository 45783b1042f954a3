// The where stage: where the baseline's gap lies. On a dataset with known levels (microphones a pure gain of the
// pressure, a second held-out condition at twice the pressure) and a baseline score given by hand: roles, measured
// attenuation against the IEC 61672-1 A-weighting written out here, the input-level and injection-timing slopes,
// the microphone offsets, the crank windows, the floors and their summary.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "model/diagnosis/stages.hpp"
#include "tests/model/test_diagnosis_data.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kWhereRpm = 3000.0;
const std::vector<double> kMicAmplitude{1.0, 1.0, 2.0, 1.0};  // microphone 3 hears twice the pressure

// IEC 61672-1 A-weighting, dB.
double a_weighting(double f) {
  const double f2 = f * f;
  const double ra =
      12194.0 * 12194.0 * f2 * f2 /
      ((f2 + 20.6 * 20.6) * std::sqrt((f2 + 107.7 * 107.7) * (f2 + 737.9 * 737.9)) * (f2 + 12194.0 * 12194.0));
  return 20.0 * std::log10(ra) + 2.0;
}

testdata::Recipe gain_run(const std::string& name, double scale, double soi) {
  testdata::Recipe r;
  r.info = testdata::ideal_info(name, kWhereRpm);
  r.info.soi_deg_btdc = soi;
  r.pressure_cycle = testdata::pressure_cycle(kWhereRpm, scale, 7);
  for (double g : kMicAmplitude) {
    std::vector<double> m = r.pressure_cycle;
    for (double& x : m) x = g * (x - 1e5);
    r.mic_cycles.push_back(std::move(m));
  }
  return r;
}

testdata::Recipe noise_run(const std::string& name, double sigma, std::uint64_t seed) {
  testdata::Recipe r;
  r.info = testdata::ideal_info(name, kWhereRpm);
  r.pressure_cycle.assign(static_cast<std::size_t>(testdata::kFs * 120.0 / kWhereRpm), 1e5);
  for (std::size_t m = 0; m < kMicAmplitude.size(); ++m) {
    r.mic_cycles.emplace_back(r.pressure_cycle.size(), 0.0);
    r.mic_extra.push_back(testdata::white_noise(testdata::recording_frames(r), sigma, seed + m));
  }
  return r;
}

fit::BandDataset dataset() {
  testdata::Recipe motored = noise_run("motored_1", 0.01, 100), background = noise_run("background", 1e-6, 200);
  motored.info.motored = true;
  background.info.background = true;
  return fit::make_dataset({testdata::build(testdata::fired("t_1", 2400, 1.0, preset("linear"), {0, 0, 0, 0}, 5)),
                            testdata::build(gain_run("h_1", 1.0, 12.0)), testdata::build(gain_run("h_2", 2.0, 18.0)),
                            testdata::build(motored), testdata::build(background)});
}

double mean_mic_ms(const fit::ConditionData& d, std::size_t b) {
  double s = 0.0;
  for (std::size_t c = 0; c < d.cycle_count(); ++c) s += d.mic_avg_ms(c, b);
  return s / static_cast<double>(d.cycle_count());
}

// The dataset, the first stages, a baseline given by hand and the where stage on it, once for every test.
struct Described {
  const fit::BandDataset data = dataset();
  DiagnosisOptions opt;
  Context cx;
  Evaluated base;
  DiagnosisResult res;
  std::size_t nb = 0;

  Described() {
    opt.train = {"t"};
    opt.holdout = {"h"};
    cx.data = &data;
    cx.opt = &opt;
    assign_roles(cx);
    mark_bands_and_floors(cx, preset("linear"));
    nb = data.band_count();
    // h_1 agrees, h_2 is 1 dB off in every scored band; predictions = measurement.
    ModelScore& s = base.score;
    for (std::size_t h = 0; h < 2; ++h) {
      const std::size_t k = cx.heldout[h];
      std::vector<double> gaps(nb, NAN);
      for (std::size_t b = 0; b < nb; ++b)
        if (cx.base_mask[k][b]) gaps[b] = h == 0 ? 0.0 : 1.0;
      s.gaps.push_back(gaps);
      s.att_pred.push_back(std::vector<double>(nb, 10.0 + h));
      fit::ConditionPrediction p;
      const fit::ConditionData& d = data.conditions[k];
      for (std::size_t c = 0; c < d.cycle_count(); ++c)
        for (std::size_t b = 0; b < nb; ++b) p.cycle_ms.push_back(d.mic_avg_ms(c, b));
      base.preds.push_back(p);
    }
    s.window_gaps = {{0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7}, {NAN, 1, 1, 1, 1, 1, 1, 1}};
    s.cell_gaps = {std::vector<double>(kW * nb, 0.5), std::vector<double>(kW * nb, NAN)};
    s.cell_gaps[1][2 * nb + 10] = 1.5;
    res.baseline = s;
    res.verdict.band_before_db.assign(nb, 0.7);
    describe_where(cx, base, res);
  }
};

class WhereStage : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { shared_ = new Described; }
  static void TearDownTestSuite() {
    delete shared_;
    shared_ = nullptr;
  }
  static Described* shared_;
  const fit::BandDataset& data_ = shared_->data;
  const Context& cx_ = shared_->cx;
  const DiagnosisResult& res_ = shared_->res;
  const std::size_t nb_ = shared_->nb;
};
Described* WhereStage::shared_ = nullptr;

// Equal, NaN where the other is NaN.
void expect_same(const std::vector<double>& a, const std::vector<double>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::isnan(b[i])) {
      EXPECT_TRUE(std::isnan(a[i])) << i;
    } else {
      EXPECT_EQ(a[i], b[i]) << i;
    }
}

TEST_F(WhereStage, RolesBandsAndTheBaselinesGapAreReported) {
  const noisemon::model::diagnosis::Where& wh = res_.where;
  EXPECT_EQ(wh.conditions, (std::vector<std::string>{"t_1", "h_1", "h_2", "motored_1", "background"}));
  EXPECT_EQ(wh.roles, (std::vector<std::string>{"train", "heldout", "heldout", "reference", "floor"}));
  ASSERT_EQ(wh.band_hz.size(), nb_);
  EXPECT_EQ(wh.band_hz.front(), 20.0);
  EXPECT_EQ(wh.band_hz.back(), 20000.0);
  EXPECT_EQ(wh.band_notes.back(), "nyquist_cut");
  ASSERT_EQ(wh.gap.size(), 2u);
  for (std::size_t h = 0; h < 2; ++h) expect_same(wh.gap[h], res_.baseline.gaps[h]);
  EXPECT_EQ(wh.gap_per_band_rms, std::vector<double>(nb_, 0.7));
  EXPECT_NEAR(wh.gap_per_condition_rms[0], 0.0, 1e-12);
  EXPECT_NEAR(wh.gap_per_condition_rms[1], 1.0, 1e-12);
  EXPECT_EQ(wh.mean_gap_db, (std::vector<double>{0.0, 1.0}));
  EXPECT_EQ(wh.att_base, res_.baseline.att_pred);
}

TEST_F(WhereStage, MeasuredAttenuationOfAPureGainIsTheGainAndTheAWeighting) {
  // Microphone mean square = mean(g^2) * pressure mean square in every band: CPL - SPL_A = -10 log10(7/4) - A(f).
  const noisemon::model::diagnosis::Where& wh = res_.where;
  ASSERT_EQ(wh.att_meas.size(), 2u);
  for (std::size_t h = 0; h < 2; ++h)
    for (std::size_t b = 0; b < nb_; ++b)
      EXPECT_NEAR(wh.att_meas[h][b], -10.0 * std::log10(7.0 / 4.0) - a_weighting(data_.bands[b].exact_mid_hz), 0.01)
          << data_.bands[b].nominal_hz;
  // Twice the pressure: 6.02 dB more input, overall and per band.
  EXPECT_NEAR(wh.cpl_overall_db[1] - wh.cpl_overall_db[0], 20.0 * std::log10(2.0), 1e-6);
  for (std::size_t b = 0; b < nb_; ++b) EXPECT_NEAR(wh.cpl_db[1][b] - wh.cpl_db[0][b], 20.0 * std::log10(2.0), 1e-6);
}

TEST_F(WhereStage, SlopesOfTheGapAgainstTheInputLevelAndTheInjectionTiming) {
  const noisemon::model::diagnosis::Where& wh = res_.where;
  EXPECT_NEAR(wh.amplitude_slope_db_per_db, 1.0 / (20.0 * std::log10(2.0)), 1e-6);  // 1 dB more gap at +6.02 dB
  EXPECT_NEAR(wh.soi_slope_db_per_deg, 1.0 / 6.0, 1e-12);                           // 1 dB more gap at 6 deg more
  EXPECT_TRUE(std::isnan(wh.speed_slope_db_per_krpm));                              // both at one speed
  EXPECT_TRUE(std::isnan(wh.load_slope_db_per_nm));                                 // and one load
  // Every cycle's gap the same (0): no slope within a condition (NaN where the levels do not spread either).
  EXPECT_FALSE(std::abs(wh.cycle_amplitude_slope_db_per_db) > 1e-9);
}

TEST_F(WhereStage, MicrophoneOffsetsFromTheArray) {
  const noisemon::model::diagnosis::Where& wh = res_.where;
  EXPECT_EQ(wh.mics, (std::vector<std::string>{"mic1", "mic2", "mic3", "mic4"}));
  // Powers 1, 1, 4, 1 against their mean 7/4.
  for (std::size_t m = 0; m < 4; ++m) {
    const double expected = 10.0 * std::log10((m == 2 ? 4.0 : 1.0) / (7.0 / 4.0));
    EXPECT_NEAR(wh.mic_offset_db[m], expected, 1e-9) << m;
    EXPECT_NEAR(wh.mic_gap_rms_db[m], std::abs(expected), 1e-9) << m;  // against the array-average prediction
  }
}

TEST_F(WhereStage, CrankWindowsAreMeansOverTheHeldOutConditionsOfTheFiniteGaps) {
  const noisemon::model::diagnosis::Where& wh = res_.where;
  EXPECT_EQ(wh.window_start_deg, (std::vector<double>{-360, -270, -180, -90, 0, 90, 180, 270}));
  EXPECT_NEAR(wh.window_gap_db[0], 0.0, 1e-12);
  for (std::size_t w = 1; w < kW; ++w) EXPECT_NEAR(wh.window_gap_db[w], (0.1 * w + 1.0) / 2, 1e-12) << w;
  EXPECT_NEAR(wh.window_band_gap_db[2][10], 1.0, 1e-12);  // (0.5 + 1.5) / 2
  EXPECT_NEAR(wh.window_band_gap_db[3][10], 0.5, 1e-12);
}

TEST_F(WhereStage, FloorsTheMotoredExcessAndTheCoherence) {
  const noisemon::model::diagnosis::Where& wh = res_.where;
  for (std::size_t b = 0; b < nb_; ++b) {
    // No block sound in the motored run (constant pressure): its excess is what its microphones hear.
    EXPECT_NEAR(wh.floor_db[b], 10.0 * std::log10(mean_mic_ms(data_.conditions[3], b) / 4e-10), 1e-6);
    EXPECT_NEAR(wh.background_db[b], 10.0 * std::log10(mean_mic_ms(data_.conditions[4], b) / 4e-10), 1e-9);
    EXPECT_NEAR(wh.mic_floor_db[b], wh.background_db[b], 1e-9);
    // Every cycle the same: the cycle-synchronous average holds all the power.
    if (std::isfinite(wh.periodic_share[b])) {
      EXPECT_NEAR(wh.periodic_share[b], 1.0, 1e-3) << b;
    }
  }
  EXPECT_EQ(wh.mic_floor_source, "background runs");
  EXPECT_EQ(wh.pressure_floor_judged_by, std::vector<std::string>(5, "stated"));
  EXPECT_EQ(wh.pressure_floor_stated_bar, std::vector<double>(5, 0.0));
  EXPECT_EQ(wh.floor_limited_bands[1], 0);
  EXPECT_EQ(wh.floor_limited_bands[2], 0);
}

TEST_F(WhereStage, TheFloorSummaryHasOneLinePerGroupOfConditions) {
  const noisemon::model::diagnosis::Where& wh = res_.where;
  ASSERT_EQ(wh.floor_summary.size(), 4u);  // t, h, motored, background
  // Fast scored bands of the held-out runs, eight crank windows each, none at the (ideal) pressure floor.
  int cells = 0;
  for (std::size_t k : cx_.heldout)
    for (std::size_t b = 0; b < nb_; ++b) cells += cx_.fast[b] && cx_.base_mask[k][b] ? 8 : 0;
  EXPECT_GT(cells, 0);
  const std::string bands = " of " + std::to_string(nb_) + " bands floor-limited";
  EXPECT_EQ(wh.floor_summary[1],
            "h (2 runs): 0" + bands + "; 0 of " + std::to_string(cells) + " crank-window cells at the pressure floor");
  // The background run is its own floor: every informative band is floor-limited, from the lowest one up.
  int informative = 0;
  double lowest = 0.0;
  for (std::size_t b = nb_; b-- > 0;)
    if (!data_.bands[b].nyquist_cut && !data_.band_line_free(4, b)) {
      ++informative;
      lowest = data_.bands[b].nominal_hz;
    }
  EXPECT_EQ(wh.floor_summary[3], "background (1 run): " + std::to_string(informative) + bands + " from " +
                                     std::to_string(static_cast<int>(lowest)) +
                                     " Hz up; 0 of 0 crank-window cells at the pressure floor");
}

TEST(LinearSlope, IsTheLeastSquaresSlopeLeavingOutUnknownPairs) {
  EXPECT_NEAR(linear_slope({1, 2, 3, 4}, {3, 5, 7, 9}), 2.0, 1e-12);
  EXPECT_NEAR(linear_slope({0, 1, 2, NAN, 3}, {1, 0, 1, 5, 0}), -0.2, 1e-12);
  EXPECT_NEAR(linear_slope({3, 3, 2.4}, {0, 1, -0.1}), 1.0, 1e-12);
  EXPECT_TRUE(std::isnan(linear_slope({1}, {2})));
  EXPECT_TRUE(std::isnan(linear_slope({2, 2, 2}, {1, 2, 3})));
}

}  // namespace
}  // namespace noisemon::model::diagnosis
