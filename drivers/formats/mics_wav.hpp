// mics.wav of a run directory: the reader (IEEE float in Pa, or PCM with run.json's full scale; any rate the
// resampler takes to 40 kHz; a file cut short is named), from a file or from memory (read_mics_wav and
// parse_mics_wav, run_dir.hpp), and the writer.
#pragma once

#include <filesystem>

#include "drivers/formats/run_dir.hpp"

namespace noisemon::drivers::formats {

// run's microphones as a float WAV at `path` (RF64 past 4 GiB). Throws RunDirError.
void write_mics_wav(const std::filesystem::path& path, const RunDir& run);

}  // namespace noisemon::drivers::formats
