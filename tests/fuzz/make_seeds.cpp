// Writes the binary seed inputs of the fuzz targets (raw LCM logs, WAV files) into DIR/<target>/, so the
// seed corpus is generated at build time instead of kept as blobs in git. Usage: fuzz_make_seeds DIR
#include <cstdio>
#include <filesystem>

#include "fuzz_util.hpp"
#include "valid_inputs.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  namespace fs = std::filesystem;
  const fs::path out = argv[1];
  for (const char* target : {"replay", "lcm_log_reader", "recordings_log"}) {
    const fs::path dir = out / target;
    fs::create_directories(dir);
    noisemon::fuzz::write_raw_log(dir / "one_mic_three_cycles.lcmlog", 1, 3, 160, 80, false);
    noisemon::fuzz::write_raw_log(dir / "pressure_only.lcmlog", 0, 2, 120, 64, true);
    noisemon::fuzz::write_raw_log(dir / "three_mics_short.lcmlog", 3, 1, 64, 40, false);
  }
  // The run-directory targets: each file valid on its own (the text ones also have variants in git).
  fs::create_directories(out / "run_dir_json");
  fs::create_directories(out / "run_dir_csv");
  fs::create_directories(out / "run_dir_wav");
  noisemon::fuzz::write_file(out / "run_dir_json" / "run.json", noisemon::fuzz::run_json());
  noisemon::fuzz::write_file(out / "run_dir_csv" / "pressure.csv", noisemon::fuzz::pressure_csv());
  noisemon::fuzz::write_file(out / "run_dir_wav" / "mics.wav", noisemon::fuzz::mics_wav());
  noisemon::fuzz::write_file(out / "run_dir_wav" / "mics_48k.wav", noisemon::fuzz::mics_wav(48000));
  return 0;
}
