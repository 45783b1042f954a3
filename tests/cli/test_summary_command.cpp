// `noisemon summary` end to end on the real Yanmar cycles (imported as a raw log, and exported back as a run
// directory): its statistics agree with the ones worked out here from `noisemon replay --csv`, row by row.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/cli/run_command.hpp"
#include "tests/daemon/csv_column.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/required.hpp"
#include "tests/support/unique_temp.hpp"

namespace fs = std::filesystem;

namespace {

using noisemon::test::kNoisemon;
const std::string kTable = std::string(NOISEMON_SHARED_DIR) + "/data/real/yanmar_l100v_fired_18Nm.txt";

using Output = noisemon::test::CommandOutput;

Output run_summary(const std::string& args) { return noisemon::test::run_command(kNoisemon + " " + args); }

std::size_t column_of(const std::string& csv_path, const std::string& name) {
  std::ifstream in(csv_path);
  std::string header;
  std::getline(in, header);
  std::size_t col = 0, at = 0;
  while (true) {
    const std::size_t comma = header.find(',', at);
    if (header.substr(at, comma - at) == name) return col;
    if (comma == std::string::npos) break;
    at = comma + 1;
    ++col;
  }
  ADD_FAILURE() << "no column " << name;
  return 0;
}

std::vector<double> column(const std::string& csv_path, const std::string& name) {
  std::ifstream in(csv_path);
  std::vector<double> v;
  for (const std::string& s : noisemon::test::csv_column(in, column_of(csv_path, name))) v.push_back(std::stod(s));
  return v;
}

}  // namespace

TEST(SummaryCommand, StatisticsOfTheRealCyclesAgreeWithTheReplayCsv) {
  NOISEMON_REQUIRE(fs::exists(kTable), kTable);
  const fs::path dir = noisemon::test::unique_temp("summary_command");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string log = (dir / "fired.lcmlog").string(), csv = (dir / "fired.csv").string();
  ASSERT_EQ(
      run_summary("import --cycles-table " + kTable + " --rpm 1799.9 --load 18 --soi 9.6 --rail 470 -o " + log).status,
      0);
  ASSERT_EQ(run_summary("replay " + log + " --csv " + csv + " --no-progress").status, 0);
  const Output json_out = run_summary("summary " + log + " --json --no-progress");
  ASSERT_EQ(json_out.status, 0) << json_out.text;
  const nlohmann::json all = nlohmann::json::parse(json_out.text);
  ASSERT_TRUE(all.contains("yanmar_l100v_fired_18Nm")) << json_out.text;
  const nlohmann::json& s = all["yanmar_l100v_fired_18Nm"];

  // Worked out from the CSV: valid cycles are those without the settling (1) or gap (2) bits.
  const std::vector<double> flags = column(csv, "flags"), imep = column(csv, "imep_net_bar"),
                            lpa = column(csv, "lpa_predicted_db");
  double n = 0, sum = 0, energy = 0, lo = 1e300, hi = -1e300;
  for (std::size_t i = 0; i < flags.size(); ++i) {
    if (static_cast<int>(flags[i]) & 3) continue;
    ++n;
    sum += imep[i];
    energy += std::pow(10.0, lpa[i] / 10.0);
    lo = std::min(lo, imep[i]);
    hi = std::max(hi, imep[i]);
  }
  EXPECT_EQ(s["cycles"].get<int>(), static_cast<int>(flags.size()));
  EXPECT_EQ(s["valid"].get<int>(), static_cast<int>(n));
  EXPECT_EQ(s["flagged"].get<int>(), static_cast<int>(flags.size() - n));
  EXPECT_NEAR(s["scalars"]["imep_net_bar"]["mean"].get<double>(), sum / n, 1e-3);  // the CSV rounds to 1e-4
  EXPECT_NEAR(s["scalars"]["imep_net_bar"]["min"].get<double>(), lo, 1e-4);
  EXPECT_NEAR(s["scalars"]["imep_net_bar"]["max"].get<double>(), hi, 1e-4);
  EXPECT_NEAR(s["scalars"]["lpa_predicted_db"]["mean"].get<double>(), 10 * std::log10(energy / n), 1e-3);
  EXPECT_TRUE(s["scalars"]["lpa_measured_db"]["mean"].is_null());  // a pressure-only recording measured nothing

  // CSV output: a header and one row per quantity; the same run as a run directory gives the same cycles.
  const Output csv_out = run_summary("summary " + log + " --csv --no-progress");
  ASSERT_EQ(csv_out.status, 0);
  EXPECT_EQ(csv_out.text.rfind("run,quantity,unit,energy_mean,n,mean,std,cov,min,max,lnv\n", 0), 0u) << csv_out.text;
  // The lowest normalised value of net IMEP (lowest over mean), from the replay CSV's column; the TDC the figures used.
  const std::string imep_row = "yanmar_l100v_fired_18Nm,imep_net_bar,bar,0,";
  const std::size_t at = csv_out.text.find(imep_row);
  ASSERT_NE(at, std::string::npos) << csv_out.text;
  const std::string row = csv_out.text.substr(at, csv_out.text.find('\n', at) - at);
  EXPECT_NEAR(std::stod(row.substr(row.rfind(',') + 1)), lo / (sum / n), 1e-4) << row;
  EXPECT_NE(csv_out.text.find("yanmar_l100v_fired_18Nm,tdc_deg,deg,0," + std::to_string(static_cast<int>(n)) + ",0,0,"),
            std::string::npos)
      << csv_out.text;
  EXPECT_NE(csv_out.text.find("yanmar_l100v_fired_18Nm,ca50_deg,deg,0,"), std::string::npos);
  ASSERT_EQ(run_summary("export " + log + " -o " + (dir / "fired_run").string()).status, 0);
  const Output from_dir = run_summary("summary " + (dir / "fired_run").string() + " --json --no-progress");
  ASSERT_EQ(from_dir.status, 0) << from_dir.text;
  const nlohmann::json d = nlohmann::json::parse(from_dir.text);
  ASSERT_EQ(d.size(), 1u);
  // The run directory holds the 40 kHz pressure, not the table's own 0.2 deg samples (export writes no crank-angle
  // stream): its figures come from the resampled pressure, whose peaks the resampler's low-pass rounds off a little.
  EXPECT_NEAR(d.begin().value()["scalars"]["imep_net_bar"]["mean"].get<double>(),
              s["scalars"]["imep_net_bar"]["mean"].get<double>(), 0.02);
  EXPECT_NEAR(d.begin().value()["scalars"]["peak_pressure_bar"]["mean"].get<double>(),
              s["scalars"]["peak_pressure_bar"]["mean"].get<double>(), 0.5);
  // A path that is not there is a clear error.
  const Output missing = run_summary("summary " + (dir / "nothing").string());
  EXPECT_NE(missing.status, 0);
  EXPECT_NE(missing.text.find("nothing"), std::string::npos) << missing.text;
  fs::remove_all(dir);
}

// ISO 3744's K1 from a background run that other code wrote: `noisemon sim --background-run` (the virtual cell with the
// engine off: its floor and the microphones' self-noise). The engine at 3450 rpm is tens of dB above it everywhere
// but in the 20 kHz band, where only the microphones' self-noise is left (outside ISO 3744:2010's 100 Hz ... 10 kHz
// anyway); a run taken as its own background is nowhere 6 dB above it: every band K1 = 1.3 dB, and its sound power an
// upper bound 1.3 dB under the uncorrected one.
TEST(SummaryCommand, BackgroundRunFromTheVirtualCellFlagsOnlyTheBandsItReaches) {
  const fs::path dir = noisemon::test::unique_temp("sim");
  const Output sim =
      run_summary("sim --condition full_mi12 --cycles 30 --background-run --no-progress -o " + dir.string());
  ASSERT_EQ(sim.status, 0) << sim.text;
  const fs::path config = dir / "bg.toml", self = dir / "self.toml";
  std::ofstream(config) << "[sound_power]\nbackground_run = \"" << (dir / "background").string() << "\"\n";
  std::ofstream(self) << "[sound_power]\nbackground_run = \"" << (dir / "full_mi12").string() << "\"\n";
  const Output with =
      run_summary("summary --json --no-progress --config " + config.string() + " " + (dir / "full_mi12").string());
  const Output without = run_summary("summary --json --no-progress " + (dir / "full_mi12").string());
  const Output itself =
      run_summary("summary --json --no-progress --config " + self.string() + " " + (dir / "full_mi12").string());
  ASSERT_EQ(with.status, 0) << with.text;
  ASSERT_EQ(itself.status, 0) << itself.text;
  const auto stats = [](const Output& o) {
    return nlohmann::json::parse(o.text.substr(o.text.find('{'))).begin().value();
  };
  const nlohmann::json s = stats(with), plain = stats(without), own = stats(itself);
  const auto& hz = s["bands"]["hz"];
  const auto& validity = s["bands"]["band_validity"];
  ASSERT_EQ(validity.size(), hz.size());
  for (std::size_t b = 0; b < hz.size(); ++b) {
    const double f = hz[b].get<double>();
    if (f >= 100 && f <= 10000) EXPECT_EQ(validity[b], 0) << f << " Hz: the engine is far above the background here";
    if (f > 10000) EXPECT_EQ(validity[b], 4) << f << " Hz: outside ISO 3744:2010's range";
  }
  EXPECT_NEAR(s["lwa_run_measured_db"].get<double>(), plain["lwa_run_measured_db"].get<double>(), 0.05);
  EXPECT_FALSE(s["lwa_run_upper_bound"].get<bool>());
  for (const auto& v : own["bands"]["band_validity"]) EXPECT_GE(v.get<int>(), 2);
  EXPECT_TRUE(own["lwa_run_upper_bound"].get<bool>());
  EXPECT_NEAR(own["lwa_run_measured_db"].get<double>(), plain["lwa_run_measured_db"].get<double>() - 1.3, 0.1);
}
