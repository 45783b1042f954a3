// The dash's reference curve against the thesis's eq. 4.1 written out here (ka = 11.885, wb = 2 pi 100 rad/s,
// zeta = 0.35, wn = 2 pi 5000 rad/s: the curve of its Figure 4.2) and the A-weighting of IEC 61672-1:2013 Table 3.
#include "cli/dash_reference.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>

#include "cli/dash_state.hpp"

namespace {

double eq_4_1_gain_db(double f_hz) {
  const double pi = std::numbers::pi;
  const std::complex<double> s(0, 2 * pi * f_hz);
  const double ka = 11.885, wb = 2 * pi * 100, zeta = 0.35, wn = 2 * pi * 5000;
  return 20 * std::log10(std::abs(ka * (s + wb) / (s * s + 2 * zeta * wn * s + wn * wn)));
}

struct Row {
  double nominal_hz, a_db;  // IEC 61672-1:2013 Table 3, A-weighting design goal
};
constexpr Row kTable3[] = {{100, -19.1}, {250, -8.6}, {500, -3.2},  {1000, 0.0},   {2000, 1.2},
                           {3150, 1.2},  {5000, 0.5}, {8000, -1.1}, {12500, -4.3}, {16000, -6.6}};

}  // namespace

TEST(DashReference, IsTheThesisLinearCurveAWeightedPerBand) {
  const nlohmann::json ref = noisemon::cli::linear_reference_json(40000.0);
  ASSERT_EQ(ref["band_hz"].size(), ref["att_db"].size());
  ASSERT_EQ(ref["band_hz"].size(), 31u);  // 20 Hz ... 20 kHz
  EXPECT_EQ(ref["preset"], "linear");
  EXPECT_DOUBLE_EQ(ref["band_hz"].front().get<double>(), 20.0);
  EXPECT_DOUBLE_EQ(ref["band_hz"].back().get<double>(), 20000.0);
  for (const auto& att : ref["att_db"]) EXPECT_TRUE(att.is_number() && std::isfinite(att.get<double>())) << ref.dump();
  for (const Row& row : kTable3) {
    std::size_t b = 0;
    while (b < ref["band_hz"].size() && std::abs(ref["band_hz"][b].get<double>() / row.nominal_hz - 1) > 0.01) ++b;
    ASSERT_LT(b, ref["band_hz"].size()) << row.nominal_hz;
    const double exact_hz = 1000 * std::pow(10.0, std::round(10 * std::log10(row.nominal_hz / 1000)) / 10);
    // Table 3 is rounded to 0.1 dB; the band's mean gain differs from the mid-band one by less than 0.2 dB.
    EXPECT_NEAR(ref["att_db"][b].get<double>(), -eq_4_1_gain_db(exact_hz) - row.a_db, 0.25) << row.nominal_hz << " Hz";
  }
}

TEST(DashReference, TravelsWithEachClientsFirstEventOnly) {
  noisemon::cli::DashState state("", 10, noisemon::cli::linear_reference_json(40000.0));
  noisemon::cycle_report_t r{};
  r.cycle = 1;
  state.on_cycle(r);
  std::uint64_t sent = 0;
  const auto first = nlohmann::json::parse(state.event_json(0, sent));
  ASSERT_TRUE(first.contains("reference"));
  EXPECT_EQ(first["reference"]["att_db"].size(), 31u);
  r.cycle = 2;
  state.on_cycle(r);
  const auto next = nlohmann::json::parse(state.event_json(sent, sent));
  EXPECT_FALSE(next.contains("reference"));
  EXPECT_TRUE(nlohmann::json::parse(state.state_json()).contains("reference"));
}
