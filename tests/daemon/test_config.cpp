// Configuration: the documented default file equals the built-in defaults, overrides land in the right
// fields, and bad input is an error that names the file, the line or the key.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "daemon/config.hpp"
#include "daemon/sources.hpp"
#include "tests/support/unique_temp.hpp"

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
  EXPECT_EQ(file.microphones, def.microphones);
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
  EXPECT_EQ(file.engine.bore_m, def.engine.bore_m);
  EXPECT_EQ(file.engine.stroke_m, def.engine.stroke_m);
  EXPECT_EQ(file.engine.conrod_m, def.engine.conrod_m);
  EXPECT_EQ(file.engine.compression_ratio, def.engine.compression_ratio);
  EXPECT_EQ(file.model.k1, def.model.k1);
  EXPECT_EQ(file.model.b1, def.model.b1);
  EXPECT_EQ(file.acoustic_delay_s, def.acoustic_delay_s);
  EXPECT_EQ(file.ring_seconds, def.ring_seconds);
  EXPECT_EQ(file.mic_average_time, def.mic_average_time);
  EXPECT_EQ(file.sound_power.k2_db, def.sound_power.k2_db);
  EXPECT_EQ(file.sound_power.absorption_area_m2, def.sound_power.absorption_area_m2);
  EXPECT_EQ(file.sound_power.no_correction_above_db, def.sound_power.no_correction_above_db);
  EXPECT_EQ(file.sound_power.source_dimension_m, def.sound_power.source_dimension_m);
  EXPECT_EQ(file.sound_power.voronoi_area_weights, def.sound_power.voronoi_area_weights);
  EXPECT_TRUE(file.sound_power.background_db.empty());
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
  EXPECT_EQ(file.sim.pressure_chain.noise_bar, def.sim.pressure_chain.noise_bar);
  EXPECT_EQ(file.sim.pressure_chain.flicker_bar, def.sim.pressure_chain.flicker_bar);
  EXPECT_EQ(file.sim.pressure_chain.adc_bits, def.sim.pressure_chain.adc_bits);
  EXPECT_EQ(file.sim.pressure_chain.adc_min_bar, def.sim.pressure_chain.adc_min_bar);
  EXPECT_EQ(file.sim.pressure_chain.adc_max_bar, def.sim.pressure_chain.adc_max_bar);
  EXPECT_EQ(file.sim.mic_chain.self_noise_dba, def.sim.mic_chain.self_noise_dba);
  EXPECT_EQ(file.sim.mic_chain.directivity_db, def.sim.mic_chain.directivity_db);
  EXPECT_EQ(file.sim.mic_chain.adc_bits, def.sim.mic_chain.adc_bits);
  EXPECT_EQ(file.sim.mic_chain.adc_range_pa, def.sim.mic_chain.adc_range_pa);
  EXPECT_EQ(file.sim.gas_ringing.gain_s, def.sim.gas_ringing.gain_s);
  EXPECT_EQ(file.sim.gas_ringing.decay_s, def.sim.gas_ringing.decay_s);
  EXPECT_EQ(file.sim.seed, def.sim.seed);
  EXPECT_EQ(file.sim.true_block.k1, def.sim.true_block.k1);
  EXPECT_EQ(file.lcm.session_timeout_s, def.lcm.session_timeout_s);
  EXPECT_EQ(file.lcm.record_loss_channel, def.lcm.record_loss_channel);
  EXPECT_EQ(file.record.enabled, def.record.enabled);
  EXPECT_EQ(file.record.dir, def.record.dir);
  EXPECT_EQ(file.record.buffer_mb, def.record.buffer_mb);
  EXPECT_EQ(file.record.rotate_mb, def.record.rotate_mb);
  EXPECT_EQ(file.record.rotate_s, def.record.rotate_s);
  EXPECT_EQ(file.record.fsync, def.record.fsync);
  EXPECT_EQ(file.record.fsync_interval_s, def.record.fsync_interval_s);
  EXPECT_EQ(file.record.test_point, def.record.test_point);
  // [comedi] and [can] are documented as commented-out examples: the file leaves their defaults.
  EXPECT_EQ(file.comedi.pressure.device, def.comedi.pressure.device);
  EXPECT_EQ(file.comedi.encoder.subdevice, def.comedi.encoder.subdevice);
  EXPECT_EQ(file.comedi.mics.channels.size(), def.comedi.mics.channels.size());
  EXPECT_EQ(file.comedi.phase, def.comedi.phase);
  EXPECT_EQ(file.comedi.mics.buffer_bytes, def.comedi.mics.buffer_bytes);
  EXPECT_EQ(file.comedi.encoder.wake_every_scan, def.comedi.encoder.wake_every_scan);
  EXPECT_FALSE(file.can.configured());
  EXPECT_TRUE(file.can.map.signals().empty());
  EXPECT_EQ(file.threads.lock_memory, def.threads.lock_memory);
  for (const auto member :
       {&noisemon::daemon::ThreadsConfig::pressure, &noisemon::daemon::ThreadsConfig::mics,
        &noisemon::daemon::ThreadsConfig::operating_point, &noisemon::daemon::ThreadsConfig::can,
        &noisemon::daemon::ThreadsConfig::lcm_receive, &noisemon::daemon::ThreadsConfig::processing,
        &noisemon::daemon::ThreadsConfig::publishing, &noisemon::daemon::ThreadsConfig::recording}) {
    EXPECT_EQ((file.threads.*member).fifo_priority, (def.threads.*member).fifo_priority);
    EXPECT_EQ((file.threads.*member).cpu, (def.threads.*member).cpu);
  }
}

TEST(Config, HardwareExampleFileIsAValidComediAndCanConfiguration) {
  const Config c = load_config(NOISEMON_SOURCE_DIR "/systemd/noisemond.comedi.toml");
  EXPECT_EQ(c.source, "comedi");
  EXPECT_EQ(c.comedi.pressure.device, "/dev/comedi0");
  EXPECT_EQ(c.comedi.pressure.channel.aref, static_cast<unsigned>(AREF_DIFF));
  EXPECT_EQ(c.comedi.pressure.start_trigger, 1);
  EXPECT_DOUBLE_EQ(c.comedi.pressure.peg_pa, 101325.0);
  EXPECT_EQ(c.comedi.encoder.device, "/dev/comedi1");
  EXPECT_EQ(c.comedi.encoder.counts_per_rev, 3600u);
  EXPECT_DOUBLE_EQ(c.comedi.encoder.max_rpm, 4000.0);
  ASSERT_EQ(c.comedi.mics.channels.size(), 10u);
  EXPECT_EQ(c.comedi.mics.channels[9].channel, 9u);
  EXPECT_EQ(c.comedi.mics.channels[9].aref, static_cast<unsigned>(AREF_DIFF));  // one value for all channels
  ASSERT_EQ(c.comedi.mics.sensitivity_mv_per_pa.size(), 10u);
  EXPECT_DOUBLE_EQ(c.comedi.mics.sensitivity_mv_per_pa[3], 48.8);
  EXPECT_EQ(c.can.interface, "can0");
  ASSERT_EQ(c.can.map.signals().size(), 5u);
  // The acquisitions the source would open from it: pressure in Pa per volt through 16.2 pC/bar x 5 mV/pC.
  const auto a = noisemon::drivers::comedi::comedi_acquisitions(c.comedi);
  ASSERT_EQ(a.size(), 3u);
  EXPECT_NEAR(a[0].channels[0].si_per_volt, 1e5 / (16.2 * 5.0 * 1e-3), 1e-6);
  EXPECT_NEAR(a[2].channels[3].si_per_volt, 1.0 / 48.8e-3, 1e-9);
  // The DAQ threads first, then the processing; memory locked.
  EXPECT_TRUE(c.threads.lock_memory);
  EXPECT_EQ(c.threads.pressure.fifo_priority, 80);
  EXPECT_EQ(c.threads.mics.fifo_priority, 80);
  EXPECT_EQ(c.threads.processing.fifo_priority, 60);
  EXPECT_EQ(c.threads.publishing.fifo_priority, 0);
}

TEST(Config, SimStoppedEngineAndPressureChainErrors) {
  const Config c = parse_config(
      "[sim]\nstopped = true\nstatic_pressure_bar = 20.0\npressure_offset_bar = 0.37\npressure_gain_error = 0.04\n",
      "t");
  EXPECT_TRUE(c.sim.stopped);
  EXPECT_DOUBLE_EQ(c.sim.static_pressure_bar, 20.0);
  EXPECT_DOUBLE_EQ(c.sim.pressure_chain.offset_bar, 0.37);
  EXPECT_DOUBLE_EQ(c.sim.pressure_chain.gain_error, 0.04);
  EXPECT_NE(error_of("[sim]\npressure_gain_error = 4\n").find("sim.pressure_gain_error: value 4 out of range"),
            std::string::npos);
  EXPECT_NE(error_of("[sim]\nstopped = 1\n").find("sim.stopped: expected true or false"), std::string::npos);
}

TEST(Config, ComediAndCanErrorsNameFileAndKey) {
  EXPECT_NE(error_of("[comedi.pressure]\nchanel = 1\n").find("test.toml:2: unknown key 'comedi.pressure.chanel'"),
            std::string::npos);
  EXPECT_NE(error_of("[comedi.pressure]\naref = \"earth\"\n").find("comedi.pressure.aref: unknown value 'earth'"),
            std::string::npos);
  EXPECT_NE(error_of("[comedi.encoder]\nmax_rpm = -1\n").find("comedi.encoder.max_rpm"), std::string::npos);
  EXPECT_NE(
      error_of("[comedi.pressure]\noffset_bar = 250.0\n").find("comedi.pressure.offset_bar: value 250 out of range"),
      std::string::npos);
  EXPECT_NE(error_of("[comedi.pressure]\noffset_bar = \"0.4\"\n").find("comedi.pressure.offset_bar: expected a number"),
            std::string::npos);
  EXPECT_DOUBLE_EQ(
      noisemon::daemon::parse_config("[comedi.pressure]\noffset_bar = -0.25\n", "t").comedi.pressure.offset_bar, -0.25);
  // The engine at rest: the pressure's scan rate on the card's timer, whole Hz.
  EXPECT_NE(
      error_of("[comedi.pressure]\nrest_scan_rate_hz = 500\n").find("comedi.pressure.rest_scan_rate_hz: value 500"),
      std::string::npos);
  EXPECT_NE(error_of("[comedi.pressure]\nrest_scan_rate_hz = 12345.5\n")
                .find("comedi.pressure.rest_scan_rate_hz: a whole number of Hz"),
            std::string::npos);
  EXPECT_DOUBLE_EQ(noisemon::daemon::parse_config("[comedi.pressure]\nrest_scan_rate_hz = 10000\n", "t")
                       .comedi.pressure.rest_scan_rate_hz,
                   10000.0);
  EXPECT_NE(
      error_of("[comedi.encoder]\ntimestamp_bits = 48\n").find("comedi.encoder.timestamp_bits: value 48 out of range"),
      std::string::npos);
  EXPECT_NE(error_of("[comedi.mics]\nchannels = [0, 1]\nsensitivity_mv_per_pa = [50.0]\n")
                .find("comedi.mics.sensitivity_mv_per_pa: has 1 entries but there are 2 channels"),
            std::string::npos);
  EXPECT_NE(error_of("[comedi]\nphase = \"crank\"\n").find("comedi.phase"), std::string::npos);
  EXPECT_NE(error_of("[can]\ninterface = \"can0\"\n").find("can.interface: no [[can.signal]] entries"),
            std::string::npos);
  EXPECT_NE(error_of("[can]\npace = \"slow\"\n").find("can.pace"), std::string::npos);
  EXPECT_NE(error_of("[can]\ncandump = \"x.log\"\n[[can.signal]]\nfield = \"speed_rpm\"\nid = 1\nstart_bit = 0\nlength "
                     "= 99\nbyte_order = \"intel\"\n")
                .find("test.toml: can.signal[0].length"),
            std::string::npos);
  EXPECT_NE(error_of("[lcm]\nsession_timeout_s = 0\n").find("lcm.session_timeout_s"), std::string::npos);
  EXPECT_EQ(error_of("[daemon]\nsource = \"comedi\"\n"), "");  // devices are checked when the source opens them
}

TEST(Config, ComediKernelBufferAndWakeUpPerAcquisition) {
  const Config def;
  EXPECT_EQ(def.comedi.pressure.buffer_bytes, 0u);  // leave the driver's buffer
  EXPECT_FALSE(def.comedi.mics.wake_every_scan);
  const Config c = parse_config(R"(
[comedi.pressure]
buffer_bytes = 1048576
[comedi.encoder]
buffer_bytes = 4194304
wake_every_scan = true
[comedi.mics]
wake_every_scan = true
)",
                                "test.toml");
  EXPECT_EQ(c.comedi.pressure.buffer_bytes, 1048576u);
  EXPECT_FALSE(c.comedi.pressure.wake_every_scan);
  EXPECT_EQ(c.comedi.encoder.buffer_bytes, 4194304u);
  EXPECT_TRUE(c.comedi.encoder.wake_every_scan);
  EXPECT_EQ(c.comedi.mics.buffer_bytes, 0u);
  EXPECT_TRUE(c.comedi.mics.wake_every_scan);
  // They reach the acquisitions the source opens (a separate timestamp counter shares the encoder's).
  Config hw = load_config(NOISEMON_SOURCE_DIR "/systemd/noisemond.comedi.toml");
  hw.comedi.pressure.buffer_bytes = 1048576;
  hw.comedi.encoder = c.comedi.encoder;
  hw.comedi.encoder.subdevice = 0;
  hw.comedi.encoder.timestamp_subdevice = 1;
  hw.comedi.mics.wake_every_scan = true;
  const auto a = noisemon::drivers::comedi::comedi_acquisitions(hw.comedi);
  ASSERT_EQ(a.size(), 4u);
  EXPECT_EQ(a[0].buffer_bytes, 1048576u);
  EXPECT_FALSE(a[0].wake_every_scan);
  EXPECT_EQ(a[1].buffer_bytes, 4194304u);
  EXPECT_EQ(a[2].buffer_bytes, 4194304u);
  EXPECT_TRUE(a[2].wake_every_scan);
  EXPECT_EQ(a[3].buffer_bytes, 0u);
  EXPECT_TRUE(a[3].wake_every_scan);

  EXPECT_NE(
      error_of("[comedi.pressure]\nbuffer_bytes = -1\n").find("comedi.pressure.buffer_bytes: value -1 out of range"),
      std::string::npos);
  EXPECT_NE(error_of("[comedi.encoder]\nbuffer_bytes = 2147483648\n")
                .find("comedi.encoder.buffer_bytes: value 2147483648 out of range"),
            std::string::npos);
  EXPECT_NE(error_of("[comedi.mics]\nbuffer_bytes = 1.5e6\n").find("comedi.mics.buffer_bytes: expected an integer"),
            std::string::npos);
  EXPECT_NE(error_of("[comedi.mics]\nwake_every_scan = \"yes\"\n")
                .find("comedi.mics.wake_every_scan: expected true or false"),
            std::string::npos);
  EXPECT_NE(error_of("[comedi.encoder]\nwake_every_scan = 1\n")
                .find("comedi.encoder.wake_every_scan: expected true or false"),
            std::string::npos);
  EXPECT_NE(error_of("[comedi]\nbuffer_bytes = 4096\n").find("unknown key 'comedi.buffer_bytes'"),
            std::string::npos);  // per acquisition only
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
)",
                                "t");
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

// The realistic test cell of [sim]: the built-in defaults are the documented realistic values
// (docs/sources-and-formats.md, "The simulated engine"), every part has a key that switches it off, and bad values name
// the key.
TEST(Config, SimTestCellIsRealisticByDefaultAndEveryPartSwitchesOff) {
  const Config def;
  EXPECT_EQ(def.sim.pressure_chain.noise_bar, 0.02);
  EXPECT_EQ(def.sim.pressure_chain.adc_bits, 16);
  EXPECT_EQ(def.sim.pressure_chain.adc_max_bar, 250.0);
  EXPECT_EQ(def.sim.mic_chain.self_noise_dba, 20.0);
  EXPECT_EQ(def.sim.mic_chain.directivity_db, 1.0);
  EXPECT_EQ(def.sim.mic_chain.adc_bits, 24);
  EXPECT_GT(def.sim.gas_ringing.gain_s, 0.0);
  const Config off = parse_config(R"(
[sim]
pressure_noise_bar = 0
pressure_flicker_bar = 0.01
pressure_adc_bits = 0
mic_self_noise_dba = -inf
mic_directivity_db = 0
mic_adc_bits = 0
gas_ringing_us = 0
gas_ringing_decay_ms = 2.5
)",
                                  "t");
  EXPECT_EQ(off.sim.pressure_chain.noise_bar, 0.0);
  EXPECT_EQ(off.sim.pressure_chain.flicker_bar, 0.01);
  EXPECT_EQ(off.sim.pressure_chain.adc_bits, 0);
  EXPECT_FALSE(off.sim.mic_chain.has_self_noise());
  EXPECT_EQ(off.sim.mic_chain.directivity_db, 0.0);
  EXPECT_EQ(off.sim.mic_chain.adc_bits, 0);
  EXPECT_FALSE(off.sim.gas_ringing.active());
  EXPECT_DOUBLE_EQ(off.sim.gas_ringing.decay_s, 2.5e-3);
  const Config tuned =
      parse_config("[sim]\npressure_noise_bar = 0.2\nmic_adc_range_pa = 200\ngas_ringing_us = 12\n", "t");
  EXPECT_EQ(tuned.sim.pressure_chain.noise_bar, 0.2);  // the real Yanmar chain
  EXPECT_EQ(tuned.sim.mic_chain.adc_range_pa, 200.0);
  EXPECT_DOUBLE_EQ(tuned.sim.gas_ringing.gain_s, 12e-6);
  EXPECT_NE(error_of("[sim]\npressure_adc_bits = 2\n")
                .find("test.toml: sim.pressure_adc_bits: expected 0 (no ADC) or 4 .. 32"),
            std::string::npos);
  EXPECT_NE(error_of("[sim]\nmic_adc_bits = 40\n").find("sim.mic_adc_bits"), std::string::npos);
  EXPECT_NE(error_of("[sim]\npressure_adc_min_bar = 10\npressure_adc_max_bar = 5\n").find("sim.pressure_adc_max_bar"),
            std::string::npos);
  EXPECT_NE(error_of("[sim]\npressure_noise_bar = -0.1\n").find("sim.pressure_noise_bar: value -0.1 out of range"),
            std::string::npos);
  EXPECT_NE(error_of("[sim]\nmic_self_noise_dba = \"quiet\"\n").find("sim.mic_self_noise_dba: expected a number"),
            std::string::npos);
}

// One list of stream sources (daemon/sources.hpp): the configuration takes each of its names and tells every one of
// them for a name it does not know.
TEST(Config, TheSourceIsOneOfTheRegisteredStreamSources) {
  std::size_t kinds = 0;
  for (const auto& kind : noisemon::daemon::stream_sources()) {
    ++kinds;
    const std::string name(kind.name);
    EXPECT_EQ(parse_config("[daemon]\nsource = \"" + name + "\"\n", "test.toml").source, name);
    EXPECT_NE(error_of("[daemon]\nsource = \"dac\"\n").find(name), std::string::npos) << name;
    EXPECT_FALSE(kind.what.empty()) << name;
  }
  EXPECT_GE(kinds, 3u);  // sim, lcm, comedi
  EXPECT_EQ(noisemon::daemon::find_stream_source("dac"), nullptr);
}

// [daemon] microphones composes the microphones of a front-end of their own with the source's pressure; [alsa]
// describes the interface; its config file is found beside the configuration.
TEST(Config, MicrophonesFromAnAudioInterfaceAreReadFromTheAlsaTable) {
  const noisemon::daemon::Config c = parse_config(
      "[daemon]\nmicrophones = \"alsa\"\n"
      "[alsa]\npcm = \"hw:CARD=UMC1820,DEV=0\"\nconfig_file = \"cell.asoundrc\"\nrate_hz = 96000\n"
      "format = \"S24_3LE\"\ncapture_channels = 10\nchannels = [0, 1, 2, 9]\n"
      "sensitivity_mv_per_pa = [50.1, 49.8, 50.0, 51.2]\nfull_scale_v = 4.9\nperiod_frames = 480\nperiods = 6\n",
      "/etc/noisemon/cell.toml");
  EXPECT_EQ(c.microphones, "alsa");
  EXPECT_EQ(c.alsa.capture.pcm, "hw:CARD=UMC1820,DEV=0");
  EXPECT_EQ(c.alsa.capture.config_file, "/etc/noisemon/cell.asoundrc");
  EXPECT_EQ(c.alsa.capture.rate_hz, 96000u);
  EXPECT_EQ(c.alsa.capture.format, "S24_3LE");
  EXPECT_EQ(c.alsa.capture.channels, 10u);
  EXPECT_EQ(c.alsa.channels, (std::vector<unsigned>{0, 1, 2, 9}));
  EXPECT_EQ(c.alsa.sensitivity_mv_per_pa, (std::vector<double>{50.1, 49.8, 50.0, 51.2}));
  EXPECT_DOUBLE_EQ(c.alsa.full_scale_v, 4.9);
  EXPECT_EQ(c.alsa.capture.period_frames, 480u);
  EXPECT_EQ(c.alsa.capture.periods, 6u);
  EXPECT_EQ(c.alsa.sync_channel, -1);  // default: no sync pulse, the host clock aligns the interface
  EXPECT_TRUE(parse_config("", "test.toml").microphones.empty());  // default: the source's own
  const noisemon::daemon::Config synced =
      parse_config("[alsa]\nsync_channel = 11\nsync_angle_deg = 37.0\nhost_delay_uncertainty_s = 0.002\n", "t.toml");
  EXPECT_EQ(synced.alsa.sync_channel, 11);
  EXPECT_DOUBLE_EQ(synced.alsa.sync_angle_deg, 37.0);
  EXPECT_DOUBLE_EQ(synced.alsa.host_delay_uncertainty_s, 0.002);
  EXPECT_NE(error_of("[alsa]\nsync_channel = 32\n").find("alsa.sync_channel"), std::string::npos);

  for (const auto& kind : noisemon::daemon::mic_sources())
    EXPECT_NE(error_of("[daemon]\nmicrophones = \"jack\"\n").find(std::string(kind.name)), std::string::npos);
  EXPECT_NE(error_of("[daemon]\nmicrophones = \"jack\"\n").find("daemon.microphones"), std::string::npos);
  EXPECT_NE(error_of("[alsa]\nformat = \"S20_LE\"\n").find("alsa.format: unknown sample format"), std::string::npos);
  EXPECT_NE(error_of("[alsa]\nchannels = [0, 32]\n").find("alsa.channels"), std::string::npos);
  EXPECT_NE(error_of("[alsa]\nchannels = [0, 1]\nsensitivity_mv_per_pa = [50]\n").find("alsa.sensitivity_mv_per_pa"),
            std::string::npos);
  EXPECT_NE(error_of("[alsa]\nrate_hz = 1000\n").find("alsa.rate_hz"), std::string::npos);
  EXPECT_NE(error_of("[alsa]\npcm_name = \"hw:1\"\n").find("unknown key 'alsa.pcm_name'"), std::string::npos);
}

TEST(Config, ErrorsNameFileAndKey) {
  EXPECT_NE(error_of("[sim]\nspeed_rmp = 3000\n").find("test.toml:2: unknown key 'sim.speed_rmp'"), std::string::npos);
  EXPECT_NE(error_of("[sim]\nspeed_rpm = \"fast\"\n").find("test.toml: sim.speed_rpm: expected a number"),
            std::string::npos);
  EXPECT_NE(error_of("[sim]\nspeed_rpm = -5.0\n").find("sim.speed_rpm: value -5 out of range"), std::string::npos);
  EXPECT_NE(error_of("[model]\npreset = \"cubic\"\n").find("model.preset"), std::string::npos);
  EXPECT_NE(error_of("[daemon]\nsource = \"dac\"\n").find("daemon.source: unknown source 'dac'"), std::string::npos);
  EXPECT_NE(error_of("[sim]\nmic_count = 3\nmic_positions_m = [[0,0,1]]\n").find("sim.mic_positions_m"),
            std::string::npos);
  EXPECT_NE(error_of("[sim\nspeed_rpm = 1\n").find("test.toml:1:"), std::string::npos);  // syntax error: line named
  EXPECT_NE(error_of("bogus = 1\n").find("unknown key 'bogus'"), std::string::npos);
}

TEST(Config, SoundPowerCorrectionsAndPositionPresets) {
  const Config c = parse_config(R"(
[sound_power]
k2_db = 1.5
no_correction_above_db = 15.0
area_weights = [1, 1, 2]
background_db = [40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, nan]
[sim]
mic_count = 10
radius_m = 2.0
mic_positions_m = "iso3744"
)",
                                "sp.toml");
  EXPECT_EQ(c.sound_power.k2_db, 1.5);
  EXPECT_EQ(c.sound_power.no_correction_above_db, 15.0);
  EXPECT_EQ(c.sound_power.area_weights, (std::vector<double>{1, 1, 2}));
  ASSERT_EQ(c.sound_power.background_db.size(), 31u);
  EXPECT_TRUE(std::isnan(c.sound_power.background_db[30]));
  // ISO 3744 Annex B's top position is (0, 0, r); the first ring lies at z = 0.15 r.
  ASSERT_EQ(c.sim.mic_positions_m.size(), 10u);
  EXPECT_NEAR(c.sim.mic_positions_m[9][2], 2.0, 1e-9);
  EXPECT_NEAR(c.sim.mic_positions_m[0][2], 0.3, 1e-9);
  const Config t = parse_config("[sim]\nradius_m = 3.5\nmic_positions_m = \"table3.1\"\n", "t.toml");
  EXPECT_NEAR(t.sim.mic_positions_m[4][2], 3.5, 1e-9);  // Table 3.1's mic 5 is the top one, scaled to 3.5 m
  EXPECT_TRUE(parse_config("[sound_power]\narea_weights = \"voronoi\"\n", "v").sound_power.voronoi_area_weights);
}

TEST(Config, CombustionPeggingAndWindow) {
  const Config c = parse_config(R"(
[combustion]
pegging = "polytropic"
polytropic_exponent = 0
polytropic_from_deg = -110
rise_from_deg = -30
gamma = 1.32
[sound_power]
air_temperature_c = 35
air_pressure_kpa = 92
lw_full_range = true
)",
                                "c.toml");
  EXPECT_EQ(c.combustion.pegging, noisemon::model::Pegging::kPolytropic);
  EXPECT_TRUE(std::isnan(c.combustion.peg_exponent));  // 0: fitted
  EXPECT_EQ(c.combustion.peg_poly_from_deg, -110.0);
  EXPECT_EQ(c.combustion.rise_from_deg, -30.0);
  EXPECT_EQ(c.combustion.gamma, 1.32);
  EXPECT_EQ(c.sound_power.air_temperature_c, 35.0);
  EXPECT_EQ(c.sound_power.air_pressure_kpa, 92.0);
  EXPECT_TRUE(c.sound_power.full_range);
  const Config d = parse_config("[combustion]\npegging = \"intake\"\nintake_pressure_bar = 1.2\n", "d.toml");
  EXPECT_EQ(d.combustion.pegging, noisemon::model::Pegging::kIntake);
  EXPECT_NEAR(d.combustion.peg_intake_pa, 1.2e5, 1e-9);
  EXPECT_TRUE(std::isnan(parse_config("", "e").combustion.rise_from_deg));  // default: from the start of injection
  EXPECT_NE(error_of("[combustion]\npegging = \"tdc\"\n").find("combustion.pegging"), std::string::npos);
  EXPECT_NE(error_of("[combustion]\npolytropic_exponent = 0.8\n").find("combustion.polytropic_exponent"),
            std::string::npos);
}

TEST(Config, SoundPowerErrorsNameTheKey) {
  EXPECT_NE(
      error_of("[sound_power]\nbackground_db = [40, 40]\n").find("sound_power.background_db: expected 31 band levels"),
      std::string::npos);
  EXPECT_NE(error_of("[sound_power]\narea_weights = \"thirds\"\n").find("sound_power.area_weights"), std::string::npos);
  EXPECT_NE(error_of("[processing]\nmic_average = \"mean\"\n").find("processing.mic_average: expected"),
            std::string::npos);
  EXPECT_TRUE(parse_config("[processing]\nmic_average = \"time\"\n", "t").mic_average_time);
  EXPECT_NE(error_of("[sound_power]\nk2_db = -1.0\n").find("sound_power.k2_db: value -1 out of range"),
            std::string::npos);
  EXPECT_NE(error_of("[sim]\nmic_positions_m = \"iso\"\n").find("sim.mic_positions_m: unknown preset 'iso'"),
            std::string::npos);
  const std::string missing = error_of("[sound_power]\nbackground_run = \"/nonexistent/bg\"\n");
  EXPECT_NE(missing.find("sound_power.background_run: /nonexistent/bg/run.json"), std::string::npos) << missing;
}

TEST(Config, MissingFileIsAnErrorNamingIt) {
  try {
    load_config("/nonexistent/noisemond.toml");
    FAIL() << "expected an error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/noisemond.toml"), std::string::npos);
  }
}

TEST(Config, ThreadsSetPoliciesAndMemoryLock) {
  const Config def;
  EXPECT_FALSE(def.threads.lock_memory);
  EXPECT_EQ(def.threads.processing.fifo_priority, 0);  // normal scheduling, any CPU
  EXPECT_FALSE(def.threads.processing.cpu.has_value());
  const Config c = parse_config(R"(
[threads]
lock_memory = true
[threads.processing]
priority = 80
cpu = 1
[threads.pressure]
priority = 90
[threads.lcm_receive]
cpu = 0
[threads.publishing]
priority = 0
cpu = -1
)",
                                "t");
  EXPECT_TRUE(c.threads.lock_memory);
  EXPECT_EQ(c.threads.processing.fifo_priority, 80);
  EXPECT_EQ(c.threads.processing.cpu, 1);
  EXPECT_EQ(c.threads.pressure.fifo_priority, 90);
  EXPECT_FALSE(c.threads.pressure.cpu.has_value());
  EXPECT_EQ(c.threads.lcm_receive.cpu, 0);
  EXPECT_EQ(c.threads.publishing.fifo_priority, 0);
  EXPECT_FALSE(c.threads.publishing.cpu.has_value());
  EXPECT_EQ(c.threads.mics.fifo_priority, 0);  // not given: the default
  EXPECT_NE(error_of("[threads.procesing]\npriority = 10\n").find("test.toml:1: unknown key 'threads.procesing'"),
            std::string::npos);
  EXPECT_NE(error_of("[threads.mics]\nprio = 10\n").find("test.toml:2: unknown key 'threads.mics.prio'"),
            std::string::npos);
  EXPECT_NE(
      error_of("[threads.mics]\npriority = \"high\"\n").find("test.toml: threads.mics.priority: expected an integer"),
      std::string::npos);
  EXPECT_NE(error_of("[threads.can]\npriority = 100\n").find("threads.can.priority: value 100 out of range [0, 99]"),
            std::string::npos);
  EXPECT_NE(error_of("[threads.can]\ncpu = -2\n").find("threads.can.cpu: value -2 out of range [-1, 1023]"),
            std::string::npos);
  EXPECT_NE(error_of("[threads]\nlock_memory = 1\n").find("threads.lock_memory: expected true or false"),
            std::string::npos);
  EXPECT_NE(error_of("[threads]\nprocessing = 80\n").find("threads.processing: expected a table"), std::string::npos);
}

TEST(Config, TheRecordSectionAndItsErrorsNamingTheField) {
  const Config def;
  EXPECT_FALSE(def.record.enabled);
  EXPECT_FALSE(def.raw_streams() && !def.lcm.publish_raw);
  const Config c = parse_config(
      "[lcm]\npublish_raw = false\ncell = \"B\"\n[record]\nenabled = true\ndir = \"/data/rec\"\nbuffer_mb = 64.0\n"
      "rotate_mb = 512.0\nrotate_s = 3600.0\nfsync = \"interval\"\nfsync_interval_s = 2.0\ntest_point = \"tp_07\"\n"
      "[threads.recording]\ncpu = 1\n",
      "t");
  EXPECT_TRUE(c.record.enabled);
  EXPECT_TRUE(c.raw_streams());  // for the recorder, though not for the bus
  EXPECT_EQ(c.record.dir, "/data/rec");
  EXPECT_EQ(c.record.buffer_mb, 64.0);
  EXPECT_EQ(c.record.rotate_mb, 512.0);
  EXPECT_EQ(c.record.rotate_s, 3600.0);
  EXPECT_EQ(c.record.fsync, noisemon::daemon::RecordFsync::kInterval);
  EXPECT_EQ(c.record.fsync_interval_s, 2.0);
  EXPECT_EQ(c.record.test_point, "tp_07");
  EXPECT_EQ(c.threads.recording.cpu, 1);
  EXPECT_EQ(c.lcm.record_loss_channel, "NOISEMON_RECORD_LOSS_B");
  EXPECT_NE(error_of("[record]\nenabled = true\n").find("test.toml: record.dir: required when the recorder is enabled"),
            std::string::npos);
  EXPECT_NE(error_of("[record]\nfsync = \"always\"\n")
                .find("record.fsync: unknown value 'always' (expected one of none, rotate, interval)"),
            std::string::npos);
  EXPECT_NE(error_of("[record]\nbuffer_mb = 0.5\n").find("record.buffer_mb: value 0.5 out of range"),
            std::string::npos);
  EXPECT_NE(error_of("[record]\nrotate_s = 0.5\n").find("record.rotate_s: expected 0"), std::string::npos);
  EXPECT_NE(error_of("[record]\ntest_point = \"a/b\"\n").find("record.test_point: 'a/b': expected letters"),
            std::string::npos);
  EXPECT_NE(error_of("[record]\ntest_point = \"\"\n").find("record.test_point"), std::string::npos);
  EXPECT_NE(error_of("[record]\nfolder = \"x\"\n").find("test.toml:2: unknown key 'record.folder'"), std::string::npos);
  // A relative folder is the configuration file's neighbour.
  const std::string dir = noisemon::test::unique_temp_dir();
  std::ofstream(dir + "/n.toml") << "[record]\nenabled = true\ndir = \"runs\"\n";
  EXPECT_EQ(load_config(dir + "/n.toml").record.dir, dir + "/runs");
}

TEST(Config, EngineGeometryForTheCombustionMetrics) {
  const Config c =
      parse_config("[engine]\nbore_mm = 92\nstroke_mm = 96\nrod_mm = 155\ncompression_ratio = 17.5\n", "e.toml");
  EXPECT_DOUBLE_EQ(c.engine.bore_m, 0.092);
  EXPECT_DOUBLE_EQ(c.engine.stroke_m, 0.096);
  EXPECT_DOUBLE_EQ(c.engine.conrod_m, 0.155);
  EXPECT_DOUBLE_EQ(c.engine.compression_ratio, 17.5);
  EXPECT_NE(error_of("[engine]\nstroke_mm = 96\nrod_mm = 40\n").find("engine.rod_mm"), std::string::npos);
  EXPECT_NE(error_of("[engine]\nbore = 92\n").find("engine.bore"), std::string::npos);
  EXPECT_NE(error_of("[engine]\ncompression_ratio = 1.0\n").find("engine.compression_ratio"), std::string::npos);
}

TEST(Config, SimFaultsAreReadInOrderAndBadOnesNameTheirEntryAndKey) {
  const Config c = parse_config(R"(
[[sim.faults]]
kind = "missing_edges"
at_s = 2.5
duration_s = 0.5
per_rev = 7
[[sim.faults]]
kind = "overload"
channel = "mic10"
at_s = 1
gain = 8
[[sim.faults]]
kind = "stall"
channel = "mics"
duration_s = 30
)",
                                "f.toml");
  ASSERT_EQ(c.sim.faults.size(), 3u);
  EXPECT_EQ(c.sim.faults[0].kind, noisemon::drivers::sim::SimFaultKind::kMissingEdges);
  EXPECT_DOUBLE_EQ(c.sim.faults[0].at_s, 2.5);
  EXPECT_DOUBLE_EQ(c.sim.faults[0].duration_s, 0.5);
  EXPECT_DOUBLE_EQ(c.sim.faults[0].per_rev, 7.0);
  EXPECT_EQ(c.sim.faults[1].kind, noisemon::drivers::sim::SimFaultKind::kOverload);
  EXPECT_EQ(c.sim.faults[1].target, 9);  // mic10, 0-based
  EXPECT_DOUBLE_EQ(c.sim.faults[1].gain, 8.0);
  EXPECT_EQ(c.sim.faults[2].target, noisemon::drivers::sim::kMicsTarget);
  EXPECT_DOUBLE_EQ(c.sim.faults[2].duration_s, 30.0);
  EXPECT_TRUE(Config().sim.faults.empty());  // none by default

  const std::string unknown = error_of("[[sim.faults]]\nkind = \"gremlins\"\n");
  EXPECT_NE(unknown.find("sim.faults[0].kind"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("gremlins"), std::string::npos) << unknown;
  const std::string mic = error_of("[[sim.faults]]\nkind = \"flat\"\nchannel = \"mic11\"\n");
  EXPECT_NE(mic.find("sim.faults[0].channel"), std::string::npos) << mic;
  EXPECT_NE(mic.find("mic11"), std::string::npos) << mic;
  const std::string stream = error_of(
      "[[sim.faults]]\nkind = \"nan\"\nchannel = \"pressure\"\n[[sim.faults]]\nkind = \"stall\"\nchannel = \"mic2\"\n");
  EXPECT_NE(stream.find("sim.faults[1].channel"), std::string::npos) << stream;
  const std::string key = error_of("[[sim.faults]]\nkind = \"flat\"\nchannel = \"pressure\"\nwhen = 3\n");
  EXPECT_NE(key.find("sim.faults[0].when"), std::string::npos) << key;
  EXPECT_NE(error_of("[sim]\nfaults = 3\n").find("sim.faults"), std::string::npos);
}

// [[sim.effects]]: on from the start without a ramp, an effect is part of the engine; with an onset or a ramp it is
// scheduled. Bad entries name their table and key.
TEST(Config, SimEffectsAreStaticOrScheduledAndBadOnesNameTheirEntry) {
  const Config c = parse_config(R"(
[[sim.effects]]
effect = "background_noise=50"
[[sim.effects]]
effect = "mic_gain=3,mic=4"
onset_s = 90
[[sim.effects]]
effect = "second_mode=6,hz=3150"
onset_s = 30
ramp_s = 600
)",
                                "f.toml");
  ASSERT_EQ(c.sim.effects.settings.size(), 1u);
  EXPECT_DOUBLE_EQ(*c.sim.effects.background_noise_dba, 50.0);
  ASSERT_EQ(c.sim.scheduled_effects.size(), 2u);
  EXPECT_EQ(c.sim.scheduled_effects[0].setting.name, "mic_gain");
  EXPECT_DOUBLE_EQ(c.sim.scheduled_effects[0].setting.magnitude, 3.0);
  EXPECT_DOUBLE_EQ(c.sim.scheduled_effects[0].onset_s, 90.0);
  EXPECT_DOUBLE_EQ(c.sim.scheduled_effects[0].ramp_s, 0.0);
  EXPECT_DOUBLE_EQ(c.sim.scheduled_effects[1].ramp_s, 600.0);
  EXPECT_TRUE(Config().sim.scheduled_effects.empty());

  const std::string unknown = error_of("[[sim.effects]]\neffect = \"gremlins=3\"\nonset_s = 1\n");
  EXPECT_NE(unknown.find("sim.effects[0].effect"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("gremlins"), std::string::npos) << unknown;
  const std::string mic = error_of("[[sim.effects]]\neffect = \"mic_gain=3,mic=11\"\n");
  EXPECT_NE(mic.find("sim.effects[0].effect"), std::string::npos) << mic;
  EXPECT_NE(mic.find("11"), std::string::npos) << mic;
  const std::string twice =
      error_of("[[sim.effects]]\neffect = \"mic_gain=3\"\n[[sim.effects]]\neffect = \"mic_gain=1\"\nonset_s = 5\n");
  EXPECT_NE(twice.find("sim.effects[1].effect"), std::string::npos) << twice;
  const std::string negative = error_of("[[sim.effects]]\neffect = \"mic_gain=3\"\nramp_s = -1\n");
  EXPECT_NE(negative.find("sim.effects[0].ramp_s"), std::string::npos) << negative;
  EXPECT_NE(error_of("[[sim.effects]]\nonset_s = 5\n").find("sim.effects[0].effect"), std::string::npos);
}

// [[sim.schedule]]: each step keeps what it does not give from the step before (the first from [sim]); bad steps,
// steps out of order and operating-point-dependent effects are refused, naming the entry and key.
TEST(Config, SimScheduleStepsInheritUnsetKeysAndBadOnesNameTheirEntry) {
  const Config c = parse_config(R"(
[sim]
speed_rpm = 3050
soi_deg_btdc = 18
[[sim.schedule]]
at_s = 600
ramp_s = 10
speed_rpm = 3450
load_nm = 20
[[sim.schedule]]
at_s = 1200
soi_deg_btdc = 14
)",
                                "f.toml");
  ASSERT_EQ(c.sim.operating_schedule.size(), 2u);
  const auto& first = c.sim.operating_schedule[0];
  EXPECT_EQ(first.at_s, 600.0);
  EXPECT_EQ(first.ramp_s, 10.0);
  EXPECT_EQ(first.condition.speed_rpm, 3450.0);
  EXPECT_EQ(first.condition.load_nm, 20.0);
  EXPECT_EQ(first.condition.soi_deg_btdc, 18.0);
  const auto& second = c.sim.operating_schedule[1];
  EXPECT_EQ(second.condition.speed_rpm, 3450.0);
  EXPECT_EQ(second.condition.load_nm, 20.0);
  EXPECT_EQ(second.condition.soi_deg_btdc, 14.0);
  EXPECT_TRUE(Config().sim.operating_schedule.empty());

  const std::string order = error_of("[[sim.schedule]]\nat_s = 60\nramp_s = 30\n[[sim.schedule]]\nat_s = 80\n");
  EXPECT_NE(order.find("sim.schedule[1].at_s"), std::string::npos) << order;
  EXPECT_NE(error_of("[[sim.schedule]]\nspeed_rpm = 2000\n").find("sim.schedule[0].at_s"), std::string::npos);
  EXPECT_NE(error_of("[[sim.schedule]]\nat_s = 5\nspeed_rpm = 20000\n").find("sim.schedule[0].speed_rpm"),
            std::string::npos);
  EXPECT_NE(error_of("[[sim.schedule]]\nat_s = 5\ngear = 3\n").find("gear"), std::string::npos);
  const std::string dependent =
      error_of("[[sim.effects]]\neffect = \"speed_dependence=2\"\n[[sim.schedule]]\nat_s = 5\nspeed_rpm = 2000\n");
  EXPECT_NE(dependent.find("sim.schedule"), std::string::npos) << dependent;
}
