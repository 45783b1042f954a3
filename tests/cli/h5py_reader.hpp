// Reading an HDF5 file back with h5py (Debian's python3-h5py: code that shares nothing with ours), for the tests
// of the HDF5 export.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include "tests/support/required.hpp"

namespace noisemon::test {

inline constexpr const char* kDebianPython = "/usr/bin/python3";  // the interpreter python3-h5py installs into

// Runs a Python script with h5py on the file and returns what it printed as JSON.
inline nlohmann::json read_with_h5py(const std::string& h5, const std::string& dir) {
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
     "k1_db": f["bands/k1_db"][:].tolist(),
     "mic_lpa": [[plain(v) for v in row] for row in f["mics/mic_lpa_db"][:].tolist()],
     "conditions": [c.decode() if isinstance(c, bytes) else c for c in f["runs/condition"][:].tolist()]}
json.dump(r, open(sys.argv[2], "w"))
)";
  const std::string command =
      std::string(kDebianPython) + " " + script + " " + h5 + " " + out + " 2>" + dir + "/err.txt";
  const int status = std::system(command.c_str());
  std::ifstream err(dir + "/err.txt");
  std::stringstream message;
  message << err.rdbuf();
  if (status != 0) throw std::runtime_error("h5py could not read the file: " + message.str());
  return nlohmann::json::parse(std::ifstream(out));
}

inline bool have_h5py() {
  return std::system((std::string(kDebianPython) + " -c 'import h5py' 2>/dev/null").c_str()) == 0;
}

}  // namespace noisemon::test

// Skips without h5py; fails instead under CI (tests/support/required.hpp), where scripts/install-deps.sh has installed
// it.
#define NOISEMON_REQUIRE_H5PY()                                                                                    \
  do {                                                                                                             \
    if (!::noisemon::test::have_h5py()) {                                                                          \
      if (::noisemon::test::under_ci()) FAIL() << "python3-h5py is missing (scripts/install-deps.sh installs it)"; \
      GTEST_SKIP() << "python3-h5py is not installed";                                                             \
    }                                                                                                              \
  } while (0)
