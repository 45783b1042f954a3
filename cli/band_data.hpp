// DATA arguments of `noisemon fit` and `noisemon diagnose` -> the band dataset (model/fit/band_dataset.hpp).
//
// A DATA path is a run directory (the interchange format of docs/sources-and-formats.md: run.json + pressure.csv +
// mics.wav) or a raw LCM log (NOISEMON_SESSION / NOISEMON_RAW / NOISEMON_OP, as noisemond publishes and `noisemon
// import` writes); a log may hold several recordings. Recordings are grouped by condition name (run.json's
// condition.name, the session's condition; without one, the path's name); several recordings of one condition add their
// cycles. A condition named "background..." (or with speed 0) is an engine-off background measurement. A directory
// holding run directories (no run.json of its own, as `noisemon sim -o DIR` writes) stands for all of them, in name
// order; a .json file among the paths (the truth.json a glob picks up) is noted and skipped.
#pragma once

#include <cstdio>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "cli/cli_support.hpp"
#include "cli/formats/recording.hpp"
#include "model/fit/band_dataset.hpp"

namespace noisemon::cli {

struct LoadedRecording {
  formats::Recording recording;
  std::string origin;  // the path it came from (for messages)
  // What only a run directory tells (NaN: unknown, as for a raw LCM log): the pressure chain's commissioned
  // noise floor, Pa rms per encoder sample (run.json's pressure.noise_floor_bar), and the encoder's mean
  // sample rate, Hz (pressure.csv's rows).
  double pressure_floor_pa = std::numeric_limits<double>::quiet_NaN();
  double encoder_rate_hz = std::numeric_limits<double>::quiet_NaN();
};

// A run directory's contents as a loaded recording (its time base at epoch_utime). Its unknown SOI and load
// stay NaN; an unknown `motored` is not checked here (load_recordings refuses it).
LoadedRecording loaded_run(const drivers::formats::RunDir& run, std::int64_t epoch_utime, std::string origin);

// Reads every DATA path. Throws std::runtime_error naming the path and what is wrong; a run directory whose
// condition.motored is null (unknown) is refused: the diagnosis must know whether a run is a motored reference.
std::vector<LoadedRecording> load_recordings(const std::vector<std::string>& paths,
                                             const std::function<void(const std::string&)>& note = {});

// Groups recordings by condition and measures them (bank, cycles, coherence). Conditions keep the order of
// their first recording.
model::fit::BandDataset make_band_dataset(const std::vector<LoadedRecording>& recordings,
                                          const model::fit::DatasetOptions& options = {});

// Both steps for `fit` and `diagnose`: load_recordings' notes go to `out`, the bank pass shows on `line`.
model::fit::BandDataset load_band_dataset(const std::vector<std::string>& paths, std::FILE* out, ProgressLine& line);

// "a, b, c": the dataset's condition names, for messages.
std::string condition_names(const model::fit::BandDataset& data);

// The condition of a recording as the dataset sees it (unknown load and SOI: NaN).
model::fit::ConditionInfo condition_info(const formats::Recording& rec, const std::string& fallback_name);
// The same with what the run directory told (pressure floor, encoder rate); the origin is the fallback name.
model::fit::ConditionInfo condition_info(const LoadedRecording& r);

}  // namespace noisemon::cli
