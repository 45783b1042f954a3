// Large pressure files: over 1 MiB, plain rows ("a,b,c", no blanks, no '+') are parsed in two halves on two
// threads, the file mapped rather than copied. Whatever that path takes must read to the same numbers as the
// line-by-line reading (which any unusual line falls back to), and every problem must still be reported at its
// line, also when it lies in the second half or exactly where the halves meet. The encoder step (median crank
// step) is taken without sorting every step: it must equal std::nth_element's median.
#include <gtest/gtest.h>
#include <sndfile.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "drivers/formats/run_dir.hpp"
#include "tests/support/unique_temp.hpp"

using namespace noisemon::drivers;
using namespace noisemon::drivers::formats;
namespace fs = std::filesystem;

namespace {

constexpr int kRows = 60000;  // about 2.4 MB: two halves

// Row i of a 0.1 deg encoder at 3000 rpm (18000 deg/s), numbers in their shortest form.
void append_row(std::string& s, int i, const char* sep = ",", const char* eol = "\n") {
  const double crank = -360.0 + 0.1 * i;
  const double fields[3] = {(crank + 360.0) / 18000.0 + 0.02, crank,
                            1.0 + 30.0 * std::exp(-0.001 * (i % 7200 - 3600) * (i % 7200 - 3600) / 36.0)};
  char buf[64];
  for (int f = 0; f < 3; ++f) {
    s.append(buf, std::to_chars(buf, buf + sizeof buf, fields[f]).ptr);
    s += f < 2 ? sep : eol;
  }
}

std::string large_csv(const char* sep = ",", const char* eol = "\n", const char* header_eol = "\n") {
  std::string s = std::string("time_s,crank_deg,pressure") + header_eol;
  for (int i = 0; i < kRows; ++i) append_row(s, i, sep, eol);
  return s;
}

formats::RunDir parse(const std::string& csv) {
  formats::RunDir run;
  formats::parse_pressure_csv(csv, "p.csv", 1e5, run);
  return run;
}

std::string large_csv_error(const std::string& csv) {
  try {
    parse(csv);
  } catch (const RunDirError& e) {
    return e.what();
  }
  return "(no error)";
}

// The line (1-based) that starts at byte `at` of text.
int line_at(const std::string& text, std::size_t at) {
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}
// The byte offset of line `line` (1-based).
std::size_t offset_of_line(const std::string& text, int line) {
  std::size_t pos = 0;
  for (int l = 1; l < line; ++l) pos = text.find('\n', pos) + 1;
  return pos;
}
// Replaces line `line` (without its newline) by `with`.
std::string with_line(std::string text, int line, const std::string& with) {
  const std::size_t from = offset_of_line(text, line);
  return text.replace(from, text.find('\n', from) - from, with);
}
// The first line of the second half: the line after the first newline at or after the middle of the data.
int first_line_of_second_half(const std::string& text) {
  const std::size_t data = text.find('\n') + 1;
  const std::size_t cut = text.find('\n', data + (text.size() - data) / 2);
  return line_at(text, cut + 1);
}

void expect_same_columns(const formats::RunDir& a, const formats::RunDir& b) {
  ASSERT_EQ(a.time_s.size(), b.time_s.size());
  // Bit for bit: memcmp, not ==.
  EXPECT_EQ(std::memcmp(a.time_s.data(), b.time_s.data(), a.time_s.size() * sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(a.crank_deg.data(), b.crank_deg.data(), a.crank_deg.size() * sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(a.pressure_pa.data(), b.pressure_pa.data(), a.pressure_pa.size() * sizeof(double)), 0);
}

#define EXPECT_HAS(haystack, needle) EXPECT_NE((haystack).find(needle), std::string::npos) << (haystack)

}  // namespace

TEST(RunDirLargeCsv, PlainRowsReadAsTheLineByLineReadingReadsThem) {
  const std::string plain = large_csv();
  ASSERT_GT(plain.size(), std::size_t{2} << 20);
  const formats::RunDir fast = parse(plain);
  ASSERT_EQ(fast.time_s.size(), static_cast<std::size_t>(kRows));
  // A blank before the first comma of row 0 is not plain: that file is read line by line from the start.
  std::string spaced = plain;
  spaced.insert(spaced.find(',', offset_of_line(spaced, 2)), " ");
  expect_same_columns(fast, parse(spaced));
  // '+' signs and blanks everywhere: line by line, the same numbers.
  expect_same_columns(fast, parse(large_csv(", +", " \n")));
  // CRLF line ends, a byte-order mark and trailing blank lines are taken by the fast path: the same numbers.
  expect_same_columns(fast, parse(large_csv(",", "\r\n", "\r\n")));
  expect_same_columns(fast, parse("\xEF\xBB\xBF" + plain));
  expect_same_columns(fast, parse(plain + "\n \n\t\r\n"));
  // No newline after the last row.
  expect_same_columns(fast, parse(plain.substr(0, plain.size() - 1)));
  EXPECT_EQ(fast.pressure_pa[3600], (1.0 + 30.0) * 1e5);
}

TEST(RunDirLargeCsv, ReadingTheMappedFileGivesTheSameNumbers) {
  const fs::path d = fs::path(noisemon::test::unique_temp_dir()) / "large_run";
  fs::remove_all(d);
  fs::create_directories(d);
  std::ofstream(d / "run.json")
      << R"({"condition": {"name": "large", "speed_rpm": 3000, "load_nm": 0, "soi_deg_btdc": 12,
    "rail_pressure_bar": null, "motored": false}, "pressure": {"file": "pressure.csv", "units": "bar"}})";
  const std::string plain = large_csv();
  std::ofstream(d / "pressure.csv", std::ios::binary) << plain;
  const formats::RunDir run = formats::read_run_dir(d);
  expect_same_columns(parse(plain), run);
  EXPECT_EQ(run.mic_count, 0u);
}

TEST(RunDirLargeCsv, ProblemsInTheSecondHalfNameTheirLine) {
  const std::string plain = large_csv();
  const int second = first_line_of_second_half(plain);
  ASSERT_GT(second, kRows / 3);
  const int late = kRows - 10;
  EXPECT_HAS(large_csv_error(with_line(plain, late, "0.5,abc,1")),
             "p.csv: line " + std::to_string(late) + ": field crank_deg is \"abc\", expected a finite number");
  EXPECT_HAS(large_csv_error(with_line(plain, late, "0.5,1")),
             "p.csv: line " + std::to_string(late) + ": 2 field(s), expected 3");
  EXPECT_HAS(large_csv_error(with_line(plain, late, "")),
             "p.csv: line " + std::to_string(late) + ": empty line inside the data");
  EXPECT_HAS(large_csv_error(with_line(plain, late, "1,2,3\r\r")),
             "p.csv: line " + std::to_string(late) + ": field pressure is \"3\r\"");
  // Where the halves meet: the second half's first row repeats the first half's last time (written with leading
  // zeros to its length, so that the halves still meet there).
  const std::size_t last = offset_of_line(plain, second - 1), first = offset_of_line(plain, second);
  std::string last_time = plain.substr(last, plain.find(',', last) - last);
  std::string first_time = plain.substr(first, plain.find(',', first) - first);
  std::string repeated = plain;
  if (last_time.size() <= first_time.size())
    repeated.replace(first, first_time.size(), std::string(first_time.size() - last_time.size(), '0') + last_time);
  else
    repeated.replace(last, last_time.size(), std::string(last_time.size() - first_time.size(), '0') + first_time);
  ASSERT_EQ(repeated.size(), plain.size());
  ASSERT_EQ(first_line_of_second_half(repeated), second);
  EXPECT_HAS(large_csv_error(repeated), "p.csv: line " + std::to_string(second) + ": time_s");
  EXPECT_HAS(large_csv_error(repeated), "does not increase");
  // The first problem in the file is the one named, though the second half's thread meets its own first.
  EXPECT_HAS(large_csv_error(with_line(with_line(plain, late, "x,1,1"), 100, "y,1,1")),
             "p.csv: line 100: field time_s is \"y\"");
}

TEST(RunDirLargeCsv, ABlankLineInTheFirstHalfWithRowsAfterItIsAnError) {
  const std::string plain = large_csv();
  EXPECT_HAS(large_csv_error(with_line(plain, 200, " \t")), "p.csv: line 200: empty line inside the data");
  // Blank from just before the second half to the end of the file: fine, the rows before it are read.
  const int second = first_line_of_second_half(plain);
  std::string cut = plain.substr(0, offset_of_line(plain, second - 1));
  const formats::RunDir run = parse(cut + std::string(plain.size() - cut.size(), '\n'));
  EXPECT_EQ(run.time_s.size(), static_cast<std::size_t>(second - 3));
}

TEST(RunDirLargeCsv, CrankGapsAndSpeedJumpsLateInTheFileNameTheirLine) {
  std::string s = "time_s,crank_deg,pressure\n";
  for (int i = 0; i < kRows; ++i)
    if (i < kRows - 100 || i >= kRows - 90) append_row(s, i);  // 10 encoder samples missing: line kRows - 99
  EXPECT_HAS(large_csv_error(s), "p.csv: line " + std::to_string(kRows - 98) + ": crank_deg jumps by 1.1 deg");
}

TEST(RunDirLargeCsv, ACsvProblemIsReportedBeforeAWavProblem) {
  const fs::path d = fs::path(noisemon::test::unique_temp_dir()) / "both_bad";
  fs::remove_all(d);
  fs::create_directories(d);
  std::ofstream(d / "run.json") << R"({"condition": {"name": "x", "speed_rpm": 3000, "load_nm": 0, "soi_deg_btdc": 12,
    "rail_pressure_bar": null, "motored": false}, "pressure": {"file": "pressure.csv", "units": "bar"},
    "mics": {"file": "mics.wav", "units": "Pa", "positions_m": [[0, 0, 1.75]]}})";
  std::ofstream(d / "mics.wav") << "not a wav";
  std::ofstream(d / "pressure.csv", std::ios::binary) << with_line(large_csv(), kRows - 5, "1,2");
  try {
    formats::read_run_dir(d);
    FAIL() << "no error";
  } catch (const RunDirError& e) {
    EXPECT_HAS(std::string(e.what()), "pressure.csv: line " + std::to_string(kRows - 5) + ": 2 field(s)");
  }
  std::ofstream(d / "pressure.csv", std::ios::binary) << large_csv();  // now only the WAV is wrong
  try {
    formats::read_run_dir(d);
    FAIL() << "no error";
  } catch (const RunDirError& e) {
    EXPECT_HAS(std::string(e.what()), "mics.wav: cannot read as a sound file");
  }
}

TEST(RunDirLargeCsv, EncoderStepIsTheMedianStep) {
  std::mt19937_64 rng(7);
  const auto nth_median = [](const std::vector<double>& crank) {
    std::vector<double> steps(crank.size() - 1);
    for (std::size_t i = 0; i + 1 < crank.size(); ++i) steps[i] = crank[i + 1] - crank[i];
    std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
    return steps[steps.size() / 2];
  };
  for (const std::size_t n : {2, 3, 4, 10, 1000, 70000, 200001}) {
    for (int kind = 0; kind < 4; ++kind) {
      std::vector<double> crank(n);
      double th = -360;
      std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
      for (std::size_t i = 0; i < n; ++i) {
        crank[i] = th;
        if (kind == 0)
          th += 0.1 + jitter(rng);  // noisy steps
        else if (kind == 1)
          th += 0.1;  // rounding: a few distinct steps
        else if (kind == 2)
          th += (i % 3 == 0) ? 0.2 : 0.05;  // two steps, ties on both sides
        else
          th += (i < n / 2 + 5) ? 0.1 : 0.1 + 1e-9 * static_cast<double>(i);  // sample and median far apart
      }
      EXPECT_EQ(formats::crank_step_deg(crank), nth_median(crank)) << "n " << n << " kind " << kind;
    }
  }
  EXPECT_TRUE(std::isnan(formats::crank_step_deg({1.0})));
}
