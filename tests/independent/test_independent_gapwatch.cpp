// The live gap watch on a stream the project did not make: the independent cell (cell_synth.hpp: the real Yanmar
// pressure records, eq. 4.1 with the cell's own constants, its own microphones, floors and effects) writes twelve
// clean runs and then six with one effect; `noisemon import` joins them into one log (a session per run) and the
// REAL `noisemon gapwatch` reads it, told nothing but the encoder's step. Magnitudes fixed before the first run: a
// flat +4 dB sensitivity error of microphone 4, a panel at 1.6 kHz (Q 5) +8 dB, 0.3 bar of added transducer noise.
// Each must give exactly one event (none in the clean part), naming the effect with its parameters.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cell_synth.hpp"
#include "required.hpp"

namespace {

namespace fs = std::filesystem;

constexpr int kCleanRuns = 12, kEffectRuns = 6, kCycles = 50;

const indep::Sources* sources() {
  static const std::string dir = std::string(NOISEMON_SHARED_DIR) + "/data/real";
  if (!fs::exists(dir + "/yanmar_l100v_fired_18Nm.txt")) return nullptr;
  static const indep::Sources s = indep::load_sources(dir);
  return &s;
}

std::string quote(const std::string& s) { return "'" + s + "'"; }

// The runs (clean, then with fx), imported into one log and watched; the events as JSON.
std::vector<nlohmann::json> watch_campaign(const indep::Effects& fx, const std::string& name) {
  const fs::path dir =
      fs::path(::testing::TempDir()) / ("noisemon-indep-gapwatch-" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  std::string runs;
  for (int i = 0; i < kCleanRuns + kEffectRuns; ++i) {
    indep::Condition c;
    c.name = "run" + std::to_string(100 + i);
    c.first_cycle = (i * 3) % 9;
    c.cycles = kCycles;
    indep::Chain chain;
    chain.seed = 1;
    const indep::Run run = indep::synthesize(*sources(), c, i, chain, i < kCleanRuns ? indep::Effects{} : fx);
    indep::write_run_dir(run, chain, dir / c.name);
    runs += " " + quote((dir / c.name).string());
  }
  const std::string noisemon = NOISEMON_PATH;
  const fs::path log = dir / "joined.lcmlog", events = dir / "events.jsonl";
  EXPECT_EQ(
      std::system((quote(noisemon) + " import" + runs + " -o " + quote(log.string()) + " > /dev/null 2>&1").c_str()),
      0);
  const std::string watch = quote(noisemon) + " gapwatch --no-progress --encoder-step-deg 0.2 --reference-s 25 --log " +
                            quote(log.string()) + " --json " + quote(events.string()) + " > " +
                            quote((dir / "out.txt").string()) + " 2>&1";
  EXPECT_EQ(std::system(watch.c_str()), 0);
  std::vector<nlohmann::json> out;
  std::ifstream in(events);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  std::ifstream text(dir / "out.txt");
  std::printf("%s: %s\n", name.c_str(), std::string(std::istreambuf_iterator<char>(text), {}).c_str());
  if (!std::getenv("NOISEMON_KEEP_TEMP")) fs::remove_all(dir);
  return out;
}

#define REQUIRE_RECORDS() NOISEMON_REQUIRE(sources(), "the Yanmar records in " NOISEMON_SHARED_DIR)

}  // namespace

TEST(IndependentGapwatch, MicrophoneSensitivityError) {
  REQUIRE_RECORDS();
  indep::Effects fx;
  fx.mic_gain_db = 4.0;
  fx.mic_gain_index = 3;
  fx.mic_gain_corner_hz = 0.0;
  const auto events = watch_campaign(fx, "mic_gain");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0]["effect"], "mic_gain");
  EXPECT_EQ(events[0]["params"]["mic"].get<double>(), 4.0);
  EXPECT_NEAR(events[0]["params"]["db"].get<double>(), 4.0, 0.5);
}

TEST(IndependentGapwatch, PanelResonance) {
  REQUIRE_RECORDS();
  indep::Effects fx;
  fx.second_mode_db = 8.0;
  fx.second_mode_hz = 1600.0;
  fx.second_mode_q = 5.0;
  const auto events = watch_campaign(fx, "second_mode");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0]["effect"], "second_mode");
  EXPECT_NEAR(std::log2(events[0]["params"]["hz"].get<double>() / 1600.0), 0.0, 1.0 / 6.0);
  EXPECT_NEAR(events[0]["params"]["db"].get<double>(), 8.0, 2.0);
}

TEST(IndependentGapwatch, TransducerNoise) {
  REQUIRE_RECORDS();
  indep::Effects fx;
  fx.transducer_noise_bar = 0.3;
  const auto events = watch_campaign(fx, "transducer_noise");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0]["effect"], "transducer_noise");
  EXPECT_NEAR(events[0]["params"]["bar"].get<double>(), 0.3, 0.1);
}
