// The alsa microphone source through alsa-lib itself: PCMs an asoundrc defines from alsa-lib's own plugins (the
// `file` plugin's infile, over a `null` slave; `plug` for the conversions alsa-lib does itself), opened by the same
// snd_pcm_open path an audio interface takes. Checked against what the raw files were made from (sines of known
// level and frequency) and against alsa-lib's own sample conversion; and the errors a user meets (a PCM that does
// not exist, a config file that is missing or broken, a rate the device cannot do, channels it lacks).
#include <gtest/gtest.h>

#include <memory>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "drivers/alsa/alsa_capture.hpp"
#include "drivers/alsa/alsa_source.hpp"
#include "drivers/combined_source.hpp"
#include "drivers/crank_reference.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/driver_counters.hpp"
#include "tests/support/unique_temp.hpp"

namespace nd = noisemon::drivers;
namespace na = noisemon::drivers::alsa;

namespace {

// Little-endian bytes of a value in [-1, 1) in each format, written here from the formats' definitions.
void append_sample(std::vector<std::uint8_t>& out, na::SampleFormat f, double v) {
  auto le = [&](std::uint32_t b, int n) {
    for (int i = 0; i < n; ++i) out.push_back(static_cast<std::uint8_t>(b >> (8 * i)));
  };
  switch (f) {
    case na::SampleFormat::kS16:
      le(static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(v * 32767.0))), 2);
      break;
    case na::SampleFormat::kS24:
      le(static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(v * 8388607.0))) & 0xFFFFFFu, 4);
      break;
    case na::SampleFormat::kS24Packed:
      le(static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(v * 8388607.0))), 3);
      break;
    case na::SampleFormat::kS32:
      le(static_cast<std::uint32_t>(static_cast<std::int32_t>(std::llround(v * 2147483647.0))), 4);
      break;
    case na::SampleFormat::kFloat: {
      const float x = static_cast<float>(v);
      std::uint32_t b;
      std::memcpy(&b, &x, 4);
      le(b, 4);
      break;
    }
  }
}

// `frames` frames of `channels` channels; channel c holds amplitude[c] * sin(2 pi freq[c] t).
struct CaptureTone {
  double amplitude, freq_hz;
};
std::string write_raw(const std::string& name, na::SampleFormat f, unsigned rate, const std::vector<CaptureTone>& tones,
                      std::size_t frames) {
  std::vector<std::uint8_t> bytes;
  for (std::size_t k = 0; k < frames; ++k)
    for (const CaptureTone& t : tones)
      append_sample(bytes, f,
                    t.amplitude * std::sin(2.0 * std::numbers::pi * t.freq_hz * static_cast<double>(k) / rate));
  const std::string path = noisemon::test::unique_temp(name).string();
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return path;
}

// An asoundrc defining `pcm.nm_test`: the file plugin capturing `infile`, over null; with `plug_format`, behind
// alsa-lib's plug converting from that format (and with `plug_rate`, fixing the slave's rate).
std::string write_asoundrc(const std::string& infile, const std::string& plug_format = "", unsigned plug_rate = 0) {
  std::string file_pcm = "{ type file slave.pcm \"null\" file \"/dev/null\" infile \"" + infile + "\" format \"raw\" }";
  std::string text;
  if (plug_format.empty()) {
    text = "pcm.nm_test " + file_pcm + "\n";
  } else {
    text = "pcm.nm_file " + file_pcm + "\npcm.nm_test { type plug slave { pcm \"nm_file\" format " + plug_format +
           (plug_rate ? " rate " + std::to_string(plug_rate) : "") + " } }\n";
  }
  const std::string path = noisemon::test::unique_temp("asoundrc").string();
  std::ofstream(path) << text;
  return path;
}

// Reads `frames` frames (or what comes before the stream runs dry) from a capture.
std::vector<double> read_frames(na::Capture& capture, unsigned channels, std::size_t frames) {
  std::vector<double> all, values;
  capture.start();
  for (int spins = 0; all.size() < frames * channels && spins < 100000; ++spins) {
    std::size_t n = 0;
    if (capture.read(values, n) != na::ReadStatus::kFrames) {
      capture.wait(10);
      continue;
    }
    all.insert(all.end(), values.begin(), values.begin() + static_cast<std::ptrdiff_t>(n * channels));
  }
  all.resize(std::min(all.size(), frames * channels));
  return all;
}

}  // namespace

class AlsaFormats : public ::testing::TestWithParam<na::SampleFormat> {};

// Our decoding of each format equals alsa-lib's own conversion of the same bytes to float (plug), and the tone
// the bytes were written from.
TEST_P(AlsaFormats, DecodedSamplesAreAlsaLibsOwnConversionAndTheWrittenTone) {
  const na::SampleFormat f = GetParam();
  const std::vector<CaptureTone> tones = {{0.5, 1000.0}, {-0.25, 3000.0}};
  const std::string raw = write_raw("tone.raw", f, 48000, tones, 4800);
  const std::string name(na::format_name(f));

  na::CaptureConfig direct{.pcm = "nm_test",
                           .config_file = write_asoundrc(raw),
                           .rate_hz = 48000,
                           .channels = 2,
                           .format = name,
                           .period_frames = 256,
                           .periods = 4};
  na::Capture ours(direct);
  EXPECT_EQ(ours.format(), f);
  const std::vector<double> mine = read_frames(ours, 2, 4800);

  na::CaptureConfig plugged = direct;
  plugged.config_file = write_asoundrc(raw, name);
  plugged.format = "FLOAT_LE";
  // (Behind plug, alsa-lib's file plugin reads its infile in the mmap path, which runs ahead of what was read after
  // two periods: the whole tone fits in two periods here.)
  plugged.period_frames = 2400;
  na::Capture theirs(plugged);
  const std::vector<double> alsa_lib = read_frames(theirs, 2, 4800);

  ASSERT_EQ(mine.size(), 9600u);
  ASSERT_EQ(alsa_lib.size(), 9600u);
  const double lsb = f == na::SampleFormat::kS16 ? 1.0 / 32768 : 1.0 / 8388608;
  double worst_vs_lib = 0, worst_vs_tone = 0;
  for (std::size_t k = 0; k < 4800; ++k)
    for (std::size_t c = 0; c < 2; ++c) {
      const double v = mine[k * 2 + c];
      worst_vs_lib = std::max(worst_vs_lib, std::abs(v - alsa_lib[k * 2 + c]));
      const double tone = tones[c].amplitude * std::sin(2.0 * std::numbers::pi * tones[c].freq_hz * k / 48000.0);
      worst_vs_tone = std::max(worst_vs_tone, std::abs(v - tone));
    }
  EXPECT_LT(worst_vs_lib, 1e-6) << name;         // alsa-lib's float holds 24 bits
  EXPECT_LT(worst_vs_tone, 1.01 * lsb) << name;  // rounding to the format's step
}

INSTANTIATE_TEST_SUITE_P(EachFormat, AlsaFormats,
                         ::testing::Values(na::SampleFormat::kS16, na::SampleFormat::kS24, na::SampleFormat::kS24Packed,
                                           na::SampleFormat::kS32, na::SampleFormat::kFloat),
                         [](const auto& info) {
                           std::string n(na::format_name(info.param));
                           for (char& ch : n)
                             if (ch == '_') ch = 'x';
                           return n;
                         });

namespace {

// The amplitude and frequency of a sine in one channel of interleaved frames at 40 kHz: least squares at the
// known frequency (amplitude), and the phase advance between the two halves (frequency).
double amplitude_at(const std::vector<double>& v, std::size_t channels, std::size_t c, double f_hz, std::size_t from,
                    std::size_t to) {
  double ss = 0, sc = 0, s2 = 0, c2 = 0, cs = 0;
  for (std::size_t k = from; k < to; ++k) {
    const double w = 2.0 * std::numbers::pi * f_hz * k / 40000.0, x = v[k * channels + c];
    ss += x * std::sin(w), sc += x * std::cos(w), s2 += std::sin(w) * std::sin(w), c2 += std::cos(w) * std::cos(w);
    cs += std::sin(w) * std::cos(w);
  }
  const double det = s2 * c2 - cs * cs, a = (ss * c2 - sc * cs) / det, b = (sc * s2 - ss * cs) / det;
  return std::hypot(a, b);
}

}  // namespace

namespace {

// A stream source of pressure alone for the composition: its own two microphones, never started (the composed
// source's microphones are the interface's), its epoch, one thread.
class PressureOnly final : public nd::Source {
 public:
  std::string name() const override { return "bench"; }
  nd::StreamInfo info() const override {
    nd::StreamInfo i;
    i.epoch_utime = 1'700'000'000'000'000;
    i.mic_count = 2;
    i.mic_full_scale_pa = 1.0;
    i.pressure_edges_per_rev = 3600;
    return i;
  }
  void start(const nd::Streams& s) override { mics_given = s.mics; }
  void stop() override {}
  bool running() const override { return true; }
  std::vector<nd::DriverThreadStatus> thread_status() const override {
    return {{"bench.pressure", nd::ThreadState::kRunning, 0, ""}};
  }
  const nd::BlockRing* mics_given = nullptr;
};

}  // namespace

// Microphones on capture channels 2 and 0 of a four-channel 24-bit interface at 48 kHz, 50 and 20 mV/Pa behind
// 2 V of full scale, composed with a pressure source: the 40 kHz stream carries each microphone's tone at the level
// in Pa the bytes and the chain make, and the composed source reports the interface's microphones, the pressure
// source's epoch and encoder, and both sources' threads.
TEST(AlsaSource, MappedChannelsArriveInPascalAt40kHzBesideAnotherSourcesPressure) {
  const std::vector<CaptureTone> tones = {{0.25, 2000.0}, {0.9, 500.0}, {0.5, 1000.0}, {0.1, 7000.0}};
  const std::string raw = write_raw("mics.raw", na::SampleFormat::kS24Packed, 48000, tones, 48000);
  na::AlsaSourceConfig a;
  a.capture = {.pcm = "nm_test",
               .config_file = write_asoundrc(raw),
               .rate_hz = 48000,
               .channels = 4,
               .format = "S24_3LE",
               .period_frames = 480,
               .periods = 4};
  a.channels = {2, 0};
  a.sensitivity_mv_per_pa = {50.0, 20.0};
  a.full_scale_v = 2.0;
  auto pressure = std::make_unique<PressureOnly>();
  const PressureOnly* bench = pressure.get();
  auto composed = nd::compose_microphones(std::move(pressure), na::make_alsa_source(a));
  const nd::StreamInfo info = composed->info();
  EXPECT_EQ(composed->name(), "bench+alsa");
  EXPECT_EQ(info.epoch_utime, 1'700'000'000'000'000);
  EXPECT_EQ(info.pressure_edges_per_rev, 3600);
  EXPECT_EQ(info.mic_count, 2u);
  EXPECT_EQ(info.mic_positions_m.size(), 2u);
  EXPECT_DOUBLE_EQ(info.mic_full_scale_pa, 0.0);  // the two chains' full scales differ (40 and 100 Pa)
  EXPECT_NEAR(info.acoustic_delay_s, 1.75 / 343.0, 1e-12);

  nd::BlockRing pressure_ring(4), mics(4096), angle(4);
  nd::OperatingPointRing ops(4);
  composed->start(nd::Streams{&pressure_ring, &mics, &ops, &angle});
  EXPECT_NE(bench->mics_given, &mics);  // its own microphones go elsewhere
  std::vector<double> v;
  auto block = std::make_unique<nd::SampleBlock>();
  for (int waits = 0; v.size() < 30000u * 2 && waits < 20000; ++waits) {
    while (mics.read(block.get(), 1) == 1)
      v.insert(v.end(), block->data, block->data + static_cast<std::size_t>(block->frames) * block->channels);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const auto threads = composed->thread_status();
  composed->stop();
  ASSERT_GE(v.size(), 30000u * 2);
  // 0.5 FS * 2 V / 50 mV/Pa = 20 Pa at 1 kHz; 0.25 FS * 2 V / 20 mV/Pa = 25 Pa at 2 kHz.
  EXPECT_NEAR(amplitude_at(v, 2, 0, 1000.0, 2000, 30000), 20.0, 0.02);
  EXPECT_NEAR(amplitude_at(v, 2, 1, 2000.0, 2000, 30000), 25.0, 0.025);
  // A frequency off by the ratio 48/40 (a resampling ratio taken the wrong way) leaves nothing at the tone.
  EXPECT_LT(amplitude_at(v, 2, 0, 1200.0, 2000, 30000), 0.2);
  ASSERT_EQ(threads.size(), 2u);
  EXPECT_EQ(threads[0].name, "bench.pressure");
  EXPECT_EQ(threads[1].name, "alsa.microphones");
}

TEST(AlsaCapture, ErrorsNameThePcmTheFileAndWhatTheDeviceOffers) {
  auto message = [](const na::CaptureConfig& c) {
    try {
      na::Capture capture(c);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string raw = write_raw("short.raw", na::SampleFormat::kS16, 44100, {{0.1, 100.0}}, 100);
  na::CaptureConfig c{
      .pcm = "nm_no_such_pcm", .config_file = write_asoundrc(raw), .rate_hz = 48000, .channels = 1, .format = ""};
  EXPECT_NE(message(c).find("'nm_no_such_pcm'"), std::string::npos) << message(c);

  c.config_file = noisemon::test::unique_temp("missing.asoundrc").string();
  c.pcm = "nm_test";
  EXPECT_NE(message(c).find(c.config_file), std::string::npos) << message(c);

  const std::string broken = noisemon::test::unique_temp("broken.asoundrc").string();
  std::ofstream(broken) << "pcm.nm_test { type file slave.pcm \"null\"\n";  // unclosed brace
  c.config_file = broken;
  EXPECT_NE(message(c).find(broken), std::string::npos) << message(c);

  c.config_file = write_asoundrc(raw, "S16_LE", 44100);  // the slave runs at 44.1 kHz, no resampling
  const std::string rate = message(c);
  EXPECT_NE(rate.find("48000 Hz"), std::string::npos) << rate;
  EXPECT_NE(rate.find("44100..44100"), std::string::npos) << rate;

  c.pcm = "hw:97";
  c.config_file.clear();
  EXPECT_NE(message(c).find("'hw:97'"), std::string::npos) << message(c);
}

TEST(AlsaSource, AConfigurationThatCannotWorkIsRefusedNamingTheField) {
  auto message = [](const na::AlsaSourceConfig& a) {
    try {
      na::make_alsa_source(a);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    } catch (const std::exception& e) {
      return std::string("other error: ") + e.what();
    }
    return std::string("no error");
  };
  const std::string raw = write_raw("cfg.raw", na::SampleFormat::kS16, 48000, {{0.1, 100.0}}, 100);
  na::AlsaSourceConfig a;
  a.capture = {.pcm = "nm_test", .config_file = write_asoundrc(raw), .rate_hz = 48000, .channels = 2, .format = ""};
  a.channels = {0, 3};
  a.sensitivity_mv_per_pa = {50.0, 50.0};
  EXPECT_NE(message(a).find("alsa.capture_channels"), std::string::npos) << message(a);
  a.capture.channels = 4;
  a.sensitivity_mv_per_pa = {50.0};
  EXPECT_NE(message(a).find("alsa.sensitivity_mv_per_pa"), std::string::npos) << message(a);
  a.sensitivity_mv_per_pa = {50.0, -1.0};
  EXPECT_NE(message(a).find("alsa.sensitivity_mv_per_pa"), std::string::npos) << message(a);
  a.sensitivity_mv_per_pa = {50.0, 50.0};
  a.channels = {0, 40};
  EXPECT_NE(message(a).find("alsa.channels"), std::string::npos) << message(a);
  a.channels = {0, 3};
  a.sync_channel = 3;  // a microphone's channel cannot carry the sync pulse
  EXPECT_NE(message(a).find("alsa.sync_channel"), std::string::npos) << message(a);
  a.sync_channel = 2;
  a.sync_angle_deg = NAN;
  EXPECT_NE(message(a).find("alsa.sync_angle_deg"), std::string::npos) << message(a);
}

namespace {

// An asoundrc defining pcm.nm_timed, the tests' virtual interface on a clock of its own (alsa_timed_device.c).
std::string timed_asoundrc(const std::string& fields) {
  const std::string path = noisemon::test::unique_temp("timed.asoundrc").string();
  std::ofstream(path) << "pcm_type.nmtimed { lib \"" NOISEMON_ALSA_TIMED_DEVICE "\" }\n"
                      << "pcm.nm_timed { type nmtimed " << fields << " }\n";
  return path;
}

// The virtual interface at 48 kHz, two channels and the device fields given, read 480 frames at a time with a
// buffer of `periods` periods.
na::CaptureConfig timed_capture(const std::string& fields, unsigned periods) {
  return {.pcm = "nm_timed",
          .config_file = timed_asoundrc("rate 48000 channels 2 " + fields),
          .rate_hz = 48000,
          .channels = 2,
          .format = "",
          .period_frames = 480,
          .periods = periods};
}

using noisemon::test::counter;

}  // namespace

// The interface's buffer overflows once (the driver thread missed its turn): the overrun is counted, capture
// starts again on the host clock, the 40 kHz stream has a gap there (the cycles across it are dropped downstream)
// and carries the tone again after it. The buffer holds 2 s, so a loaded machine adds no overrun of its own; if
// one did, it would be counted and leave its own gap.
TEST(AlsaSource, AnOverrunIsCountedAndSurvivedWithAGapInTheStream) {
  na::AlsaSourceConfig a;
  a.capture = timed_capture("tone_hz 1000 amplitude 0.5 xrun_at_frame 9600", 200);
  a.channels = {1};
  a.sensitivity_mv_per_pa = {50.0};
  a.full_scale_v = 1.0;  // 0.5 FS = 10 Pa
  auto src = na::make_alsa_source(a);
  nd::BlockRing mics(4096);
  src->start(mics, nd::wall_utime(), nullptr);
  std::vector<std::int64_t> first_index, end_index;  // of each block
  std::vector<double> values;
  auto block = std::make_unique<nd::SampleBlock>();
  for (int waits = 0; values.size() < 20000 && waits < 30000; ++waits) {
    while (mics.read(block.get(), 1) == 1) {
      first_index.push_back(block->first_index);
      end_index.push_back(block->first_index + block->frames);
      values.insert(values.end(), block->data, block->data + block->frames);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_EQ(src->thread_status().front().state, nd::ThreadState::kRunning);
  src->stop();
  const std::int64_t overruns = counter(*src, "alsa.mics.overruns");
  EXPECT_GE(overruns, 1);
  std::size_t gaps = 0, frames_before_gap = 0;
  for (std::size_t i = 1; i < first_index.size(); ++i)
    if (first_index[i] != end_index[i - 1]) {
      EXPECT_GT(first_index[i], end_index[i - 1]);  // forward, never overlapping
      if (gaps++ == 0)
        for (std::size_t j = 0; j < i; ++j)
          frames_before_gap += static_cast<std::size_t>(end_index[j] - first_index[j]);
    }
  EXPECT_EQ(static_cast<std::int64_t>(gaps), overruns);
  ASSERT_GT(values.size(), frames_before_gap + 4000) << "no tone after the overrun";
  double peak = 0;
  for (std::size_t k = frames_before_gap + 1000; k < values.size(); ++k) peak = std::max(peak, std::abs(values[k]));
  EXPECT_NEAR(peak, 10.0, 0.1);
}

// A sync pulse through alsa-lib's own path: the virtual interface runs 80 ppm fast and carries, on a spare channel, a
// pulse at each multiple of 20 ms of the wall clock (a 3000 rpm engine's once-per-revolution); the test posts those
// instants as the pipeline would post the crank's. The source locks to them and tracks the interface's rate.
TEST(AlsaSource, ASyncPulseOnASpareChannelLocksTheClockAndTracksTheDrift) {
  constexpr std::int64_t kPeriodUs = 20000;
  na::AlsaSourceConfig a;
  a.capture = timed_capture("ppm 80 sync_channel 1 sync_period_us 20000", 400);  // 4 s of buffer: no overrun
  a.channels = {0};
  a.sensitivity_mv_per_pa = {50.0};
  a.sync_channel = 1;
  a.sync_angle_deg = 0.0;
  auto src = na::make_alsa_source(a);
  const std::int64_t epoch = nd::wall_utime() / kPeriodUs * kPeriodUs;  // a pulse's instant
  nd::CrankReference reference(0.0);
  nd::BlockRing mics(4096);
  src->start(mics, epoch, &reference);
  auto block = std::make_unique<nd::SampleBlock>();
  std::int64_t posted = 0;  // pulses posted, from the epoch's
  const auto deadline = std::chrono::steady_clock::now() + noisemon::test::allowance(std::chrono::seconds(20));
  // Tracked for 3 s after the lock: the rate then known to about a ppm.
  std::optional<std::chrono::steady_clock::time_point> locked;
  while (std::chrono::steady_clock::now() < deadline) {
    while (mics.read(block.get(), 1) == 1) {
    }
    for (; epoch + posted * kPeriodUs < nd::wall_utime() - 30000; ++posted)
      reference.post(static_cast<double>(posted * kPeriodUs) * 1e-6);
    if (!locked && counter(*src, "alsa.mics.synced") == 1) locked = std::chrono::steady_clock::now();
    if (locked && std::chrono::steady_clock::now() - *locked > std::chrono::seconds(3)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(locked.has_value()) << "never locked; sync pulses rejected: "
                                  << counter(*src, "alsa.mics.sync_pulses_rejected");
  EXPECT_EQ(counter(*src, "alsa.mics.synced"), 1);
  RecordProperty("clock_ppb", std::to_string(counter(*src, "alsa.mics.clock_ppb")));
  RecordProperty("alignment_uncertainty_us", std::to_string(counter(*src, "alsa.mics.alignment_uncertainty_us")));
  EXPECT_NEAR(static_cast<double>(counter(*src, "alsa.mics.clock_ppb")), 80000.0, 5000.0);
  EXPECT_LE(counter(*src, "alsa.mics.alignment_uncertainty_us"), 25);  // within a 40 kHz sample
  EXPECT_EQ(counter(*src, "alsa.mics.sync_losses"), 0);
  src->stop();
}

TEST(AlsaCapture, ABusyInterfaceAndAFormatItLacksAreErrorsNamingIt) {
  const std::string lock = noisemon::test::unique_temp("card.lock").string();
  na::CaptureConfig c{.pcm = "nm_timed",
                      .config_file = timed_asoundrc("rate 48000 channels 2 busy_file \"" + lock + "\""),
                      .rate_hz = 48000,
                      .channels = 2,
                      .format = ""};
  na::Capture first(c);
  EXPECT_EQ(first.format(), na::SampleFormat::kS32);  // the only one it offers, chosen without being named
  try {
    na::Capture second(c);
    ADD_FAILURE() << "a second open of a held interface succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'nm_timed'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("busy"), std::string::npos) << e.what();
  }
  na::CaptureConfig s16 = c;
  s16.config_file = timed_asoundrc("rate 48000 channels 2");
  s16.format = "S16_LE";
  try {
    na::Capture capture(s16);
    ADD_FAILURE() << "S16_LE accepted from an S32_LE-only interface";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot capture S16_LE"), std::string::npos) << e.what();
  }
}

class AlsaRates : public ::testing::TestWithParam<unsigned> {};

// The interface's rate from 44.1 to 192 kHz: the resampling to 40 kHz keeps a 1 kHz tone's level (20 Pa of
// amplitude from 0.5 of full scale, 1 V and 25 mV/Pa) and frequency.
TEST_P(AlsaRates, AToneKeepsItsLevelAt40kHz) {
  const unsigned rate = GetParam();
  const std::string raw = write_raw("rate.raw", na::SampleFormat::kS32, rate, {{0.5, 1000.0}}, rate);
  na::AlsaSourceConfig a;
  a.capture = {.pcm = "nm_test",
               .config_file = write_asoundrc(raw),
               .rate_hz = rate,
               .channels = 1,
               .format = "S32_LE",
               .period_frames = 1024,
               .periods = 4};
  a.channels = {0};
  a.sensitivity_mv_per_pa = {25.0};
  a.full_scale_v = 1.0;
  auto src = na::make_alsa_source(a);
  nd::BlockRing mics(4096);
  src->start(mics, nd::wall_utime(), nullptr);
  std::vector<double> v;
  auto block = std::make_unique<nd::SampleBlock>();
  for (int waits = 0; v.size() < 30000 && waits < 20000; ++waits) {
    while (mics.read(block.get(), 1) == 1) v.insert(v.end(), block->data, block->data + block->frames);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  src->stop();
  ASSERT_GE(v.size(), 30000u);
  EXPECT_NEAR(amplitude_at(v, 1, 0, 1000.0, 2000, 30000), 20.0, 0.02) << rate;
}

INSTANTIATE_TEST_SUITE_P(FromCdToStudioRates, AlsaRates, ::testing::Values(44100u, 96000u, 192000u));
