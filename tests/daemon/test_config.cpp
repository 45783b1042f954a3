// Configuration: the documented default file equals the built-in defaults, overrides land in the right
// fields, and bad input is an error that names the file, the line or the key.
#include <gtest/gtest.h>

#include <fstream>

#include "daemon/config.hpp"

using noisemon::daemon::Config;
using noisemon::daemon::ConfigError;
using noisemon::daemon::load_config;
using noisemon::daemon::parse_config;

namespace {

std::string error_of(const std::string& text) {
  try {
    parse_config(text, "test.toml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Config, DocumentedDefaultFileEqualsBuiltInDefaults) {
  const Config file = load_config(NOISEMON_SOURCE_DIR "/systemd/noisemond.toml");
  const Config def;
  EXPECT_EQ(file.source, def.source);
  EXPECT_EQ(file.cycles, def.cycles);
  EXPECT_EQ(file.log_level, def.log_level);
  EXPECT_EQ(file.live, def.live);
  EXPECT_EQ(file.lcm.url, def.lcm.url);
  EXPECT_EQ(file.lcm.report_channel, def.lcm.report_channel);
  EXPECT_EQ(file.lcm.status_channel, def.lcm.status_channel);
  EXPECT_EQ(file.lcm.raw_channel, def.lcm.raw_channel);
  EXPECT_EQ(file.lcm.operating_point_channel, def.lcm.operating_point_channel);
  EXPECT_EQ(file.lcm.session_channel, def.lcm.session_channel);
  EXPECT_EQ(file.lcm.publish_raw, def.lcm.publish_raw);
  EXPECT_EQ(file.model.k1, def.model.k1);
  EXPECT_EQ(file.model.b1, def.model.b1);
  EXPECT_EQ(file.acoustic_delay_s, def.acoustic_delay_s);
  EXPECT_EQ(file.ring_seconds, def.ring_seconds);
  EXPECT_EQ(file.sim.speed_rpm, def.sim.speed_rpm);
  EXPECT_EQ(file.sim.load_nm, def.sim.load_nm);
  EXPECT_EQ(file.sim.full_load_nm, def.sim.full_load_nm);
  EXPECT_EQ(file.sim.soi_deg_btdc, def.sim.soi_deg_btdc);
  EXPECT_EQ(file.sim.motored, def.sim.motored);
  EXPECT_EQ(file.sim.speed_fluctuation, def.sim.speed_fluctuation);
  EXPECT_EQ(file.sim.cycle_variation, def.sim.cycle_variation);
  EXPECT_EQ(file.sim.encoder_resolution_deg, def.sim.encoder_resolution_deg);
  EXPECT_EQ(file.sim.mic_count, def.sim.mic_count);
  EXPECT_EQ(file.sim.radius_m, def.sim.radius_m);
  EXPECT_EQ(file.sim.speed_of_sound_m_s, def.sim.speed_of_sound_m_s);
  EXPECT_EQ(file.sim.mic_rate_hz, def.sim.mic_rate_hz);
  EXPECT_EQ(file.sim.mic_gain_spread_db, def.sim.mic_gain_spread_db);
  EXPECT_EQ(file.sim.background_noise_db, def.sim.background_noise_db);
  EXPECT_EQ(file.sim.seed, def.sim.seed);
  EXPECT_EQ(file.sim.true_block.k1, def.sim.true_block.k1);
}

TEST(Config, PresetAndOverridesAreApplied) {
  const Config c = parse_config(R"(
[model]
preset = "nl_damper"
b3 = 2500.0
[sim]
speed_rpm = 3450
soi_deg_btdc = 24
mic_count = 2
mic_positions_m = [[1.0, 0.0, 0.5], [0.0, 1.0, 0.5]]
[sim.true_block]
preset = "nl_spring_damper"
)", "t");
  // Table 4.1, nonlinear damper row, with b3 overridden.
  EXPECT_DOUBLE_EQ(c.model.k1, 9.87e8);
  EXPECT_DOUBLE_EQ(c.model.b1, 7.00e3);
  EXPECT_DOUBLE_EQ(c.model.b3, 2500.0);
  EXPECT_DOUBLE_EQ(c.sim.speed_rpm, 3450.0);  // an integer is accepted where a number is expected
  EXPECT_DOUBLE_EQ(c.sim.soi_deg_btdc, 24.0);
  ASSERT_EQ(c.sim.mic_positions_m.size(), 2u);
  EXPECT_DOUBLE_EQ(c.sim.mic_positions_m[1][1], 1.0);
  EXPECT_DOUBLE_EQ(c.sim.true_block.k1, 8.00e8);
  EXPECT_DOUBLE_EQ(c.sim.true_block.k3, 1.00e13);
}

TEST(Config, ErrorsNameFileAndKey) {
  EXPECT_NE(error_of("[sim]\nspeed_rmp = 3000\n").find("test.toml:2: unknown key 'sim.speed_rmp'"), std::string::npos);
  EXPECT_NE(error_of("[sim]\nspeed_rpm = \"fast\"\n").find("test.toml: sim.speed_rpm: expected a number"), std::string::npos);
  EXPECT_NE(error_of("[sim]\nspeed_rpm = -5.0\n").find("sim.speed_rpm: value -5 out of range"), std::string::npos);
  EXPECT_NE(error_of("[model]\npreset = \"cubic\"\n").find("model.preset"), std::string::npos);
  EXPECT_NE(error_of("[daemon]\nsource = \"dac\"\n").find("daemon.source: unknown source 'dac'"), std::string::npos);
  EXPECT_NE(error_of("[sim]\nmic_count = 3\nmic_positions_m = [[0,0,1]]\n").find("sim.mic_positions_m"), std::string::npos);
  EXPECT_NE(error_of("[sim\nspeed_rpm = 1\n").find("test.toml:1:"), std::string::npos);  // syntax error: line named
  EXPECT_NE(error_of("bogus = 1\n").find("unknown key 'bogus'"), std::string::npos);
}

TEST(Config, MissingFileIsAnErrorNamingIt) {
  try {
    load_config("/nonexistent/noisemond.toml");
    FAIL() << "expected an error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/noisemond.toml"), std::string::npos);
  }
}
