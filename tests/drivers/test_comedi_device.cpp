// Tests of the comedi device path that need no card: the open error on a missing device, the read loop's
// overrun/restart/backoff and end-of-stream handling (scripted fake reads and real closed descriptors), the
// command settling loop against scripted comedi_command_test behaviour, CR_PACK against comedi.h's
// documented bit layout (chan bits 0-15, range 16-23, aref 24-25), the wake-every-scan flag, and the sizing of
// the kernel buffer against scripted libcomedi buffer calls (and the start-up note on what it holds).
#include "drivers/comedi/comedi_device.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>

#include "drivers/comedi/comedi_source.hpp"

namespace nd = noisemon::drivers;

namespace {

// One scripted read() outcome: bytes to deliver, or an errno with -1, or 0 for EOF.
struct Step {
  ssize_t result;
  int err = 0;
};

nd::comedi::ReadFunction scripted(std::deque<Step>& steps) {
  return [&steps](int, void* buf, std::size_t size) -> ssize_t {
    if (steps.empty()) return 0;
    const Step s = steps.front();
    steps.pop_front();
    if (s.result < 0) {
      errno = s.err;
      return -1;
    }
    const auto n = std::min<std::size_t>(static_cast<std::size_t>(s.result), size);
    std::memset(buf, 0x5a, n);
    return static_cast<ssize_t>(n);
  };
}

nd::comedi::ReadLoopConfig test_config() {
  nd::comedi::ReadLoopConfig c;
  c.device_path = "/dev/comedi7";
  c.subdevice = 3;
  c.initial_backoff = std::chrono::microseconds(1000);
  c.max_backoff = std::chrono::microseconds(4000);
  c.max_consecutive_overruns = 3;
  return c;
}

}  // namespace

TEST(ComediDevice, MissingDeviceErrorNamesPath) {
  const std::string path = "/dev/comedi0";
  struct stat st {};
  if (stat(path.c_str(), &st) == 0) GTEST_SKIP() << path << " exists on this machine";
  nd::comedi::ComediAcquisitionConfig cfg;
  cfg.device_path = path;
  cfg.channels = {{.channel = 0, .range = 0, .aref = AREF_GROUND, .si_per_volt = 1.0}};
  try {
    nd::comedi::ComediDevice dev(cfg);
    FAIL() << "opening a missing device succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(ComediReadLoop, OverrunRestartsAndCounts) {
  std::deque<Step> steps{{100}, {-1, EPIPE}, {40}, {-1, EINTR}, {60}, {0}};
  std::vector<std::size_t> chunks;
  int restarts = 0;
  std::array<std::byte, 256> buffer{};
  std::atomic<bool> stop{false};
  const auto r = nd::comedi::run_read_loop(
      -1, buffer, [&](const std::byte*, std::size_t n) { chunks.push_back(n); }, [&] { return ++restarts, true; }, stop,
      test_config(), scripted(steps));
  EXPECT_FALSE(r.failed) << r.message;
  EXPECT_EQ(r.overruns, 1u);
  EXPECT_EQ(restarts, 1);
  EXPECT_EQ(r.bytes, 200u);
  EXPECT_EQ(chunks, (std::vector<std::size_t>{100, 40, 60}));
  EXPECT_NE(r.message.find("/dev/comedi7 subdevice 3"), std::string::npos) << r.message;
}

TEST(ComediReadLoop, ConsecutiveOverrunsBackOffThenGiveUp) {
  std::deque<Step> steps(10, Step{-1, EPIPE});
  int restarts = 0;
  std::array<std::byte, 64> buffer{};
  std::atomic<bool> stop{false};
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = nd::comedi::run_read_loop(
      -1, buffer, [](const std::byte*, std::size_t) {}, [&] { return ++restarts, true; }, stop, test_config(),
      scripted(steps));
  const auto elapsed = std::chrono::steady_clock::now() - t0;
  EXPECT_TRUE(r.failed);
  EXPECT_EQ(restarts, 3);                                    // max_consecutive_overruns
  EXPECT_EQ(r.overruns, 4u);                                 // the fourth overrun gives up
  EXPECT_GE(elapsed, std::chrono::milliseconds(1 + 2 + 4));  // backoff doubled each time
  EXPECT_NE(r.message.find("/dev/comedi7 subdevice 3"), std::string::npos) << r.message;
}

TEST(ComediReadLoop, FailedRestartEndsWithError) {
  std::deque<Step> steps{{-1, EPIPE}};
  std::array<std::byte, 64> buffer{};
  std::atomic<bool> stop{false};
  const auto r = nd::comedi::run_read_loop(
      -1, buffer, [](const std::byte*, std::size_t) {}, [] { return false; }, stop, test_config(), scripted(steps));
  EXPECT_TRUE(r.failed);
  EXPECT_EQ(r.overruns, 1u);
  EXPECT_NE(r.message.find("/dev/comedi7 subdevice 3"), std::string::npos) << r.message;
}

TEST(ComediReadLoop, ReadErrorOnRealDescriptorNamesDevice) {
  int fds[2];
  ASSERT_EQ(pipe2(fds, O_CLOEXEC), 0);
  // Reading the write end of a pipe fails with EBADF: a real read() error, not a scripted one.
  std::array<std::byte, 64> buffer{};
  std::atomic<bool> stop{false};
  int restarts = 0;
  const auto r = nd::comedi::run_read_loop(
      fds[1], buffer, [](const std::byte*, std::size_t) {}, [&] { return ++restarts, true; }, stop, test_config());
  close(fds[0]);
  close(fds[1]);
  EXPECT_TRUE(r.failed);
  EXPECT_EQ(restarts, 0);
  EXPECT_NE(r.message.find("/dev/comedi7 subdevice 3"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find(std::strerror(EBADF)), std::string::npos) << r.message;
}

TEST(ComediReadLoop, EofOfClosedPipeEndsCleanly) {
  int fds[2];
  ASSERT_EQ(pipe2(fds, O_CLOEXEC), 0);
  close(fds[1]);
  std::array<std::byte, 64> buffer{};
  std::atomic<bool> stop{false};
  const auto r = nd::comedi::run_read_loop(
      fds[0], buffer, [](const std::byte*, std::size_t) {}, [] { return true; }, stop, test_config());
  close(fds[0]);
  EXPECT_FALSE(r.failed);
  EXPECT_EQ(r.bytes, 0u);
  EXPECT_NE(r.message.find("end of stream on /dev/comedi7 subdevice 3"), std::string::npos) << r.message;
}

TEST(ComediReadLoop, StopRequestedEndsBeforeReading) {
  std::deque<Step> steps{{10}};
  std::array<std::byte, 64> buffer{};
  std::atomic<bool> stop{true};
  const auto r = nd::comedi::run_read_loop(
      -1, buffer, [](const std::byte*, std::size_t) {}, [] { return true; }, stop, test_config(), scripted(steps));
  EXPECT_FALSE(r.failed);
  EXPECT_EQ(steps.size(), 1u);
}

TEST(ComediCommand, ChannelListUsesCrPackLayout) {
  const auto list = nd::comedi::pack_channel_list(
      {{.channel = 5, .range = 2, .aref = AREF_DIFF}, {.channel = 0, .range = 0, .aref = AREF_GROUND}});
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0], 5u | (2u << 16) | (static_cast<unsigned>(AREF_DIFF) << 24));
  EXPECT_EQ(list[1], static_cast<unsigned>(AREF_GROUND) << 24);
}

TEST(ComediCommand, ExternalScanClock) {
  unsigned chanlist[2] = {1, 2};
  const comedi_cmd cmd = nd::comedi::external_scan_command(4, 1, chanlist, 2);
  EXPECT_EQ(cmd.subdev, 4u);
  EXPECT_EQ(cmd.start_src, static_cast<unsigned>(TRIG_NOW));
  EXPECT_EQ(cmd.scan_begin_src, static_cast<unsigned>(TRIG_EXT));
  EXPECT_EQ(cmd.scan_begin_arg, 1u);
  EXPECT_EQ(cmd.scan_end_src, static_cast<unsigned>(TRIG_COUNT));
  EXPECT_EQ(cmd.scan_end_arg, 2u);
  EXPECT_EQ(cmd.stop_src, static_cast<unsigned>(TRIG_NONE));
  EXPECT_EQ(cmd.chanlist, chanlist);
  EXPECT_EQ(cmd.chanlist_len, 2u);
}

TEST(ComediCommand, SettlesAdjustedArguments) {
  unsigned chanlist[1] = {0};
  comedi_cmd cmd = nd::comedi::external_scan_command(0, 0, chanlist, 1);
  int calls = 0;
  // Like a driver: raise convert_arg to its 2000 ns minimum (return 3), then accept.
  nd::comedi::settle_command(
      cmd,
      [&](comedi_cmd& c) {
        ++calls;
        if (c.convert_arg < 2000) {
          c.convert_arg = 2000;
          return 3;
        }
        return 0;
      },
      "/dev/comedi7", 3);
  EXPECT_EQ(calls, 2);
  EXPECT_EQ(cmd.convert_arg, 2000u);
}

TEST(ComediCommand, UnsettledFieldIsNamed) {
  unsigned chanlist[1] = {0};
  comedi_cmd cmd = nd::comedi::external_scan_command(0, 0, chanlist, 1);
  int calls = 0;
  auto oscillating = [&](comedi_cmd& c) {
    ++calls;
    c.scan_begin_arg ^= 1u;
    return 4;
  };
  try {
    nd::comedi::settle_command(cmd, oscillating, "/dev/comedi7", 3);
    FAIL() << "an oscillating command settled";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("scan_begin_arg"), std::string::npos) << what;
    EXPECT_EQ(what.find("convert_arg"), std::string::npos) << what;
    EXPECT_NE(what.find("/dev/comedi7 subdevice 3"), std::string::npos) << what;
  }
  EXPECT_EQ(calls, 5);

  // An unsupported source the driver cannot fix names the stage.
  try {
    nd::comedi::settle_command(
        cmd, [](comedi_cmd&) { return 1; }, "/dev/comedi7", 3);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("trigger sources"), std::string::npos) << e.what();
  }
  // A failing test reports errno.
  EXPECT_THROW(nd::comedi::settle_command(
                   cmd,
                   [](comedi_cmd&) {
                     errno = EINVAL;
                     return -1;
                   },
                   "/dev/comedi7", 3),
               std::runtime_error);
}

TEST(ComediCommand, WakeEveryScanSetsOnlyCmdfWakeEos) {
  unsigned chanlist[1] = {0};
  comedi_cmd cmd = nd::comedi::external_scan_command(0, 0, chanlist, 1);
  EXPECT_EQ(cmd.flags & CMDF_WAKE_EOS, 0u);  // default: the kernel wakes the reader per block
  cmd.flags = CMDF_PRIORITY;
  nd::comedi::apply_wake_flag(cmd, true);
  EXPECT_EQ(cmd.flags, static_cast<unsigned>(CMDF_PRIORITY | CMDF_WAKE_EOS));
  nd::comedi::apply_wake_flag(cmd, true);  // idempotent
  EXPECT_EQ(cmd.flags, static_cast<unsigned>(CMDF_PRIORITY | CMDF_WAKE_EOS));
  nd::comedi::apply_wake_flag(cmd, false);
  EXPECT_EQ(cmd.flags, static_cast<unsigned>(CMDF_PRIORITY));
  EXPECT_EQ(CMDF_WAKE_EOS, TRIG_WAKE_EOS);  // the older name of the same bit
}

namespace {

// A subdevice's kernel buffer as libcomedi sees it: sizes round up to whole pages; raising the maximum can be
// refused (an unprivileged process).
struct FakeKernelBuffer {
  int size = 65536, max = 1 << 20;
  bool may_raise_max = true;
  int set_calls = 0, set_max_calls = 0;
  std::string order;
  static int pages(unsigned n) { return static_cast<int>((n + 4095) / 4096 * 4096); }
  nd::comedi::KernelBufferCalls calls() {
    return {.get_size = [this] { return size; },
            .get_max_size = [this] { return max; },
            .set_size =
                [this](unsigned n) {
                  ++set_calls;
                  order += "s";
                  return size = pages(n);
                },
            .set_max_size =
                [this](unsigned n) {
                  ++set_max_calls;
                  order += "m";
                  if (!may_raise_max) return errno = EPERM, -1;
                  return max = pages(n);
                },
            .error = [] { return std::string(std::strerror(EPERM)); }};
  }
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ComediBuffer, ZeroLeavesTheDriversBuffer) {
  FakeKernelBuffer k;
  EXPECT_EQ(nd::comedi::size_kernel_buffer(0, k.calls(), "/dev/comedi7", 3), 65536u);
  EXPECT_EQ(k.set_calls + k.set_max_calls, 0);
}

TEST(ComediBuffer, WithinTheLimitSetsTheSizeAndReportsWhatTheKernelGave) {
  FakeKernelBuffer k;
  EXPECT_EQ(nd::comedi::size_kernel_buffer(500000, k.calls(), "/dev/comedi7", 3), 503808u);  // 123 pages
  EXPECT_EQ(k.order, "s");
}

TEST(ComediBuffer, AboveTheLimitRaisesTheLimitFirst) {
  FakeKernelBuffer k;
  EXPECT_EQ(nd::comedi::size_kernel_buffer(4 << 20, k.calls(), "/dev/comedi7", 3), 4u << 20);
  EXPECT_EQ(k.order, "ms");
  EXPECT_EQ(k.max, 4 << 20);
}

TEST(ComediBuffer, RefusedLimitNamesDeviceSubdeviceSizeAndRoot) {
  FakeKernelBuffer k;
  k.may_raise_max = false;
  const std::string what = error_of([&] { nd::comedi::size_kernel_buffer(4 << 20, k.calls(), "/dev/comedi7", 3); });
  EXPECT_NE(what.find("/dev/comedi7 subdevice 3"), std::string::npos) << what;
  EXPECT_NE(what.find("4194304 bytes"), std::string::npos) << what;
  EXPECT_NE(what.find("buffer_bytes"), std::string::npos) << what;
  EXPECT_NE(what.find("needs root"), std::string::npos) << what;
  EXPECT_NE(what.find(std::strerror(EPERM)), std::string::npos) << what;
  EXPECT_EQ(k.set_calls, 0);  // the size is not attempted once the limit is refused
}

TEST(ComediBuffer, RefusedSizeNamesDeviceSubdeviceAndSize) {
  FakeKernelBuffer k;
  auto calls = k.calls();
  calls.set_size = [](unsigned) { return errno = EBUSY, -1; };  // e.g. a command running on the subdevice
  calls.error = [] { return std::string(std::strerror(EBUSY)); };
  const std::string what = error_of([&] { nd::comedi::size_kernel_buffer(1 << 20, calls, "/dev/comedi7", 3); });
  EXPECT_NE(what.find("cannot set the kernel buffer of /dev/comedi7 subdevice 3 to 1048576 bytes"), std::string::npos)
      << what;
  EXPECT_NE(what.find(std::strerror(EBUSY)), std::string::npos) << what;
}

TEST(ComediBuffer, SecondsHeldAtTheScanRate) {
  // 1 MiB of ten 16-bit microphone channels at 50 kHz: 1048576 / (20 x 50000) s.
  EXPECT_DOUBLE_EQ(nd::comedi::buffer_seconds(1 << 20, 20, 50000.0), 1.048576);
  EXPECT_EQ(nd::comedi::buffer_seconds(1 << 20, 20, 0.0), 0.0);
  EXPECT_EQ(nd::comedi::buffer_seconds(1 << 20, 0, 50000.0), 0.0);
  // Edge-clocked: the edge rate at max_rpm, else the most the resampler accepts.
  nd::comedi::ComediSourceConfig::Encoder e;
  e.counts_per_rev = 3600;
  e.max_rpm = 4000;
  EXPECT_DOUBLE_EQ(nd::comedi::edge_scan_rate_hz(e), 240000.0);
  e.counts_per_edge = 4;
  EXPECT_DOUBLE_EQ(nd::comedi::edge_scan_rate_hz(e), 60000.0);
  e.max_rpm = 0;
  EXPECT_DOUBLE_EQ(nd::comedi::edge_scan_rate_hz(e), 600000.0);
}

namespace {

// Only what buffer_note reads: where, sample width, channel count and the kernel buffer's size.
class NoteAcquisition final : public nd::comedi::Acquisition {
 public:
  std::string where() const override { return "/dev/comedi7 subdevice 3"; }
  int fd() const override { return -1; }
  nd::comedi::SampleWidth sample_width() const override { return nd::comedi::SampleWidth::k16Bit; }
  const std::vector<nd::comedi::ChannelConversion>& conversions() const override { return conversions_; }
  double scan_period_s() const override { return 2e-5; }
  void start() override {}
  bool restart() override { return true; }
  void cancel() override {}
  std::int64_t origin_utime() const override { return 0; }
  unsigned buffer_bytes() const override { return 1 << 20; }

 private:
  std::vector<nd::comedi::ChannelConversion> conversions_ = std::vector<nd::comedi::ChannelConversion>(10);
};

}  // namespace

TEST(ComediBuffer, StartUpNoteStatesSizeRateAndSeconds) {
  const NoteAcquisition a;
  nd::comedi::ComediAcquisitionConfig c;
  c.buffer_bytes = 1000000;
  c.wake_every_scan = true;
  const std::string note = nd::comedi::buffer_note(a, c, 50000.0, "the card's settled scan rate");
  for (const char* part : {"/dev/comedi7 subdevice 3", "kernel buffer 1048576 bytes", "buffer_bytes = 1000000",
                           "holds 1.05 s", "20-byte scans", "50000 scans/s", "every scan"})
    EXPECT_NE(note.find(part), std::string::npos) << part << " in: " << note;
  c.buffer_bytes = 0;
  c.wake_every_scan = false;
  const std::string driver = nd::comedi::buffer_note(a, c, 50000.0, "x");
  EXPECT_NE(driver.find("the driver's"), std::string::npos) << driver;
  EXPECT_NE(driver.find("per block"), std::string::npos) << driver;
}
