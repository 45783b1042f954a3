#include "daemon/background_run.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "daemon/sound_power_setup.hpp"
#include "drivers/formats/run_dir.hpp"
#include "dsp/levels.hpp"
#include "dsp/third_octave_bank.hpp"

namespace noisemon::daemon {

std::vector<double> background_from_run_dir(const std::filesystem::path& dir) {
  const drivers::formats::RunManifest manifest = drivers::formats::read_run_manifest(dir);
  if (!manifest.has_mics)
    throw std::runtime_error((dir / "run.json").string() + ": the background run has no microphones");
  const std::filesystem::path wav = dir / manifest.mics_file;  // an absolute mics_file replaces dir
  drivers::formats::RunDir run;
  drivers::formats::read_mics_wav(wav, static_cast<std::uint32_t>(manifest.mic_positions_m.size()),
                                  manifest.full_scale_pa, run);
  dsp::ThirdOctaveBank bank(run.mic_rate_hz, run.mic_count);
  std::vector<double> block;
  constexpr std::size_t kFrames = 4096;
  for (std::size_t f = 0; f * run.mic_count < run.mic_pa.size(); f += kFrames) {
    const std::size_t n = std::min(kFrames, run.mic_pa.size() / run.mic_count - f);
    block.assign(run.mic_pa.begin() + static_cast<std::ptrdiff_t>(f * run.mic_count),
                 run.mic_pa.begin() + static_cast<std::ptrdiff_t>((f + n) * run.mic_count));
    bank.process(block.data(), n);
  }
  std::vector<double> ms(run.mic_count * bank.band_count());
  bank.take_mean_square(ms.data());
  std::vector<double> levels(kBackgroundBands, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t b = 0; b < bank.band_count(); ++b) {
    const int i = background_band_index(bank.bands()[b].nominal_hz);
    if (i < 0 || i >= kBackgroundBands || bank.bands()[b].nyquist_cut) continue;
    double sum = 0;
    for (std::size_t m = 0; m < run.mic_count; ++m) sum += ms[m * bank.band_count() + b];
    levels[i] = dsp::level_db(sum / static_cast<double>(run.mic_count));
  }
  return levels;
}

}  // namespace noisemon::daemon
