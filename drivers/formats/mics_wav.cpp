#include "drivers/formats/mics_wav.hpp"

#include <sndfile.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "drivers/formats/mapped_file.hpp"
#include "drivers/source.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers::formats {
namespace {

constexpr double kMinMicRateHz = 40000.0;

struct MemoryFile {
  const std::uint8_t* data;
  sf_count_t size;
  sf_count_t pos;
};

sf_count_t mem_length(void* user) { return static_cast<MemoryFile*>(user)->size; }
sf_count_t mem_seek(sf_count_t offset, int whence, void* user) {
  auto* m = static_cast<MemoryFile*>(user);
  sf_count_t to = whence == SEEK_SET ? offset : whence == SEEK_CUR ? m->pos + offset : m->size + offset;
  if (to < 0 || to > m->size) return -1;
  m->pos = to;
  return to;
}
sf_count_t mem_read(void* ptr, sf_count_t count, void* user) {
  auto* m = static_cast<MemoryFile*>(user);
  const sf_count_t n = std::max<sf_count_t>(0, std::min(count, m->size - m->pos));
  if (n > 0) std::memcpy(ptr, m->data + m->pos, static_cast<std::size_t>(n));
  m->pos += n;
  return n;
}
sf_count_t mem_write(const void*, sf_count_t, void*) { return 0; }
sf_count_t mem_tell(void* user) { return static_cast<MemoryFile*>(user)->pos; }

const char* subtype_name(int subtype) {
  switch (subtype) {
    case SF_FORMAT_PCM_S8:
      return "8-bit signed PCM";
    case SF_FORMAT_PCM_U8:
      return "8-bit unsigned PCM";
    case SF_FORMAT_PCM_16:
      return "16-bit PCM";
    case SF_FORMAT_PCM_24:
      return "24-bit PCM";
    case SF_FORMAT_PCM_32:
      return "32-bit PCM";
    case SF_FORMAT_FLOAT:
      return "32-bit IEEE float";
    case SF_FORMAT_DOUBLE:
      return "64-bit IEEE float";
    case SF_FORMAT_ULAW:
      return "u-law";
    case SF_FORMAT_ALAW:
      return "A-law";
    default:
      return "a compressed or unusual encoding";
  }
}

// Scales samples [from, to) of mic by `scale` while they are still in the cache; the index of the first that is not
// finite, or `to`.
std::size_t scale_finite(std::vector<float>& mic, std::size_t from, std::size_t to, double scale) {
  for (std::size_t i = from; i < to; ++i)
    if (!std::isfinite(mic[i])) return i;
  if (scale != 1.0)  // v * 1.0 is v: float samples keep their bits
    for (std::size_t i = from; i < to; ++i) mic[i] = static_cast<float>(mic[i] * scale);
  return to;
}

// The sound file's frames straight into mic, block by block, each block checked and scaled as it arrives. A
// file that ends early is named before a non-finite sample (as when every sample was read first).
void read_samples(SNDFILE* sf, sf_count_t frames, const std::string& file, std::uint32_t channels, double scale,
                  std::vector<float>& mic) {
  mic.reserve(static_cast<std::size_t>(frames) * channels);
  prefer_huge_pages(mic);
  mic.resize(static_cast<std::size_t>(frames) * channels);
  constexpr sf_count_t kBlockFrames = 16384;
  sf_count_t done = 0;
  std::size_t bad = mic.size();  // the first non-finite sample
  while (done < frames) {
    const std::size_t at = static_cast<std::size_t>(done) * channels;
    const sf_count_t n = sf_readf_float(sf, mic.data() + at, std::min(kBlockFrames, frames - done));
    if (n <= 0) break;
    done += n;
    if (bad == mic.size()) {
      const std::size_t to = static_cast<std::size_t>(done) * channels;
      if (const std::size_t i = scale_finite(mic, at, to, scale); i < to) bad = i;
    }
  }
  if (done != frames)
    throw RunDirError(file + ": ends after frame " + std::to_string(done) + " of " + std::to_string(frames) +
                      " (truncated or damaged)");
  if (bad < mic.size())
    throw RunDirError(file + ": frame " + std::to_string(bad / channels) + ", channel " +
                      std::to_string(bad % channels + 1) + ": not a finite number");
}

// Checks and reads an opened sound file into run (closes it).
void read_sound(SNDFILE* sf, const SF_INFO& info, const std::string& file, std::uint32_t channels,
                std::optional<double> full_scale_pa, RunDir& run) {
  struct Closer {
    SNDFILE* f;
    ~Closer() { sf_close(f); }
  } closer{sf};
  if (info.channels != static_cast<int>(channels))
    throw RunDirError(file + ": " + std::to_string(info.channels) + " channels, expected " + std::to_string(channels) +
                      " (one per entry of mics.positions_m in run.json)");
  const int subtype = info.format & SF_FORMAT_SUBMASK;
  const bool is_float = subtype == SF_FORMAT_FLOAT || subtype == SF_FORMAT_DOUBLE;
  const bool is_pcm = subtype == SF_FORMAT_PCM_S8 || subtype == SF_FORMAT_PCM_U8 || subtype == SF_FORMAT_PCM_16 ||
                      subtype == SF_FORMAT_PCM_24 || subtype == SF_FORMAT_PCM_32;
  double scale = 1.0;
  if (is_pcm && full_scale_pa) {
    scale = *full_scale_pa;
  } else if (is_pcm) {
    throw RunDirError(file + ": samples are " + subtype_name(subtype) +
                      ", expected IEEE float in Pa (PCM has no physical scale: convert it to float Pa, or give "
                      "mics.full_scale_pa in run.json)");
  } else if (!is_float) {
    throw RunDirError(file + ": samples are " + subtype_name(subtype) + ", expected IEEE float in Pa");
  }
  const double rate = static_cast<double>(info.samplerate);
  if (rate < kMinMicRateHz)
    throw RunDirError(file + ": sample rate " + std::to_string(info.samplerate) +
                      " Hz, expected at least 40000 Hz (the 1/3-octave bands reach 20 kHz)");
  if (rate != kPipelineRateHz) {
    try {
      dsp::RationalResampler probe(rate, kPipelineRateHz, 1);
    } catch (const std::invalid_argument&) {
      throw RunDirError(
          file + ": sample rate " + std::to_string(info.samplerate) +
          " Hz cannot be resampled to 40000 Hz (the ratio needs more than 4096 filter phases or decimates by "
          "more than 4096); "
          "expected a common rate such as 44100, 48000, 51200 or 96000 Hz");
    }
  }
  if (info.frames <= 0) throw RunDirError(file + ": no samples");
  // libsndfile quietly reads a WAV cut short as a shorter one; its log says so ("data : 8000 (should be 7200)").
  char log[4096] = {};
  sf_command(sf, SFC_GET_LOG_INFO, log, sizeof log);
  if (const char* d = std::strstr(log, "\ndata : ")) {
    long long claimed = 0, actual = 0;
    if (std::sscanf(d, "\ndata : %lld (should be %lld)", &claimed, &actual) == 2 && actual < claimed)
      throw RunDirError(file + ": truncated: the header promises " + std::to_string(claimed) +
                        " bytes of samples, the file holds " + std::to_string(actual));
  }
  run.mic_rate_hz = rate;
  run.mic_count = channels;
  read_samples(sf, info.frames, file, channels, scale, run.mic_pa);
}

}  // namespace

void read_mics_wav(const std::filesystem::path& file, std::uint32_t channels, std::optional<double> full_scale_pa,
                   RunDir& run) {
  SF_INFO info{};
  SNDFILE* sf = sf_open(file.c_str(), SFM_READ, &info);
  if (!sf)
    throw RunDirError(file.string() + ": cannot read as a sound file (" + sf_strerror(nullptr) +
                      "); expected a WAV of IEEE float samples in Pa");
  read_sound(sf, info, file.string(), channels, full_scale_pa, run);
}

void parse_mics_wav(const std::uint8_t* data, std::size_t size, const std::string& file, std::uint32_t channels,
                    std::optional<double> full_scale_pa, RunDir& run) {
  SF_VIRTUAL_IO io{mem_length, mem_seek, mem_read, mem_write, mem_tell};
  MemoryFile mem{data, static_cast<sf_count_t>(size), 0};
  SF_INFO info{};
  SNDFILE* sf = sf_open_virtual(&io, SFM_READ, &info, &mem);
  if (!sf)
    throw RunDirError(file + ": cannot read as a sound file (" + sf_strerror(nullptr) +
                      "); expected a WAV of IEEE float samples in Pa");
  read_sound(sf, info, file, channels, full_scale_pa, run);
}

void write_mics_wav(const std::filesystem::path& path, const RunDir& run) {
  SF_INFO info{};
  info.samplerate = static_cast<int>(std::lround(run.mic_rate_hz));
  info.channels = static_cast<int>(run.mic_count);
  // RF64 that libsndfile writes as plain WAV when it stays below 4 GiB.
  info.format = SF_FORMAT_RF64 | SF_FORMAT_FLOAT;
  SNDFILE* sf = sf_open(path.c_str(), SFM_WRITE, &info);
  if (!sf) throw RunDirError(path.string() + ": cannot write (" + sf_strerror(nullptr) + ")");
  sf_command(sf, SFC_RF64_AUTO_DOWNGRADE, nullptr, SF_TRUE);
  const sf_count_t frames = static_cast<sf_count_t>(run.mic_pa.size() / run.mic_count);
  const sf_count_t written = sf_writef_float(sf, run.mic_pa.data(), frames);
  const int close_err = sf_close(sf);
  if (written != frames || close_err != 0) throw RunDirError(path.string() + ": cannot write (disk full?)");
}

}  // namespace noisemon::drivers::formats
