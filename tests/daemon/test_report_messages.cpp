// The LCM messages: what the daemon publishes decodes to the same values with LCM's C++ decoder and with the
// Python classes lcm-gen generates for other tools (a second, independent decoder).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>

#include "daemon/report_messages.hpp"
#include "tests/support/unique_temp.hpp"

using namespace noisemon;

namespace {

daemon::CycleReport sample_report() {
  daemon::CycleReport r;
  r.utime = 1'700'000'000'123'456;
  r.cycle = 42;
  r.duration_s = 0.039344;
  r.op.speed_rpm = 3050.0;
  r.op.load_nm = 0.0;
  r.op.soi_deg_btdc = 18.0;
  r.op.rail_pressure_bar = NAN;
  r.lpa_measured_db = 84.25;
  r.lpa_predicted_db = 84.0;
  r.lwa_measured_db = 97.09;
  r.lwa_predicted_db = 96.84;
  r.radius_m = 1.75;
  r.nbands = 31;
  for (int b = 0; b < 31; ++b) {
    r.band_hz[b] = static_cast<float>(20 * std::pow(10.0, b / 10.0));
    r.cpl_db[b] = 200.0f - b;
    r.spl_a_measured_db[b] = 50.0f + b;
    r.spl_a_predicted_db[b] = 51.0f + b;
    r.att_measured_db[b] = r.cpl_db[b] - r.spl_a_measured_db[b];
    r.att_predicted_db[b] = r.cpl_db[b] - r.spl_a_predicted_db[b];
  }
  r.band_flags[30] = daemon::kBandNyquistCut;
  r.nmics = 10;
  for (int m = 0; m < 10; ++m) r.mic_lpa_db[m] = 84.0f + 0.1f * m;
  r.mic_flags[9] = daemon::kMicExcluded | daemon::kMicLow;
  r.flags = daemon::kCycleSettling | daemon::kCycleMicExcluded;
  return r;
}

std::string run_command(const std::string& cmd) {
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(cmd.c_str(), "r"), pclose);
  std::string out;
  char buf[4096];
  while (pipe && fgets(buf, sizeof buf, pipe.get())) out += buf;
  return out;
}

}  // namespace

TEST(ReportMessages, FlagConstantsMatchTheMessageDefinition) {
  EXPECT_EQ(daemon::kBandNyquistCut, +noisemon::cycle_report_t::BAND_NYQUIST_CUT);
  EXPECT_EQ(daemon::kBandSlow, +noisemon::cycle_report_t::BAND_SLOW);
  EXPECT_EQ(daemon::kBandSettling, +noisemon::cycle_report_t::BAND_SETTLING);
  EXPECT_EQ(daemon::kBandBelowFiring, +noisemon::cycle_report_t::BAND_BELOW_FIRING);
  EXPECT_EQ(daemon::kCycleSettling, +noisemon::cycle_report_t::CYCLE_SETTLING);
  EXPECT_EQ(daemon::kCycleGap, +noisemon::cycle_report_t::CYCLE_GAP);
  EXPECT_EQ(daemon::kCycleNoOperatingPoint, +noisemon::cycle_report_t::CYCLE_NO_OPERATING_POINT);
  EXPECT_EQ(daemon::kCycleLengthOdd, +noisemon::cycle_report_t::CYCLE_LENGTH_ODD);
  EXPECT_EQ(daemon::kCycleNoMics, +noisemon::cycle_report_t::CYCLE_NO_MICS);
  EXPECT_EQ(daemon::kCycleEncoder, +noisemon::cycle_report_t::CYCLE_ENCODER);
  EXPECT_EQ(daemon::kCycleOverload, +noisemon::cycle_report_t::CYCLE_OVERLOAD);
  EXPECT_EQ(daemon::kCycleMicExcluded, +noisemon::cycle_report_t::CYCLE_MIC_EXCLUDED);
  EXPECT_EQ(daemon::kCyclePressureFault, +noisemon::cycle_report_t::CYCLE_PRESSURE_FAULT);
  EXPECT_EQ(daemon::kMicExcluded, +noisemon::cycle_report_t::MIC_EXCLUDED);
  EXPECT_EQ(daemon::kMicFlat, +noisemon::cycle_report_t::MIC_FLAT);
  EXPECT_EQ(daemon::kMicOverload, +noisemon::cycle_report_t::MIC_OVERLOAD);
  EXPECT_EQ(daemon::kMicNan, +noisemon::cycle_report_t::MIC_NAN);
  EXPECT_EQ(daemon::kMicLow, +noisemon::cycle_report_t::MIC_LOW);
}

TEST(ReportMessages, EveryCycleFlagHasAName) {
  EXPECT_EQ(daemon::cycle_flags_text(0), "ok");
  EXPECT_EQ(daemon::cycle_flags_text(daemon::kCycleEncoder | daemon::kCycleOverload | daemon::kCycleMicExcluded |
                                     daemon::kCyclePressureFault),
            "encoder,overload,mic-excluded,pressure-fault");
  EXPECT_EQ(daemon::kCycleLwUpperBound, +noisemon::cycle_report_t::CYCLE_LW_UPPER_BOUND);
  EXPECT_EQ(daemon::kCycleAngleGap, +noisemon::cycle_report_t::CYCLE_ANGLE_GAP);
  for (std::int32_t bit = 1; bit <= daemon::kCycleAngleGap; bit <<= 1)
    EXPECT_NE(daemon::cycle_flags_text(bit), "") << bit;
}

TEST(ReportMessages, CycleReportRoundTripsThroughLcmEncoding) {
  const noisemon::cycle_report_t m = daemon::to_message(sample_report());
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  ASSERT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  noisemon::cycle_report_t back;
  ASSERT_EQ(back.decode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  EXPECT_EQ(back.cycle, 42);
  EXPECT_EQ(back.nbands, 31);
  EXPECT_FLOAT_EQ(back.att_measured_db[5], 200.0f - 5 - (50.0f + 5));
  EXPECT_EQ(back.band_flags[30], +noisemon::cycle_report_t::BAND_NYQUIST_CUT);
  ASSERT_EQ(back.mic_flags.size(), 10u);
  EXPECT_EQ(back.mic_flags[9], noisemon::cycle_report_t::MIC_EXCLUDED | noisemon::cycle_report_t::MIC_LOW);
  EXPECT_EQ(back.mic_flags[8], 0);
  EXPECT_TRUE(std::isnan(back.rail_pressure_bar));
}

TEST(ReportMessages, RawBlockStaysUnderTheLcmFragmentLimit) {
  drivers::SampleBlock b;
  b.first_index = 123456;
  b.frames = drivers::SampleBlock::kMaxFrames;
  b.channels = drivers::SampleBlock::kMaxChannels;
  for (std::size_t i = 0; i < b.frames * b.channels; ++i) b.data[i] = static_cast<double>(i);
  const noisemon::raw_block_t m = daemon::to_message(b, noisemon::raw_block_t::STREAM_MICS, 1'000'000);
  // LCM 1.3.1 fragments UDP datagrams above 64 KB; the largest raw block must fit with the channel name.
  EXPECT_LT(m.getEncodedSize() + 64, 65000);
  EXPECT_EQ(m.utime, 1'000'000 + 123456 * 25);                         // 25 us per frame at 40 kHz
  EXPECT_DOUBLE_EQ(m.data[3 * b.channels + 5], 3.0 * b.channels + 5);  // frame 3, channel 5
}

TEST(ReportMessages, PythonDecoderReadsWhatTheDaemonEncodes) {
  const std::string python_dir = NOISEMON_BINARY_DIR "/msgs/gen/python";
  if (run_command("python3 -c 'print(1)' 2>/dev/null") != "1\n") GTEST_SKIP() << "python3 not available";
  const noisemon::cycle_report_t m = daemon::to_message(sample_report());
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  const std::string path = noisemon::test::unique_temp_dir() + "/cycle_report.bin";
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(buf.data()), static_cast<std::streamsize>(buf.size()));
  const std::string out = run_command(
      "PYTHONPATH=" + python_dir + " python3 -c \"import noisemon; m = noisemon.cycle_report_t.decode(open('" + path +
      "','rb').read()); print(m.cycle, m.nbands, round(m.lpa_measured_db, 3), "
      "round(m.cpl_db[3], 3), m.band_flags[30], m.nmics, round(m.mic_lpa_db[9], 3), m.mic_flags[9], m.flags)\"");
  EXPECT_EQ(out, "42 31 84.25 197.0 1 10 84.9 17 129\n");
}

TEST(ReportMessages, EveryUnknownValueIsPlainNanInTheCsv) {
  // A NaN with its sign bit set (what arithmetic on NaN may give) must not print as "-nan".
  daemon::CycleReport r;
  r.op.load_nm = -std::numeric_limits<double>::quiet_NaN();
  for (double* v :
       {&r.combustion.peak_pressure_pa, &r.combustion.peak_angle_deg, &r.combustion.max_rise_pa_per_deg,
        &r.combustion.max_rise_angle_deg, &r.combustion.imep_gross_pa, &r.combustion.imep_net_pa,
        &r.combustion.heat_release_j, &r.combustion.ca10_deg, &r.combustion.ca50_deg, &r.combustion.ca90_deg,
        &r.combustion.ringing_intensity_w_per_m2, &r.combustion.pegging_offset_pa, &r.combustion.pmep_pa,
        &r.combustion.n_compression, &r.combustion.n_expansion, &r.combustion.ca05_deg, &r.combustion.burn_duration_deg,
        &r.combustion.max_rise_motored_pa_per_deg, &r.combustion.mapo_pa})
    *v = -std::numeric_limits<double>::quiet_NaN();
  const std::string row = daemon::cycle_csv_row(daemon::to_message(r), "c");
  EXPECT_EQ(row.find("-nan"), std::string::npos) << row;
  std::size_t nans = 0;
  for (std::size_t at = row.find("nan"); at != std::string::npos; at = row.find("nan", at + 1)) ++nans;
  EXPECT_EQ(nans, 20u) << row;
}
