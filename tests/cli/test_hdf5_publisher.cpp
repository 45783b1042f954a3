// The HDF5 export read back by h5py (Debian's python3-h5py, code that shares nothing with ours): every value,
// shape and unit attribute as written, NaN kept, a short report padded, two runs indexed.
#include "cli/hdf5_publisher.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/cli/h5py_reader.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using nlohmann::json;
using noisemon::cycle_report_t;
using noisemon::test::read_with_h5py;

cycle_report_t report(std::int64_t cycle, int nbands, int nmics) {
  cycle_report_t m{};
  m.utime = 1'700'000'000'000'000 + cycle * 39'344;
  m.cycle = cycle;
  m.duration_s = 0.039344;
  m.speed_rpm = 3050.0 + cycle;
  m.lpa_measured_db = 100.0 + 0.25 * static_cast<double>(cycle);
  m.lpa_predicted_db = cycle == 1 ? NAN : 99.5;
  m.flags = cycle == 2 ? cycle_report_t::CYCLE_GAP : 0;
  m.peak_pressure_bar = 70.0 + cycle;
  m.nbands = static_cast<std::int16_t>(nbands);
  for (int b = 0; b < nbands; ++b) {
    m.band_hz.push_back(static_cast<float>(100.0 * std::pow(10.0, b / 10.0)));
    m.spl_a_measured_db.push_back(static_cast<float>(60 + b + cycle));
    m.spl_a_predicted_db.push_back(59.0f);
    m.cpl_db.push_back(150.0f);
    m.att_measured_db.push_back(static_cast<float>(90 - b - cycle));
    m.att_predicted_db.push_back(91.0f);
    m.band_flags.push_back(b == 0 ? cycle_report_t::BAND_BELOW_FIRING : 0);
    m.k1_db.push_back(b == 1 ? 0.75f : 0.0f);
    m.background_db.push_back(40.0f);
  }
  m.nmics = static_cast<std::int16_t>(nmics);
  for (int i = 0; i < nmics; ++i) {
    m.mic_lpa_db.push_back(static_cast<float>(95 + i));
    m.mic_flags.push_back(i == 1 ? cycle_report_t::MIC_EXCLUDED : 0);
  }
  return m;
}

TEST(Hdf5Publisher, H5pyReadsEveryValueShapeAndUnitAsWritten) {
  NOISEMON_REQUIRE_H5PY();
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string h5 = dir + "/cycles.h5";
  {
    noisemon::cli::Hdf5Publisher publisher(h5);
    publisher.begin_run("idle");
    for (int c = 0; c < 3; ++c) publisher.publish("NOISEMON_CYCLE", report(c, 4, 3), 0);
    publisher.begin_run("full");
    publisher.publish("NOISEMON_CYCLE", report(0, 4, 2), 0);  // one microphone short: padded with NaN
    publisher.flush();
  }
  const json r = read_with_h5py(h5, dir);
  EXPECT_EQ(r["groups"], json({"bands", "cycles", "mics", "runs"}));
  EXPECT_EQ(r["cycle"], json({0, 1, 2, 0}));
  EXPECT_EQ(r["run"], json({0, 0, 0, 1}));
  EXPECT_EQ(r["conditions"], json({"idle", "full"}));
  EXPECT_EQ(r["lpa_measured_db"], json({100.0, 100.25, 100.5, 100.0}));
  EXPECT_EQ(r["lpa_predicted_db"], json({99.5, nullptr, 99.5, 99.5}));  // NaN stays NaN
  EXPECT_EQ(r["flags"], json({0, 0, cycle_report_t::CYCLE_GAP, 0}));
  EXPECT_EQ(r["peak_pressure_bar"], json({70.0, 71.0, 72.0, 70.0}));
  EXPECT_EQ(r["units_lpa"], "dB(A) re 20 uPa");
  EXPECT_EQ(r["units_band_hz"], "Hz");
  ASSERT_EQ(r["band_hz"].size(), 4u);
  EXPECT_NEAR(r["band_hz"][3].get<double>(), 199.526, 1e-3);
  EXPECT_EQ(r["spl_shape"], json({4, 4}));
  EXPECT_EQ(r["spl"][2], json({62.0, 63.0, 64.0, 65.0}));
  EXPECT_EQ(r["band_flags"][0][0].get<double>(), static_cast<double>(cycle_report_t::BAND_BELOW_FIRING));
  EXPECT_NEAR(r["k1_db"][0][1].get<double>(), 0.75, 1e-6);
  EXPECT_EQ(r["mic_lpa"][0], json({95.0, 96.0, 97.0}));
  EXPECT_EQ(r["mic_lpa"][3], json({95.0, 96.0, nullptr}));
}

TEST(Hdf5Publisher, ManyCyclesSpanSeveralWritesInOrder) {
  NOISEMON_REQUIRE_H5PY();
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string h5 = dir + "/many.h5";
  constexpr int kCycles = 2500;  // more than two buffered writes
  {
    noisemon::cli::Hdf5Publisher publisher(h5);
    for (int c = 0; c < kCycles; ++c) publisher.publish("NOISEMON_CYCLE", report(c, 2, 1), 0);
  }  // the destructor writes the rest
  const json r = read_with_h5py(h5, dir);
  ASSERT_EQ(r["cycle"].size(), static_cast<std::size_t>(kCycles));
  for (int c = 0; c < kCycles; c += 97) EXPECT_EQ(r["cycle"][c], c);
  EXPECT_EQ(r["lpa_measured_db"][kCycles - 1], 100.0 + 0.25 * (kCycles - 1));
  EXPECT_EQ(r["conditions"], json({""}));
}

TEST(Hdf5Publisher, AReportWiderThanTheFirstIsRefusedNamingTheFileAndCycle) {
  const std::string dir = noisemon::test::unique_temp_dir();
  noisemon::cli::Hdf5Publisher publisher(dir + "/wide.h5");
  publisher.publish("NOISEMON_CYCLE", report(0, 4, 2), 0);
  try {
    publisher.publish("NOISEMON_CYCLE", report(7, 4, 3), 0);
    FAIL() << "a report with more microphones than the first was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("wide.h5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cycle 7"), std::string::npos) << e.what();
  }
}

TEST(Hdf5Publisher, AnUnwritablePathIsAClearError) {
  try {
    noisemon::cli::Hdf5Publisher publisher("/nonexistent-dir/x.h5");
    FAIL() << "created a file in a missing directory";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.h5"), std::string::npos) << e.what();
  }
}

}  // namespace
