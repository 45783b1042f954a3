// The HDF5 export read back by h5py (Debian's python3-h5py, code that shares nothing with ours): every value,
// shape and unit attribute as written, NaN kept, a short report padded, two runs indexed.
#include "daemon/cli/hdf5_publisher.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "tests/drivers/unique_temp.hpp"

namespace {

using noisemon::cycle_report_t;
using nlohmann::json;

constexpr const char* kDebianPython = "/usr/bin/python3";  // the interpreter python3-h5py installs into

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
  }
  m.nmics = static_cast<std::int16_t>(nmics);
  for (int i = 0; i < nmics; ++i) {
    m.mic_lpa_db.push_back(static_cast<float>(95 + i));
    m.mic_flags.push_back(i == 1 ? cycle_report_t::MIC_EXCLUDED : 0);
  }
  return m;
}

// Runs a Python script with h5py on the file and returns what it printed as JSON.
json read_with_h5py(const std::string& h5, const std::string& dir) {
  const std::string script = dir + "/read.py", out = dir + "/read.json";
  std::ofstream(script) << R"(import h5py, json, math, sys
f = h5py.File(sys.argv[1], "r")
def plain(v):
    return None if isinstance(v, float) and math.isnan(v) else v
r = {"groups": sorted(f.keys()),
     "cycle": f["cycles/cycle"][:].tolist(), "run": f["cycles/run"][:].tolist(),
     "lpa_measured_db": f["cycles/lpa_measured_db"][:].tolist(),
     "lpa_predicted_db": [plain(v) for v in f["cycles/lpa_predicted_db"][:].tolist()],
     "flags": f["cycles/flags"][:].tolist(), "peak_pressure_bar": f["cycles/peak_pressure_bar"][:].tolist(),
     "units_lpa": f["cycles/lpa_measured_db"].attrs["units"].decode(),
     "units_band_hz": f["bands/band_hz"].attrs["units"].decode(),
     "band_hz": f["bands/band_hz"][:].tolist(),
     "spl_shape": list(f["bands/spl_a_measured_db"].shape),
     "spl": f["bands/spl_a_measured_db"][:].tolist(),
     "band_flags": f["bands/band_flags"][:].tolist(),
     "mic_lpa": [[plain(v) for v in row] for row in f["mics/mic_lpa_db"][:].tolist()],
     "conditions": [c.decode() if isinstance(c, bytes) else c for c in f["runs/condition"][:].tolist()]}
json.dump(r, open(sys.argv[2], "w"))
)";
  const std::string command = std::string(kDebianPython) + " " + script + " " + h5 + " " + out + " 2>" + dir + "/err.txt";
  const int status = std::system(command.c_str());
  std::ifstream err(dir + "/err.txt");
  std::stringstream message;
  message << err.rdbuf();
  if (status != 0) throw std::runtime_error("h5py could not read the file: " + message.str());
  return json::parse(std::ifstream(out));
}

bool have_h5py() {
  return std::system((std::string(kDebianPython) + " -c 'import h5py' 2>/dev/null").c_str()) == 0;
}

TEST(Hdf5Publisher, H5pyReadsEveryValueShapeAndUnitAsWritten) {
  if (!have_h5py()) {
    if (std::getenv("CI")) FAIL() << "python3-h5py is missing (scripts/install-deps.sh installs it)";
    GTEST_SKIP() << "python3-h5py is not installed";
  }
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string h5 = dir + "/cycles.h5";
  {
    noisemon::daemon::Hdf5Publisher publisher(h5);
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
  EXPECT_EQ(r["band_flags"][0][0].get<double>(), cycle_report_t::BAND_BELOW_FIRING);
  EXPECT_EQ(r["mic_lpa"][0], json({95.0, 96.0, 97.0}));
  EXPECT_EQ(r["mic_lpa"][3], json({95.0, 96.0, nullptr}));
}

TEST(Hdf5Publisher, ManyCyclesSpanSeveralWritesInOrder) {
  if (!have_h5py()) GTEST_SKIP() << "python3-h5py is not installed";
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string h5 = dir + "/many.h5";
  constexpr int kCycles = 2500;  // more than two buffered writes
  {
    noisemon::daemon::Hdf5Publisher publisher(h5);
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
  noisemon::daemon::Hdf5Publisher publisher(dir + "/wide.h5");
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
    noisemon::daemon::Hdf5Publisher publisher("/nonexistent-dir/x.h5");
    FAIL() << "created a file in a missing directory";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.h5"), std::string::npos) << e.what();
  }
}

}  // namespace
