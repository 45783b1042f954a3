// `noisemon tdc`: thermodynamic TDC on the real Yanmar motored record two ways — from the cycle table (its own scale)
// and from a run directory made of it by `import` and `export` (40 kHz frames with the crank angle of each, as a
// recorder writes them), and from the raw log: all must put TDC at the same angle. And --write-config sets [combustion]
// tdc_deg, which the daemon's configuration reader then reads, the rest of the file kept.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "cli/tdc_command.hpp"
#include "daemon/config.hpp"
#include "tests/cli/run_command.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/required.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace fs = std::filesystem;

namespace {

using noisemon::test::kNoisemon;
const std::string kMotored = std::string(NOISEMON_SHARED_DIR) + "/data/real/yanmar_l100v_motored.txt";

noisemon::test::CommandOutput run_tdc(const std::string& args) {
  return noisemon::test::run_command(kNoisemon + " " + args);
}

// The "firing TDC by the loss angle" figure a `tdc` run printed.
double tdc_printed(const std::string& text) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(R"(by the loss angle \([0-9.]+ deg\): ([-+][0-9.]+) deg)"))) return NAN;
  return std::stod(m[1]);
}

using noisemon::test::slurp;

}  // namespace

TEST(TdcCommand, TheTableAndARunDirectoryOfItAgree) {
  NOISEMON_REQUIRE(fs::exists(kMotored), kMotored);
  const fs::path dir = noisemon::test::unique_temp("tdc");
  fs::create_directories(dir);
  const auto table = run_tdc("tdc --cycles-table " + kMotored);  // a table's TDC needs no speed
  ASSERT_EQ(table.status, 0) << table.text;
  ASSERT_EQ(run_tdc("import --cycles-table " + kMotored + " --rpm 1799.9 --motored --load 0 --no-progress -o " +
                    (dir / "m.lcmlog").string())
                .status,
            0);
  ASSERT_EQ(run_tdc("export " + (dir / "m.lcmlog").string() + " --no-progress -o " + (dir / "run").string()).status, 0);
  const auto from_run = run_tdc("tdc " + (dir / "run").string());
  ASSERT_EQ(from_run.status, 0) << from_run.text;
  const double a = tdc_printed(table.text), b = tdc_printed(from_run.text);
  std::printf("TDC from the table %+.2f deg, from its run directory %+.2f deg\n", a, b);
  EXPECT_NEAR(a, -1.84, 0.05);  // docs/sources-and-formats.md: the peak at -2.54 plus 0.7
  EXPECT_NEAR(b, a, 0.1);
  // The raw log itself (what the daemon records while motoring) gives the same.
  const auto from_log = run_tdc("tdc " + (dir / "m.lcmlog").string());
  ASSERT_EQ(from_log.status, 0) << from_log.text;
  EXPECT_NEAR(tdc_printed(from_log.text), b, 1e-6);
  // A fired run is refused, naming it.
  const auto fired =
      run_tdc("tdc --cycles-table " + std::string(NOISEMON_SHARED_DIR) + "/data/real/yanmar_l100v_fired_18Nm.txt");
  EXPECT_NE(fired.status, 0);
  EXPECT_NE(fired.text.find("not a motored cycle"), std::string::npos) << fired.text;
  fs::remove_all(dir);
}

TEST(TdcCommand, WriteConfigSetsTdcDegAndKeepsTheRest) {
  const fs::path dir = noisemon::test::unique_temp("tdc_config");
  fs::create_directories(dir);
  const fs::path with_key = dir / "a.toml", with_table = dir / "b.toml", without = dir / "c.toml";
  std::ofstream(with_key)
      << "# cell 3\n[combustion]\npegging = \"intake\"\ntdc_deg = 0.0  # old\n[engine]\nbore_mm = 86.0\n";
  std::ofstream(with_table) << "[combustion]\npegging = \"intake\"\n\n[engine]\nbore_mm = 86.0\n";
  std::ofstream(without) << "[engine]\nbore_mm = 86.0\n";
  for (const fs::path& p : {with_key, with_table, without}) {
    noisemon::cli::write_tdc_deg(p.string(), -1.84);
    const noisemon::daemon::Config c = noisemon::daemon::load_config(p.string());
    EXPECT_NEAR(c.combustion.tdc_deg, -1.84, 1e-9) << p;
    EXPECT_NEAR(c.engine.bore_m, 0.086, 1e-12) << p;
  }
  EXPECT_NE(slurp(with_key).find("# cell 3\n"), std::string::npos);
  EXPECT_EQ(slurp(with_key).find("old"), std::string::npos);  // the line replaced
  EXPECT_EQ(noisemon::daemon::load_config(with_key.string()).combustion.pegging, noisemon::model::Pegging::kIntake);
  fs::remove_all(dir);
}

// `import RUN_DIR... --motored-run DIR`: the run directories of the Yanmar records (made by import and export, so on
// the record's own scale, TDC 1.84 deg after its zero) come in on the piston's angles: net IMEP above the recorded
// 18 N m's BMEP (5.19 bar) and as the cycle-table import with --motored-table gives it; without the motored run, the
// record's scale puts it below the BMEP. --loss-angle-deg alone is refused.
TEST(TdcCommand, ImportWithAMotoredRunPutsTheRunsOnThePistonsAngles) {
  const std::string fired_table = std::string(NOISEMON_SHARED_DIR) + "/data/real/yanmar_l100v_fired_18Nm.txt";
  NOISEMON_REQUIRE(fs::exists(kMotored) && fs::exists(fired_table), "the Yanmar records");
  const fs::path dir = noisemon::test::unique_temp("motored_run");
  fs::create_directories(dir);
  const auto as_run = [&](const std::string& table, const std::string& name, const std::string& extra) {
    const std::string log = (dir / (name + ".lcmlog")).string();
    ASSERT_EQ(run_tdc("import --cycles-table " + table + " --rpm 1799.9 " + extra + " --no-progress -o " + log).status,
              0);
    ASSERT_EQ(run_tdc("export " + log + " --no-progress -o " + (dir / name).string()).status, 0);
  };
  as_run(kMotored, "motored", "--motored --load 0");
  as_run(fired_table, "fired", "--load 18 --soi 9.6");
  const auto net_imep = [&](const std::string& log) -> double {
    const auto s = run_tdc("summary " + log + " --csv --no-progress");
    const std::size_t at = s.text.find(",imep_net_bar,bar,0,");
    if (at == std::string::npos) return NAN;
    std::stringstream row(s.text.substr(at + 20));
    std::string n, mean;
    std::getline(row, n, ',');
    std::getline(row, mean, ',');
    return std::stod(mean);
  };
  const std::string with = (dir / "with.lcmlog").string(), without = (dir / "without.lcmlog").string(),
                    table = (dir / "table.lcmlog").string();
  const auto imported = run_tdc("import " + (dir / "fired").string() + " --motored-run " + (dir / "motored").string() +
                                " --no-progress -o " + with);
  ASSERT_EQ(imported.status, 0) << imported.text;
  EXPECT_NE(imported.text.find("thermodynamic TDC from"), std::string::npos) << imported.text;
  ASSERT_EQ(run_tdc("import " + (dir / "fired").string() + " --no-progress -o " + without).status, 0);
  ASSERT_EQ(run_tdc("import --cycles-table " + fired_table + " --motored-table " + kMotored +
                    " --rpm 1799.9 --load 18 --soi 9.6 --no-progress -o " + table)
                .status,
            0);
  const double a = net_imep(with), b = net_imep(without), c = net_imep(table);
  std::printf("net IMEP: run directories with the motored run %.3f bar, without %.3f bar; the tables %.3f bar\n", a, b,
              c);
  EXPECT_GT(a, 5.19);
  EXPECT_LT(b, 5.19);
  EXPECT_NEAR(a, c, 0.03);
  const auto refused =
      run_tdc("import " + (dir / "fired").string() + " --loss-angle-deg 1 --no-progress -o " + without);
  EXPECT_EQ(refused.status, 2);
  EXPECT_NE(refused.text.find("--loss-angle-deg needs"), std::string::npos) << refused.text;
  fs::remove_all(dir);
}
