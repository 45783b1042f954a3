// The background for ISO 3744's K1 from a recording made with the engine off ([sound_power] background_run).
#pragma once

#include <filesystem>
#include <vector>

namespace noisemon::daemon {

// The background band levels of a run directory recorded with the engine off (run.json and its mics.wav; the
// pressure is not read): each microphone's band levels over the whole recording, energy-averaged over the
// microphones, at the nominal bands of background_band_hz (NaN where the WAV's rate does not reach). Throws
// std::runtime_error naming the file when it has no microphones or cannot be read.
std::vector<double> background_from_run_dir(const std::filesystem::path& dir);

}  // namespace noisemon::daemon
