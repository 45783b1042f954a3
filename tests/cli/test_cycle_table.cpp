// Cycle tables (crank angle + one pressure column per cycle) -> run directory: the angle mapping written out
// independently from the documented rule (column j is cycle j, [720 j - 360, 720 j + 360) about its own TDC, whole;
// t from a constant speed),
// the pegging row, the bad inputs, and the real Yanmar L100V tables.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "cli/formats/cycle_table.hpp"
#include "tests/support/required.hpp"

using namespace noisemon::drivers;
using namespace noisemon::cli::formats;

namespace {

// A table over [first, first + 720) in `step` steps with `cycles` columns; value(j, a) per cell; the first row
// holds `pegging` in every column when pegging >= 0.
std::string make_table(double first, double step, int cycles, double pegging, double (*value)(int, double)) {
  std::string s;
  const int rows = static_cast<int>(std::lround(720.0 / step));
  char buf[64];
  for (int r = 0; r < rows; ++r) {
    const double a = first + r * step;
    std::snprintf(buf, sizeof buf, "%.6f", a);
    s += buf;
    for (int j = 0; j < cycles; ++j) {
      std::snprintf(buf, sizeof buf, "\t%.6f", r == 0 && pegging >= 0 ? pegging : value(j, a));
      s += buf;
    }
    s += "\t\r\n";  // trailing tab and CRLF, as the Yanmar files have
  }
  return s;
}

double cell(int j, double a) { return 1.0 + j + a / 1000.0; }

std::string table_error(const std::string& text) {
  try {
    parse_cycle_table(text, "t.txt");
  } catch (const formats::RunDirError& e) {
    return e.what();
  }
  return "(no error)";
}

#define EXPECT_HAS(haystack, needle) EXPECT_NE((haystack).find(needle), std::string::npos) << (haystack)

std::string shared_file(const std::string& name) { return noisemon::test::reference_file(name); }

}  // namespace

TEST(CycleTable, EachColumnBecomesOneWholeCycleAboutItsFiringTdc) {
  // -180 .. 539.5 deg in 0.5 deg steps, 3 cycles, a pegging value of 0.97 in the first row; cell(j, a) carries the
  // column's index, so a sample from another column would show.
  const CycleTable t = parse_cycle_table(make_table(-180.0, 0.5, 3, 0.97, cell), "t.txt");
  ASSERT_EQ(t.crank_deg.size(), 1440u);
  ASSERT_EQ(t.cycles_bar.size(), 3u);
  CycleTableOptions o;
  o.speed_rpm = 1200.0;  // 7200 deg/s
  o.condition.name = "synthetic";
  o.condition.load_nm = 5;
  const CycleTableConversion c = cycle_table_to_run(t, o, "t.txt");
  EXPECT_TRUE(c.pegging_row_dropped);
  const formats::RunDir& run = c.run;
  ASSERT_EQ(run.crank_deg.size(), 3u * 1439u);
  EXPECT_EQ(run.condition.speed_rpm, 1200.0);
  EXPECT_EQ(run.condition.load_nm, 5);
  EXPECT_EQ(run.mic_count, 0u);
  // Cycle j is [720 j - 360, 720 j + 360); its first 180 deg are the column's own 360 .. 539.5 (its next intake).
  EXPECT_NEAR(run.crank_deg.front(), -360.0, 1e-9);
  EXPECT_NEAR(run.crank_deg.back(), 720.0 * 2 + 359.5, 1e-9);
  for (std::size_t i = 0; i < run.crank_deg.size(); ++i) {
    const double theta = run.crank_deg[i];
    const int j = static_cast<int>(std::floor((theta + 360.0) / 720.0));
    const double in_cycle = theta - 720.0 * j, table_angle = in_cycle < -180.0 ? in_cycle + 720.0 : in_cycle;
    ASSERT_NEAR(run.pressure_pa[i], cell(j, table_angle) * 1e5, 1e-3) << theta;
    ASSERT_NEAR(run.time_s[i], (theta + 360.0) / 7200.0, 1e-12);
    if (i > 0) {
      ASSERT_GT(theta, run.crank_deg[i - 1]);
    }
  }
  // Cycle by cycle, whole: 1439 samples each, and the only wider step is the dropped pegging row's at -180.
  for (int j = 0; j < 3; ++j) {
    int n = 0;
    for (double theta : run.crank_deg) n += theta >= 720.0 * j - 360.0 && theta < 720.0 * j + 360.0;
    EXPECT_EQ(n, 1439) << j;
  }
  for (std::size_t i = 1; i < run.crank_deg.size(); ++i) {
    const double step = run.crank_deg[i] - run.crank_deg[i - 1];
    const double at = std::remainder(run.crank_deg[i], 720.0);
    ASSERT_NEAR(step, std::abs(at - (-179.5)) < 1e-9 ? 1.0 : 0.5, 1e-9) << run.crank_deg[i];
  }
}

TEST(CycleTable, TableOverZeroTo720WithTdcAt360) {
  const CycleTable t = parse_cycle_table(make_table(0.0, 1.0, 2, -1, cell), "t.txt");
  CycleTableOptions o;
  o.speed_rpm = 600.0;
  o.tdc_deg = 360.0;
  const CycleTableConversion c = cycle_table_to_run(t, o, "t.txt");
  EXPECT_FALSE(c.pegging_row_dropped);                  // the first rows differ between cycles: samples
  EXPECT_NEAR(c.run.crank_deg.front(), -360.0, 1e-12);  // a window centred on TDC needs no rotation
  EXPECT_NEAR(c.run.crank_deg[360], 0.0, 1e-12);        // table 360 deg = firing TDC
  EXPECT_NEAR(c.run.pressure_pa[360], cell(0, 360.0) * 1e5, 1e-3);
  EXPECT_NEAR(c.run.crank_deg.back(), 720.0 + 719.0 - 360.0, 1e-12);
  EXPECT_NEAR(c.run.time_s.back(), (720.0 + 719.0) / 3600.0, 1e-12);
}

TEST(CycleTable, PeggingRowChoice) {
  const CycleTable t = parse_cycle_table(make_table(-180.0, 1.0, 2, 0.9, cell), "t.txt");
  CycleTableOptions o;
  o.speed_rpm = 1000;
  o.pegging = PeggingRow::kNone;
  EXPECT_EQ(cycle_table_to_run(t, o, "t.txt").run.pressure_pa.size(), 2u * 720u);
  o.pegging = PeggingRow::kFirstRow;
  EXPECT_EQ(cycle_table_to_run(t, o, "t.txt").run.pressure_pa.size(), 2u * 719u);
  o.speed_rpm = 0;
  try {
    cycle_table_to_run(t, o, "t.txt");
    ADD_FAILURE() << "no error without a speed";
  } catch (const formats::RunDirError& e) {
    EXPECT_HAS(std::string(e.what()), "t.txt: the engine speed must be given");
  }
}

TEST(CycleTableBadInput, ErrorsNameFileLineColumnAndWhatWasExpected) {
  std::string t = make_table(-180.0, 1.0, 2, -1, cell);
  // Row 5 (line 5) loses a column.
  std::size_t line5 = 0;
  for (int i = 0; i < 4; ++i) line5 = t.find('\n', line5) + 1;
  std::string ragged = t;
  ragged.replace(ragged.find('\t', ragged.find('\t', line5) + 1),
                 ragged.find('\n', line5) - ragged.find('\t', ragged.find('\t', line5) + 1) - 1, "");
  EXPECT_HAS(table_error(ragged), "t.txt: line 5: 2 columns, expected 3 like line 1");
  std::string bad = t;
  bad.replace(bad.find('\t', line5) + 1, 8, "1.5e+x");
  EXPECT_HAS(table_error(bad), "t.txt: line 5: column 2 is \"1.5e+x");
  EXPECT_HAS(table_error(bad), "expected a pressure in bar");
  std::string crank = t;
  crank.replace(line5, crank.find('\t', line5) - line5, "-175.500000");
  EXPECT_HAS(table_error(crank), "t.txt: line 5: crank angle -175.5 after -177, expected a uniform step of");
  std::size_t half = 0;  // the first 360 rows only
  for (int i = 0; i < 360; ++i) half = t.find('\n', half) + 1;
  EXPECT_HAS(table_error(t.substr(0, half)),
             "t.txt: the crank column covers 360 deg (360 rows of 1 deg), expected 720 deg");
  EXPECT_HAS(table_error("angle p1 p2\n1 1 2\nabc 1 2\n"),
             "t.txt: line 3: column 1 (crank angle) is \"abc\", expected a number");
  EXPECT_HAS(table_error("1\n2\n3\n4\n5\n6\n7\n8\n"), "t.txt: line 1: 1 column, expected the crank angle followed by");
}

TEST(CycleTableBadInput, PressureOrCrankBeyondAnyEngineIsRefusedNotOverflowed) {
  // Found by fuzzing: 1e308 bar is a finite double but overflows to inf once converted to Pa (x 1e5); a crank
  // angle of 1e300 would turn the step check into inf - inf. Both are corrupted cells, named as such.
  std::string t = make_table(-180.0, 1.0, 2, -1, cell);
  std::size_t line3 = 0;
  for (int i = 0; i < 2; ++i) line3 = t.find('\n', line3) + 1;
  std::string huge_p = t;
  huge_p.replace(huge_p.find('\t', line3) + 1, 8, "1e308");
  EXPECT_HAS(table_error(huge_p), "t.txt: line 3: column 2 is \"1e308\", expected a pressure in bar");
  std::string huge_crank = t;
  huge_crank.replace(line3, huge_crank.find('\t', line3) - line3, "1e300");
  EXPECT_HAS(table_error(huge_crank), "t.txt: line 3: crank angle 1e+300 deg, expected a crank angle within");
  // A plausible extreme (3000 bar) is still accepted.
  std::string high = t;
  high.replace(high.find('\t', line3) + 1, 8, "3000.000");
  EXPECT_EQ(table_error(high), "(no error)");
}

TEST(CycleTable, HeaderLineAndCommentsAreSkipped) {
  const std::string t = "# exported by a lab script\ncrank p1 p2\n" + make_table(-180.0, 1.0, 2, -1, cell);
  const CycleTable c = parse_cycle_table(t, "t.txt");
  EXPECT_EQ(c.crank_deg.size(), 720u);
  EXPECT_EQ(c.first_data_line, 3u);
}

TEST(CycleTable, SemicolonDecimalCommaCommaSeparatedAndSeveralHeaderLinesGiveTheSameNumbers) {
  // The same two cycles written as an indicating system's exports in other locales and layouts; the values the
  // test wrote (0.5 deg steps, p = 1 + cycle + crank / 1000 bar) must come back in every one.
  const auto expected = [](int c, double crank) { return 1.0 + c + crank / 1000.0; };
  std::string semi = "Kurbelwinkel;Zyklus 1;Zyklus 2\n[deg];[bar];[bar]\n";
  std::string tabs_dc = "crank\tp1\tp2\n", commas = "# CSV\ncrank,p1,p2\n";
  for (int r = 0; r < 1440; ++r) {
    const double crank = -360.0 + 0.5 * r;
    char a[96], b[96];
    std::snprintf(a, sizeof a, "%.1f;%.4f;%.4f\n", crank, expected(0, crank), expected(1, crank));
    std::snprintf(b, sizeof b, "%.1f, %.4f, %.4f\n", crank, expected(0, crank), expected(1, crank));
    std::string de = a;
    for (char& ch : de) ch = ch == '.' ? ',' : ch;  // decimal commas
    semi += de;
    std::string t = de;
    for (char& ch : t) ch = ch == ';' ? '\t' : ch;
    tabs_dc += t;
    commas += b;
  }
  for (const std::string* text : {&semi, &tabs_dc, &commas}) {
    const CycleTable t = parse_cycle_table(*text, "t.csv");
    ASSERT_EQ(t.crank_deg.size(), 1440u);
    ASSERT_EQ(t.cycles_bar.size(), 2u);
    for (std::size_t r = 0; r < 1440; r += 97) {
      EXPECT_DOUBLE_EQ(t.crank_deg[r], -360.0 + 0.5 * static_cast<double>(r));
      for (int c = 0; c < 2; ++c) EXPECT_NEAR(t.cycles_bar[c][r], expected(c, t.crank_deg[r]), 5e-5);
    }
  }
  EXPECT_EQ(parse_cycle_table(semi, "t.csv").first_data_line, 3u);  // two header lines: names and units
}

TEST(CycleTable, RealYanmarTablesParse) {
  for (const char* name : {"yanmar_l100v_fired_18Nm.txt", "yanmar_l100v_motored.txt"}) {
    const std::string path = shared_file(name);
    if (path.empty()) GTEST_SKIP() << "reference data not found under " << NOISEMON_SHARED_DIR;
    const CycleTable t = read_cycle_table(path);
    // The data README: -180 .. 539.8 deg in 0.2 deg steps (3600 rows), 60 cycles, pegging value first.
    ASSERT_EQ(t.crank_deg.size(), 3600u) << name;
    EXPECT_EQ(t.cycles_bar.size(), 60u) << name;
    EXPECT_NEAR(t.crank_deg.front(), -180.0, 1e-9);
    EXPECT_NEAR(t.crank_deg.back(), 539.8, 1e-9);
    CycleTableOptions o;
    o.speed_rpm = 1799.9;
    const CycleTableConversion c = cycle_table_to_run(t, o, path);
    EXPECT_TRUE(c.pegging_row_dropped) << name;
    EXPECT_EQ(c.run.crank_deg.size(), 60u * 3599u);
  }
}
