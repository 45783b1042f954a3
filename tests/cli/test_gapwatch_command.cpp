// `noisemon gapwatch` end to end on a real log: noisemond runs the virtual engine unpaced with a microphone whose
// sensitivity rises 4 dB at 20 s ([[sim.effects]]), logging its cycle reports; the watch over the log names it,
// with its microphone, size and onset; the reference it saves gives the same event when loaded.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/cli/run_command.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/unique_temp.hpp"

namespace fs = std::filesystem;

namespace {

using noisemon::test::kNoisemon;
using noisemon::test::kNoisemond;
constexpr double kOnsetS = 20.0;

std::vector<nlohmann::json> read_events(const fs::path& path) {
  std::vector<nlohmann::json> events;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) events.push_back(nlohmann::json::parse(line));
  return events;
}

// 30 s of engine time (762 cycles at 3050 rpm), four microphones, a 0.5 deg encoder: the effect from 20 s on.
fs::path make_log(const fs::path& dir) {
  const fs::path log = dir / "run.lcmlog", config = dir / "run.toml";
  std::ofstream(config) << "[lcm]\nurl = \"file://" << log.string() << "?mode=w\"\npublish_raw = false\n"
                        << "[sim]\npaced = false\nencoder_resolution_deg = 0.5\nmic_count = 4\n"
                        << "[[sim.effects]]\neffect = \"mic_gain=4,mic=3\"\nonset_s = " << kOnsetS << "\n";
  const auto r =
      noisemon::test::run_command(kNoisemond + " --config " + config.string() + " --cycles 762 --log-level error");
  EXPECT_EQ(r.status, 0) << r.text;
  return log;
}

void expect_the_mic_gain(const std::vector<nlohmann::json>& events) {
  ASSERT_EQ(events.size(), 1u);
  const nlohmann::json& e = events[0];
  EXPECT_EQ(e["effect"], "mic_gain");
  EXPECT_EQ(e["kind"], "step");
  EXPECT_EQ(e["params"]["mic"].get<double>(), 3.0);
  EXPECT_NEAR(e["params"]["db"].get<double>(), 4.0, 0.4);
  EXPECT_NEAR(e["onset_s"].get<double>(), kOnsetS, 0.5);  // the reports' clock starts within a cycle of the sim's
  EXPECT_GE(e["detected_s"].get<double>(), e["onset_s"].get<double>());
  EXPECT_LT(e["detected_s"].get<double>(), kOnsetS + 3.0);
  EXPECT_GT(e["confidence"].get<double>(), 0.9);
  for (const char* key : {"gap_before_db", "gap_after_db", "onset_cycle", "detected_cycle", "features", "candidates"})
    EXPECT_TRUE(e.contains(key)) << key;
}

}  // namespace

TEST(GapwatchCommand, NamesAMicrophoneStepInALogAndAgainFromItsSavedReference) {
  const fs::path dir = noisemon::test::unique_temp("gapwatch_command");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path log = make_log(dir);
  const std::string watch = kNoisemon + " gapwatch --no-progress --reference-s 15 --log " + log.string();
  const auto first = noisemon::test::run_command(watch + " --json " + (dir / "a.jsonl").string() +
                                                 " --save-reference " + (dir / "ref.json").string());
  ASSERT_EQ(first.status, 0) << first.text;
  EXPECT_NE(first.text.find("mic_gain mic=3"), std::string::npos) << first.text;
  expect_the_mic_gain(read_events(dir / "a.jsonl"));
  // The saved reference, loaded: watched from the first block, the same effect, microphone and onset.
  const auto second = noisemon::test::run_command(watch + " --json " + (dir / "b.jsonl").string() + " --reference " +
                                                  (dir / "ref.json").string());
  ASSERT_EQ(second.status, 0) << second.text;
  expect_the_mic_gain(read_events(dir / "b.jsonl"));
  fs::remove_all(dir);
}

TEST(GapwatchCommand, BadInputNamesTheFile) {
  const fs::path dir = noisemon::test::unique_temp("gapwatch_bad");
  fs::create_directories(dir);
  std::ofstream(dir / "empty.lcmlog") << "";
  std::ofstream(dir / "ref.json") << "{\"format\": \"something else\"}";
  const auto empty =
      noisemon::test::run_command(kNoisemon + " gapwatch --no-progress --log " + (dir / "empty.lcmlog").string());
  EXPECT_EQ(empty.status, 1);
  EXPECT_NE(empty.text.find("empty.lcmlog: no cycle reports"), std::string::npos) << empty.text;
  const auto ref =
      noisemon::test::run_command(kNoisemon + " gapwatch --no-progress --log " + (dir / "empty.lcmlog").string() +
                                  " --reference " + (dir / "ref.json").string());
  EXPECT_EQ(ref.status, 1);
  EXPECT_NE(ref.text.find("ref.json"), std::string::npos) << ref.text;
  const auto help = noisemon::test::run_command(kNoisemon + " gapwatch --help");
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.text.find("--false-alarm-hours"), std::string::npos);
  fs::remove_all(dir);
}
