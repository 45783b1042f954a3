// Run-directory reader and writer (the interchange format of docs/sources-and-formats.md): every bad input names the
// file, the position and what was expected; what is written reads back to the same numbers.
#include <gtest/gtest.h>
#include <sndfile.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>

#include "drivers/formats/run_dir.hpp"
#include "tests/support/unique_temp.hpp"

using namespace noisemon::drivers;
using namespace noisemon::drivers::formats;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::path(noisemon::test::unique_temp_dir()) / ("run_dir_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void write_text(const fs::path& p, const std::string& text) { std::ofstream(p, std::ios::binary) << text; }

const char* kJson = R"({
  "condition": {"name": "idle_mi12", "speed_rpm": 3050, "load_nm": 0, "soi_deg_btdc": 12,
                "rail_pressure_bar": null, "motored": false, "operator": "ignored"},
  "pressure": {"file": "pressure.csv", "units": "bar"},
  "mics": {"file": "mics.wav", "units": "Pa", "positions_m": [[-1.35, 0.78, 0.79], [0.0, 0.0, 1.75]], "radius_m": 1.75},
  "notes": "unknown keys are ignored"
})";

// A valid pressure.csv: 0.5 deg encoder at 3000 rpm (18 kHz edges), crank from -360.
std::string valid_csv(int rows = 200) {
  std::string s = "time_s,crank_deg,pressure\n";
  for (int i = 0; i < rows; ++i) {
    const double crank = -360.0 + 0.5 * i;
    char line[128];
    std::snprintf(line, sizeof line, "%.9f,%.3f,%.6f\n", crank / 18000.0 + 0.02, crank, 1.0 + 0.001 * i);
    s += line;
  }
  return s;
}

void write_wav(const fs::path& p, int channels, int rate, int format, sf_count_t frames = 1000,
               double amplitude = 0.25) {
  SF_INFO info{};
  info.channels = channels;
  info.samplerate = rate;
  info.format = format;
  SNDFILE* f = sf_open(p.c_str(), SFM_WRITE, &info);
  ASSERT_NE(f, nullptr) << sf_strerror(nullptr);
  std::vector<double> d(static_cast<std::size_t>(frames * channels));
  for (sf_count_t i = 0; i < frames; ++i)
    for (int c = 0; c < channels; ++c)
      d[static_cast<std::size_t>(i * channels + c)] =
          amplitude * std::sin(2 * std::numbers::pi * 1000.0 * static_cast<double>(i) / rate);
  sf_writef_double(f, d.data(), frames);
  sf_close(f);
}

// A complete valid run directory; tests then break one thing.
fs::path valid_run(const std::string& name) {
  const fs::path d = fresh_dir(name);
  write_text(d / "run.json", kJson);
  write_text(d / "pressure.csv", valid_csv());
  write_wav(d / "mics.wav", 2, 51200, SF_FORMAT_WAV | SF_FORMAT_FLOAT);
  return d;
}

std::string error_of(const fs::path& dir) {
  try {
    formats::read_run_dir(dir);
  } catch (const RunDirError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string csv_error(const std::string& csv) {
  formats::RunDir run;
  try {
    formats::parse_pressure_csv(csv, "p.csv", 1e5, run);
  } catch (const RunDirError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string json_error(const std::string& json) {
  try {
    formats::parse_run_json(json, "r.json");
  } catch (const RunDirError& e) {
    return e.what();
  }
  return "(no error)";
}

#define EXPECT_HAS(haystack, needle) EXPECT_NE((haystack).find(needle), std::string::npos) << (haystack)

}  // namespace

TEST(RunDir, ReadsAValidRunAndIgnoresUnknownKeys) {
  const fs::path d = valid_run("valid");
  const formats::RunDir run = formats::read_run_dir(d);
  EXPECT_EQ(run.condition.name, "idle_mi12");
  EXPECT_EQ(run.condition.speed_rpm, 3050);
  EXPECT_EQ(run.condition.soi_deg_btdc, 12);
  EXPECT_FALSE(run.condition.rail_pressure_bar.has_value());
  EXPECT_FALSE(run.condition.motored);
  ASSERT_EQ(run.time_s.size(), 200u);
  EXPECT_DOUBLE_EQ(run.crank_deg[0], -360.0);
  EXPECT_NEAR(run.pressure_pa[10], 1.01e5, 1e-6);  // bar -> Pa
  EXPECT_EQ(run.mic_count, 2u);
  EXPECT_EQ(run.mic_rate_hz, 51200);
  ASSERT_EQ(run.mic_pa.size(), 2000u);
  EXPECT_NEAR(run.mic_pa[2 * 10], 0.25 * std::sin(2 * std::numbers::pi * 1000.0 * 10 / 51200), 1e-7);
  ASSERT_EQ(run.mic_positions_m.size(), 2u);
  EXPECT_EQ(run.mic_positions_m[0][0], -1.35);
  EXPECT_EQ(run.radius_m, 1.75);
}

TEST(RunDir, PressureOnlyRunHasNoMics) {
  const fs::path d = fresh_dir("pressure_only");
  write_text(d / "run.json", R"({"condition": {"name": "m", "speed_rpm": 3000, "load_nm": 0, "soi_deg_btdc": 0,
    "motored": true}, "pressure": {"file": "p.csv", "units": "Pa"}})");
  write_text(d / "p.csv", valid_csv());
  const formats::RunDir run = formats::read_run_dir(d);
  EXPECT_EQ(run.mic_count, 0u);
  EXPECT_TRUE(run.condition.motored);
  EXPECT_NEAR(run.pressure_pa[0], 1.0, 1e-12);  // units Pa: no scaling
}

TEST(RunDir, WriteThenReadGivesTheSameNumbers) {
  formats::RunDir run;
  run.condition = {"full_mi18", 3450, 20, 18, 550.0, false};
  for (int i = 0; i < 5000; ++i) {
    run.time_s.push_back(i / 40000.0 + 1.0 / 3.0);
    run.crank_deg.push_back(-200.0 + i * 0.517 + 1e-9 * i * i);
    run.pressure_pa.push_back(1e5 + 6e6 * std::exp(-std::pow((i - 2500) / 300.0, 2)) + std::numbers::pi);
  }
  run.mic_count = 3;
  run.mic_rate_hz = 48000;
  run.mic_positions_m = {{1, 2, 3}, {-1.35, 0.78, 0.79}, {0.1, 0.2, 1.7}};
  run.radius_m = 1.5;
  run.acoustic_delay_s = 0.004;
  for (int i = 0; i < 3 * 4000; ++i) run.mic_pa.push_back(static_cast<float>(0.01 * std::sin(0.001 * i * i)));
  for (const char* units : {"bar", "Pa"}) {
    const fs::path d = fresh_dir(std::string("roundtrip_") + units);
    formats::write_run_dir(d, run, units);
    const formats::RunDir back = formats::read_run_dir(d);
    EXPECT_EQ(back.condition.name, run.condition.name);
    EXPECT_EQ(back.condition.speed_rpm, 3450);
    EXPECT_EQ(back.condition.load_nm, 20);
    EXPECT_EQ(back.condition.rail_pressure_bar.value_or(-1), 550.0);
    ASSERT_EQ(back.time_s.size(), run.time_s.size());
    for (std::size_t i = 0; i < run.time_s.size(); ++i) {
      ASSERT_EQ(back.time_s[i], run.time_s[i]);  // shortest round-trip text: exact
      ASSERT_EQ(back.crank_deg[i], run.crank_deg[i]);
      ASSERT_NEAR(back.pressure_pa[i], run.pressure_pa[i],
                  1e-15 * run.pressure_pa[i] * 4);  // bar scaling: an ulp or two
    }
    EXPECT_EQ(back.mic_pa, run.mic_pa);  // 32-bit float WAV: exact
    EXPECT_EQ(back.mic_rate_hz, 48000);
    EXPECT_EQ(back.mic_positions_m, run.mic_positions_m);
    EXPECT_EQ(back.radius_m, 1.5);
    EXPECT_EQ(back.acoustic_delay_s, 0.004);
  }
}

namespace {

// run.json for the valid pressure.csv with the given condition (its other keys as kJson's) and pressure entry.
std::string run_json_with(const std::string& condition, const std::string& pressure_extra = "") {
  return R"({"condition": {"name": "other_program", )" + condition + R"(},
             "pressure": {"file": "pressure.csv", "units": "bar")" +
         pressure_extra + "}}";
}

}  // namespace

TEST(RunDirNulls, NullIsAcceptedForEveryConditionValueAndReadsAsUnknown) {
  const fs::path d = valid_run("nulls");
  write_text(d / "run.json", run_json_with(R"("speed_rpm": null, "load_nm": null, "soi_deg_btdc": null,
                                              "rail_pressure_bar": null, "motored": null)"));
  const formats::RunDir run = formats::read_run_dir(d);
  EXPECT_TRUE(std::isnan(run.condition.speed_rpm));
  EXPECT_TRUE(std::isnan(run.condition.load_nm));
  EXPECT_TRUE(std::isnan(run.condition.soi_deg_btdc));
  EXPECT_FALSE(run.condition.rail_pressure_bar.has_value());
  EXPECT_FALSE(run.condition.motored_known);
  EXPECT_FALSE(run.condition.motored);  // what a boolean message publishes
  EXPECT_EQ(run.time_s.size(), 200u);   // the rows are read as always
  // The speed, unknown, is the encoder's: 0.5 deg per 1/36000 s = 3000 rpm.
  EXPECT_NEAR(formats::encoder_speed_rpm(run), 3000.0, 0.01);
}

TEST(RunDirNulls, AMotoredRunWithoutSoiKeepsEverythingElse) {
  const fs::path d = valid_run("motored_soi_null");
  write_text(d / "run.json",
             run_json_with(R"("speed_rpm": 3050, "load_nm": 0, "soi_deg_btdc": null, "motored": true)"));
  const formats::RunDir run = formats::read_run_dir(d);
  EXPECT_EQ(run.condition.speed_rpm, 3050);
  EXPECT_EQ(run.condition.load_nm, 0);
  EXPECT_TRUE(std::isnan(run.condition.soi_deg_btdc));
  EXPECT_TRUE(run.condition.motored_known);
  EXPECT_TRUE(run.condition.motored);
}

TEST(RunDirNulls, ANullSpeedIsNotCheckedAgainstTheRowsButAKnownOneStillIs) {
  // time_s in ms: 3 rpm. Declared 3050 rpm: refused (the units are wrong); declared null: the rows' speed is
  // the run's, whatever it is (nothing to compare with).
  const fs::path d = valid_run("speed_null");
  std::string ms = "time_s,crank_deg,pressure\n";
  for (int i = 0; i < 200; ++i)
    ms += std::to_string(1000.0 * (0.5 * i / 18000.0)) + "," + std::to_string(-360.0 + 0.5 * i) + ",1\n";
  write_text(d / "pressure.csv", ms);
  write_text(d / "run.json", run_json_with(R"("speed_rpm": 3050, "load_nm": 0, "soi_deg_btdc": 12, "motored": false)"));
  EXPECT_HAS(error_of(d), "condition.speed_rpm is 3050");
  write_text(d / "run.json", run_json_with(R"("speed_rpm": null, "load_nm": 0, "soi_deg_btdc": 12, "motored": false)"));
  EXPECT_EQ(error_of(d), "(no error)");
  EXPECT_NEAR(formats::encoder_speed_rpm(formats::read_run_dir(d)), 3.0, 0.01);
}

TEST(RunDirNulls, AMissingKeyIsStillAnErrorNamingTheKeyAndTheFile) {
  const fs::path d = valid_run("nulls_missing");
  for (const char* key : {"speed_rpm", "load_nm", "soi_deg_btdc", "motored"}) {
    std::string condition;
    for (const char* k : {"speed_rpm", "load_nm", "soi_deg_btdc", "motored"})
      if (std::string(k) != key) condition += std::string(condition.empty() ? "" : ", ") + "\"" + k + "\": null";
    write_text(d / "run.json", run_json_with(condition));
    EXPECT_HAS(error_of(d), (d / "run.json").string() + ": missing key \"condition." + key + "\"");
  }
}

TEST(RunDirNulls, UnknownValuesAreWrittenAsNullAndReadBackUnknown) {
  const fs::path src = valid_run("nulls_write_src");
  formats::RunDir run = formats::read_run_dir(src);
  run.condition = {"written", std::nan(""), std::nan(""), std::nan(""), std::nullopt, false, false};
  const fs::path d = fresh_dir("nulls_write");
  formats::write_run_dir(d, run);
  std::ifstream in(d / "run.json");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  for (const char* key : {"speed_rpm", "load_nm", "soi_deg_btdc", "rail_pressure_bar", "motored"})
    EXPECT_HAS(text, "\"" + std::string(key) + "\": null");
  const formats::RunDir back = read_run_dir(d);
  EXPECT_TRUE(std::isnan(back.condition.speed_rpm));
  EXPECT_TRUE(std::isnan(back.condition.load_nm));
  EXPECT_TRUE(std::isnan(back.condition.soi_deg_btdc));
  EXPECT_FALSE(back.condition.motored_known);
}

TEST(RunDirNoiseFloor, RoundTripsThroughWriteAndRead) {
  const fs::path src = valid_run("floor_src");
  formats::RunDir run = formats::read_run_dir(src);
  EXPECT_FALSE(run.pressure_noise_floor_bar.has_value());  // kJson has none
  run.pressure_noise_floor_bar = 0.0123456789;
  const fs::path d = fresh_dir("floor");
  formats::write_run_dir(d, run);
  EXPECT_EQ(formats::read_run_dir(d).pressure_noise_floor_bar.value_or(-1), 0.0123456789);
  run.pressure_noise_floor_bar = 0.0;  // a perfect chain is a known floor, not an unknown one
  write_run_dir(d, run);
  EXPECT_EQ(formats::read_run_dir(d).pressure_noise_floor_bar.value_or(-1), 0.0);
  run.pressure_noise_floor_bar.reset();  // unknown: not written at all
  write_run_dir(d, run);
  std::ifstream in(d / "run.json");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  EXPECT_EQ(text.find("noise_floor_bar"), std::string::npos) << text;
  EXPECT_FALSE(formats::read_run_dir(d).pressure_noise_floor_bar.has_value());
  run.pressure_noise_floor_bar = -1e-3;
  try {
    write_run_dir(fresh_dir("floor_negative"), run);
    ADD_FAILURE() << "a negative floor was written";
  } catch (const RunDirError& e) {
    EXPECT_HAS(std::string(e.what()), "noise floor");
  }
}

TEST(RunDirNoiseFloor, NullAndAbsentAreUnknownBadValuesNameTheKey) {
  const std::string condition = R"("speed_rpm": 3000, "load_nm": 0, "soi_deg_btdc": 12, "motored": false)";
  EXPECT_FALSE(formats::parse_run_json(run_json_with(condition), "r.json").pressure_noise_floor_bar.has_value());
  EXPECT_FALSE(formats::parse_run_json(run_json_with(condition, R"(, "noise_floor_bar": null)"), "r.json")
                   .pressure_noise_floor_bar.has_value());
  EXPECT_EQ(formats::parse_run_json(run_json_with(condition, R"(, "noise_floor_bar": 0.002)"), "r.json")
                .pressure_noise_floor_bar.value_or(-1),
            0.002);
  EXPECT_HAS(
      json_error(run_json_with(condition, R"(, "noise_floor_bar": -0.002)")),
      "r.json: key \"pressure.noise_floor_bar\": expected a noise floor >= 0 bar rms per encoder sample, or null");
  EXPECT_HAS(json_error(run_json_with(condition, R"(, "noise_floor_bar": "2 mbar")")),
             "r.json: key \"pressure.noise_floor_bar\": expected a number");
  // Through read_run_dir: the run directory's file is named.
  const fs::path d = valid_run("floor_bad");
  write_text(d / "run.json", run_json_with(condition, R"(, "noise_floor_bar": -1)"));
  EXPECT_HAS(error_of(d), (d / "run.json").string() + ": key \"pressure.noise_floor_bar\"");
}

// ---------------------------------------------------------------------------------------------- pressure.csv

TEST(RunDirBadInput, CsvWithoutHeaderNamesFileLineAndTheExpectedHeader) {
  const std::string e = csv_error("0.0,-360,1.0\n0.1,-359.5,1.0\n");
  EXPECT_HAS(e, "p.csv: line 1: header \"0.0,-360,1.0\"");
  EXPECT_HAS(e, "expected \"time_s,crank_deg,pressure\"");
  EXPECT_HAS(csv_error(""), "p.csv: empty file");
  EXPECT_HAS(csv_error("time,crank,p\n"), "line 1: header");
}

TEST(RunDirBadInput, CsvNonNumericFieldNamesLineAndField) {
  std::string csv = valid_csv(10);
  csv += "0.5,abc,1.0\n";
  const std::string e = csv_error(csv);
  EXPECT_HAS(e, "p.csv: line 12: field crank_deg is \"abc\", expected a finite number");
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\n0,-360,\n"), "line 2: field pressure is \"\"");
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\n0,-360,1e5x\n"), "line 2: field pressure is \"1e5x\"");
}

TEST(RunDirBadInput, CsvNaNAndInfinityAreRejected) {
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\n0,-360,nan\n"),
             "line 2: field pressure is \"nan\", expected a finite number");
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\ninf,-360,1\n"), "line 2: field time_s is \"inf\"");
}

TEST(RunDirBadInput, CsvWrongFieldCount) {
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\n0,-360\n"), "line 2: 2 field(s), expected 3");
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\n0,-360,1,4\n"), "line 2: more than 3 fields");
}

TEST(RunDirBadInput, CsvRowsOutOfOrderNameTheLine) {
  std::string csv = "time_s,crank_deg,pressure\n";
  csv += "0.000,-360.0,1\n0.001,-359.5,1\n0.0005,-359.0,1\n";  // time goes back
  const std::string e = csv_error(csv);
  EXPECT_HAS(e, "p.csv: line 4: time_s");
  EXPECT_HAS(e, "does not increase");
  EXPECT_HAS(e, "out of order");
}

TEST(RunDirBadInput, CsvCrankNotIncreasingNamesTheLine) {
  const std::string e = csv_error("time_s,crank_deg,pressure\n0.000,10,1\n0.001,10.5,1\n0.002,-349.0,1\n");
  EXPECT_HAS(e, "p.csv: line 4: crank_deg");
  EXPECT_HAS(e, "unwrapped and increasing");
}

TEST(RunDirBadInput, CsvCrankGapOfManyEncoderStepsNamesLineAndSize) {
  std::string csv = "time_s,crank_deg,pressure\n";
  char line[64];
  for (int i = 0; i < 100; ++i) {
    const int step = i < 50 ? i : i + 9;  // 9 encoder steps of 0.5 deg missing before row 50
    std::snprintf(line, sizeof line, "%.6f,%.1f,1\n", step * 0.5 / 18000.0, step * 0.5);
    csv += line;
  }
  const std::string e = csv_error(csv);
  EXPECT_HAS(e, "p.csv: line 52: crank_deg jumps by 5 deg from 24.5 to 29.5 (10.0 encoder steps of 0.5 deg)");
  EXPECT_HAS(e, "at most 4 steps expected");
  // Two missing steps are within what resampling fills in.
  std::string ok = "time_s,crank_deg,pressure\n";
  for (int i = 0; i < 100; ++i) {
    const int step = i < 50 ? i : i + 2;
    std::snprintf(line, sizeof line, "%.6f,%.1f,1\n", step * 0.5 / 18000.0, step * 0.5);
    ok += line;
  }
  EXPECT_EQ(csv_error(ok), "(no error)");
}

TEST(RunDirBadInput, CsvTimeJumpWithoutCrankMotionNamesTheLine) {
  std::string csv = "time_s,crank_deg,pressure\n";
  char line[64];
  for (int i = 0; i < 50; ++i) {
    const double t = i * 0.5 / 18000.0 + (i >= 30 ? 0.2 : 0.0);  // acquisition paused 0.2 s before row 30
    std::snprintf(line, sizeof line, "%.9f,%.1f,1\n", t, i * 0.5);
    csv += line;
  }
  const std::string e = csv_error(csv);
  EXPECT_HAS(e, "p.csv: line 32: time_s jumps");
  EXPECT_HAS(e, "lost samples or a time error");
}

TEST(RunDirBadInput, CsvEmptyLineInsideTheData) {
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\n0,-360,1\n\n0.001,-359.5,1\n"),
             "line 3: empty line inside the data");
  EXPECT_EQ(csv_error("time_s,crank_deg,pressure\r\n0,-360,1\r\n0.001,-359.5,1\r\n\r\n"),
            "(no error)");  // CRLF, trailing blank
}

TEST(RunDirBadInput, CsvNamedByRunJsonMissing) {
  const fs::path d = valid_run("csv_missing");
  fs::remove(d / "pressure.csv");
  const std::string e = error_of(d);
  EXPECT_HAS(e, (d / "pressure.csv").string() + ": cannot open the pressure file named by pressure.file in run.json");
}

TEST(RunDirBadInput, CsvWhoseSpeedIsNotRunJsonsNamesBothSpeeds) {
  // time_s written in ms: every row is consistent, but the run is 1000 times too slow (3 rpm, not 3050); found
  // by fuzzing as an absurd time span that overflowed the 40 kHz frame count.
  const fs::path d = valid_run("csv_ms");
  std::string ms = "time_s,crank_deg,pressure\n";
  for (int i = 0; i < 200; ++i) {
    const double crank = -360.0 + 0.5 * i;
    char line[128];
    std::snprintf(line, sizeof line, "%.9f,%.3f,1.0\n", 1000.0 * (crank / 18000.0 + 0.02), crank);
    ms += line;
  }
  write_text(d / "pressure.csv", ms);
  const std::string e = error_of(d);
  EXPECT_HAS(e, (d / "pressure.csv").string() + ": the rows imply 3 rpm");
  EXPECT_HAS(e, "condition.speed_rpm is 3050");
  // Within the tolerance (3000 rows vs 3050 declared) the same rows are accepted.
  write_text(d / "pressure.csv", valid_csv());
  EXPECT_EQ(error_of(d), "(no error)");
}

// ---------------------------------------------------------------------------------------------- run.json

TEST(RunDirBadInput, RunJsonMissingKeysNameKeyAndFile) {
  const fs::path d = valid_run("json_missing");
  write_text(d / "run.json", R"({"condition": {"name": "x", "load_nm": 0, "soi_deg_btdc": 0, "motored": false},
                                 "pressure": {"file": "pressure.csv", "units": "bar"}})");
  const std::string e = error_of(d);
  EXPECT_HAS(e, (d / "run.json").string() + ": missing key \"condition.speed_rpm\"");
  EXPECT_HAS(
      json_error(R"({"condition": {"name": "x", "speed_rpm": 1, "load_nm": 0, "soi_deg_btdc": 0, "motored": false}})"),
      "r.json: missing key \"pressure\"");
  EXPECT_HAS(json_error(R"({"pressure": {"file": "p.csv", "units": "bar"}})"), "r.json: missing key \"condition\"");
  EXPECT_HAS(
      json_error(R"({"condition": {"name": "x", "speed_rpm": 1, "load_nm": 0, "soi_deg_btdc": 0, "motored": false},
      "pressure": {"file": "p.csv", "units": "bar"}, "mics": {"file": "m.wav"}})"),
      "r.json: missing key \"mics.positions_m\"");
}

TEST(RunDirBadInput, RunJsonWrongTypesNameKeyAndExpectedType) {
  const std::string base = R"("pressure": {"file": "p.csv", "units": "bar"})";
  EXPECT_HAS(
      json_error(
          R"({"condition": {"name": "x", "speed_rpm": "fast", "load_nm": 0, "soi_deg_btdc": 0, "motored": false}, )" +
          base + "}"),
      "r.json: key \"condition.speed_rpm\": expected a number or null (engine speed, rpm), found a string");
  EXPECT_HAS(
      json_error(R"({"condition": {"name": "x", "speed_rpm": 1, "load_nm": 0, "soi_deg_btdc": 0, "motored": "no"}, )" +
                 base + "}"),
      "key \"condition.motored\": expected true, false or null");
  EXPECT_HAS(
      json_error(
          R"({"condition": {"name": "x", "speed_rpm": 1, "load_nm": 0, "soi_deg_btdc": "n/a", "motored": true}, )" +
          base + "}"),
      "r.json: key \"condition.soi_deg_btdc\": expected a number or null (start of injection");
  EXPECT_HAS(
      json_error(R"({"condition": {"name": "x", "speed_rpm": 1, "load_nm": [], "soi_deg_btdc": 0, "motored": true}, )" +
                 base + "}"),
      "r.json: key \"condition.load_nm\": expected a number or null (brake torque, N m), found an array");
  EXPECT_HAS(
      json_error(R"({"condition": {"name": 7, "speed_rpm": 1, "load_nm": 0, "soi_deg_btdc": 0, "motored": false}, )" +
                 base + "}"),
      "key \"condition.name\": expected a string");
  EXPECT_HAS(json_error(R"({"condition": [], )" + base + "}"), "key \"condition\": expected an object, found an array");
  EXPECT_HAS(
      json_error(R"({"condition": {"name": "x", "speed_rpm": 1, "load_nm": 0, "soi_deg_btdc": 0, "motored": false},
      "pressure": {"file": "p.csv", "units": "psi"}})"),
      "key \"pressure.units\": \"psi\", expected \"bar\" or \"Pa\"");
  EXPECT_HAS(
      json_error(R"({"condition": {"name": "x", "speed_rpm": 1, "load_nm": 0, "soi_deg_btdc": 0, "motored": false}, )" +
                 base + R"(, "mics": {"file": "m.wav", "positions_m": [[1, 2]]}})"),
      "key \"mics.positions_m[0]\": expected [x, y, z]");
  EXPECT_HAS(
      json_error(
          R"({"condition": {"name": "x", "speed_rpm": -5, "load_nm": 0, "soi_deg_btdc": 0, "motored": false}, )" +
          base + "}"),
      "key \"condition.speed_rpm\": expected a speed above 0 rpm");
}

TEST(RunDirBadInput, RunJsonSyntaxErrorNamesFileAndPosition) {
  const std::string e = json_error("{\n  \"condition\": {,\n}");
  EXPECT_HAS(e, "r.json: not valid JSON");
  EXPECT_HAS(e, "line 2");
  EXPECT_HAS(json_error("[1, 2]"), "r.json: expected a JSON object at the top, found an array");
}

TEST(RunDirBadInput, RunJsonNumberBeyondDoubleNamesTheFile) {
  // Found by fuzzing: the JSON parser reports 2e308 as out_of_range, not as a parse error; it must still be a
  // RunDirError naming the file, not an exception of another type without it.
  const std::string e = json_error(R"({"condition": {"name": "x", "speed_rpm": 2e308}})");
  EXPECT_HAS(e, "r.json: not valid JSON");
  EXPECT_HAS(e, "2e308");
}

TEST(RunDirBadInput, CsvPressureBeyondAnyEngineIsRefusedNotOverflowed) {
  // 1e304 bar is a finite double, inf once converted to Pa.
  EXPECT_HAS(csv_error("time_s,crank_deg,pressure\n0,-360,1e304\n"),
             "line 2: field pressure is \"1e304\", expected a cylinder pressure within");
}

TEST(RunDirBadInput, MissingRunJsonSaysItIsNotARunDirectory) {
  const fs::path d = fresh_dir("empty");
  EXPECT_HAS(error_of(d), (d / "run.json").string() + ": cannot open run.json");
}

// ---------------------------------------------------------------------------------------------- mics.wav

TEST(RunDirBadInput, WavOfWrongChannelCountNamesFileAndExpectedCount) {
  const fs::path d = valid_run("wav_channels");
  write_wav(d / "mics.wav", 3, 51200, SF_FORMAT_WAV | SF_FORMAT_FLOAT);
  const std::string e = error_of(d);
  EXPECT_HAS(e, (d / "mics.wav").string() + ": 3 channels, expected 2 (one per entry of mics.positions_m in run.json)");
}

TEST(RunDirBadInput, PcmWavWithoutFullScaleIsRefusedWithTheReason) {
  const fs::path d = valid_run("wav_pcm");
  write_wav(d / "mics.wav", 2, 51200, SF_FORMAT_WAV | SF_FORMAT_PCM_16);
  const std::string e = error_of(d);
  EXPECT_HAS(e, (d / "mics.wav").string() + ": samples are 16-bit PCM, expected IEEE float in Pa");
  EXPECT_HAS(e, "mics.full_scale_pa");
}

TEST(RunDirBadInput, PcmWavWithFullScaleIsScaledToPa) {
  const fs::path d = valid_run("wav_pcm_scaled");
  write_wav(d / "mics.wav", 2, 48000, SF_FORMAT_WAV | SF_FORMAT_PCM_24);
  std::string json = kJson;
  json.replace(json.find("\"radius_m\": 1.75"), 16, "\"radius_m\": 1.75, \"full_scale_pa\": 200");
  write_text(d / "run.json", json);
  const formats::RunDir run = formats::read_run_dir(d);
  // 0.25 of full scale = 50 Pa amplitude; 24-bit quantisation 200 Pa / 2^23.
  for (int i = 0; i < 100; ++i)
    EXPECT_NEAR(run.mic_pa[2 * i + 1], 50.0 * std::sin(2 * std::numbers::pi * 1000.0 * i / 48000.0), 200.0 / (1 << 22));
}

TEST(RunDirBadInput, WavOfUnsupportedEncodingIsRefused) {
  const fs::path d = valid_run("wav_ulaw");
  write_wav(d / "mics.wav", 2, 51200, SF_FORMAT_WAV | SF_FORMAT_ULAW);
  EXPECT_HAS(error_of(d), (d / "mics.wav").string() + ": samples are u-law, expected IEEE float in Pa");
}

TEST(RunDirBadInput, WavRateTooLowOrNotResampleableNamesTheRate) {
  const fs::path d = valid_run("wav_rate");
  write_wav(d / "mics.wav", 2, 32000, SF_FORMAT_WAV | SF_FORMAT_FLOAT);
  EXPECT_HAS(error_of(d), (d / "mics.wav").string() + ": sample rate 32000 Hz, expected at least 40000 Hz");
  write_wav(d / "mics.wav", 2, 44101, SF_FORMAT_WAV | SF_FORMAT_FLOAT);
  const std::string e = error_of(d);
  EXPECT_HAS(e, (d / "mics.wav").string() + ": sample rate 44101 Hz cannot be resampled to 40000 Hz");
  // Found by fuzzing: a huge rate whose ratio to 40 kHz is simple (up 1, down 25000) asked the resampler for a
  // filter of billions of taps; it must be refused like the 44101 Hz file, not exhaust memory.
  write_wav(d / "mics.wav", 2, 1000000000, SF_FORMAT_WAV | SF_FORMAT_FLOAT);
  EXPECT_HAS(error_of(d), (d / "mics.wav").string() + ": sample rate 1000000000 Hz cannot be resampled to 40000 Hz");
}

TEST(RunDirBadInput, NotASoundFileOrTruncatedWav) {
  const fs::path d = valid_run("wav_garbage");
  write_text(d / "mics.wav", "this is not a WAV file at all, just text");
  EXPECT_HAS(error_of(d), (d / "mics.wav").string() + ": cannot read as a sound file");
  // A WAV whose data chunk is cut: the header promises more frames than the file holds.
  write_wav(d / "mics.wav", 2, 51200, SF_FORMAT_WAV | SF_FORMAT_FLOAT, 1000);
  fs::resize_file(d / "mics.wav", fs::file_size(d / "mics.wav") - 800);
  EXPECT_HAS(error_of(d),
             (d / "mics.wav").string() + ": truncated: the header promises 8000 bytes of samples, the file holds 7200");
}

TEST(RunDirBadInput, WavWithNonFiniteSamplesNamesFrameAndChannel) {
  const fs::path d = valid_run("wav_nan");
  SF_INFO info{};
  info.channels = 2;
  info.samplerate = 51200;
  info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
  SNDFILE* f = sf_open((d / "mics.wav").c_str(), SFM_WRITE, &info);
  std::vector<float> v(200, 0.0f);
  v[2 * 37 + 1] = std::numeric_limits<float>::quiet_NaN();
  sf_writef_float(f, v.data(), 100);
  sf_close(f);
  EXPECT_HAS(error_of(d), (d / "mics.wav").string() + ": frame 37, channel 2: not a finite number");
}
