#include "drivers/comedi/comedi_device.hpp"

#include <poll.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <thread>

namespace noisemon::drivers::comedi {

namespace {

std::string where(const std::string& device_path, unsigned subdevice) {
  return device_path + " subdevice " + std::to_string(subdevice);
}

std::string comedi_error() { return comedi_strerror(comedi_errno()); }

// Overrun bookkeeping shared by the read loops: count, back off (doubling per consecutive overrun), re-arm.
class OverrunRecovery {
 public:
  explicit OverrunRecovery(const ReadLoopConfig& config) : config_(config), backoff_(config.initial_backoff) {}
  void on_data() {
    consecutive_ = 0;
    backoff_ = config_.initial_backoff;
  }
  // After an EPIPE: false (with result.failed and message set) when acquisition cannot go on.
  bool recover(ReadLoopResult& result, const std::string& name, const std::function<bool()>& restart) {
    ++result.overruns;
    if (++consecutive_ > config_.max_consecutive_overruns) {
      result.failed = true;
      result.message = "buffer overrun on " + name + ": gave up after " +
                       std::to_string(config_.max_consecutive_overruns) + " consecutive restarts";
      return false;
    }
    std::this_thread::sleep_for(backoff_);
    backoff_ = std::min(backoff_ * 2, config_.max_backoff);
    if (!restart()) {
      result.failed = true;
      result.message = "buffer overrun on " + name + ": restarting acquisition failed";
      return false;
    }
    return true;
  }

 private:
  const ReadLoopConfig& config_;
  std::chrono::microseconds backoff_;
  unsigned consecutive_ = 0;
};

}  // namespace

ReadLoopResult run_read_loop(int fd, std::span<std::byte> buffer,
                             const std::function<void(const std::byte*, std::size_t)>& on_bytes,
                             const std::function<bool()>& restart, const std::atomic<bool>& stop,
                             const ReadLoopConfig& config, const ReadFunction& read_fn) {
  ReadLoopResult result;
  const std::string name = where(config.device_path, config.subdevice);
  OverrunRecovery recovery(config);
  while (!stop.load(std::memory_order_relaxed)) {
    const ssize_t n = read_fn ? read_fn(fd, buffer.data(), buffer.size()) : ::read(fd, buffer.data(), buffer.size());
    if (n > 0) {
      result.bytes += static_cast<std::uint64_t>(n);
      on_bytes(buffer.data(), static_cast<std::size_t>(n));
      recovery.on_data();
      continue;
    }
    if (n == 0) {
      result.message = "end of stream on " + name;
      return result;
    }
    const int err = errno;
    if (err == EINTR) continue;
    if (err != EPIPE) {
      result.failed = true;
      result.message = "read error on " + name + ": " + std::strerror(err);
      return result;
    }
    // EPIPE: the card's buffer overran and comedi stopped the command; re-arm after a backoff.
    if (!recovery.recover(result, name, restart)) return result;
  }
  result.message = "stopped reading " + name;
  return result;
}

ReadLoopResult run_group_read_loop(std::span<ReadStream> streams, const std::function<void()>& after_pass,
                                   const std::function<bool()>& restart, const std::atomic<bool>& stop,
                                   const ReadLoopConfig& config, int poll_ms) {
  ReadLoopResult result;
  OverrunRecovery recovery(config);
  constexpr std::size_t kMaxStreams = 8;
  if (streams.empty() || streams.size() > kMaxStreams)
    throw std::invalid_argument("run_group_read_loop: 1.." + std::to_string(kMaxStreams) + " streams");
  std::array<bool, kMaxStreams> ended{};
  std::array<pollfd, kMaxStreams> pfd{};
  std::string names;
  for (const ReadStream& s : streams) names += (names.empty() ? "" : ", ") + s.where;
  while (!stop.load(std::memory_order_relaxed)) {
    std::size_t open = 0;
    for (std::size_t i = 0; i < streams.size(); ++i) {
      pfd[i] = {ended[i] ? -1 : streams[i].fd, POLLIN, 0};
      open += ended[i] ? 0 : 1;
    }
    if (open == 0) {
      result.message = "end of stream on " + names;
      return result;
    }
    const int ready = ::poll(pfd.data(), streams.size(), poll_ms);
    if (ready < 0) {
      if (errno == EINTR) continue;
      result.failed = true;
      result.message = "poll error on " + names + ": " + std::strerror(errno);
      return result;
    }
    bool overrun = false;
    std::string overrun_name;
    for (std::size_t i = 0; i < streams.size() && !overrun; ++i) {
      if (ended[i] || pfd[i].revents == 0) continue;
      ReadStream& s = streams[i];
      const ssize_t n = s.read_fn ? s.read_fn(s.fd, s.buffer.data(), s.buffer.size())
                                  : ::read(s.fd, s.buffer.data(), s.buffer.size());
      if (n > 0) {
        result.bytes += static_cast<std::uint64_t>(n);
        s.on_bytes(s.buffer.data(), static_cast<std::size_t>(n));
        recovery.on_data();
      } else if (n == 0) {
        ended[i] = true;
      } else if (errno == EPIPE) {
        overrun = true;
        overrun_name = s.where;
      } else if (errno != EINTR && errno != EAGAIN) {
        result.failed = true;
        result.message = "read error on " + s.where + ": " + std::strerror(errno);
        return result;
      }
    }
    if (after_pass) after_pass();
    if (overrun) {
      // The whole group restarts together, so every member begins again at the same encoder edge.
      if (!recovery.recover(result, overrun_name, restart)) return result;
      ended.fill(false);
    }
  }
  result.message = "stopped reading " + names;
  return result;
}

std::vector<unsigned> pack_channel_list(const std::vector<ComediChannelConfig>& channels) {
  std::vector<unsigned> list;
  list.reserve(channels.size());
  for (const auto& c : channels) list.push_back(CR_PACK(c.channel, c.range, c.aref));
  return list;
}

comedi_cmd external_scan_command(unsigned subdevice, unsigned external_trigger, unsigned* chanlist,
                                 unsigned chanlist_len, int start_trigger, unsigned convert_src) {
  comedi_cmd cmd{};
  cmd.subdev = subdevice;
  cmd.start_src = start_trigger >= 0 ? TRIG_EXT : TRIG_NOW;
  cmd.start_arg = start_trigger >= 0 ? static_cast<unsigned>(start_trigger) : 0;
  cmd.scan_begin_src = TRIG_EXT;
  cmd.scan_begin_arg = external_trigger;
  cmd.convert_src = convert_src;
  cmd.convert_arg = 0;  // fastest; command_test raises it to the card's minimum
  cmd.scan_end_src = TRIG_COUNT;
  cmd.scan_end_arg = chanlist_len;
  cmd.stop_src = TRIG_NONE;
  cmd.stop_arg = 0;
  cmd.chanlist = chanlist;
  cmd.chanlist_len = chanlist_len;
  return cmd;
}

void apply_wake_flag(comedi_cmd& cmd, bool wake_every_scan) {
  if (wake_every_scan)
    cmd.flags |= CMDF_WAKE_EOS;
  else
    cmd.flags &= ~static_cast<unsigned>(CMDF_WAKE_EOS);
}

unsigned size_kernel_buffer(unsigned bytes, const KernelBufferCalls& calls, const std::string& device_path,
                            unsigned subdevice) {
  const std::string name = where(device_path, subdevice);
  auto fail = [&](const std::string& what) { throw std::runtime_error(what + ": " + calls.error()); };
  if (bytes > 0) {
    const std::string size = std::to_string(bytes) + " bytes (buffer_bytes)";
    const int max = calls.get_max_size();
    if (max < 0) fail("cannot read the kernel buffer limit of " + name);
    if (bytes > static_cast<unsigned>(max) && calls.set_max_size(bytes) < 0)
      fail("cannot raise the kernel buffer limit of " + name + " from " + std::to_string(max) + " to " + size +
           ": raising it needs root (CAP_SYS_ADMIN)");
    if (calls.set_size(bytes) < 0) fail("cannot set the kernel buffer of " + name + " to " + size);
  }
  const int got = calls.get_size();
  if (got < 0) fail("cannot read the kernel buffer size of " + name);
  return static_cast<unsigned>(got);
}

double buffer_seconds(std::size_t buffer_bytes, std::size_t scan_bytes, double scan_rate_hz) {
  if (scan_bytes == 0 || !(scan_rate_hz > 0.0)) return 0.0;
  return static_cast<double>(buffer_bytes) / (static_cast<double>(scan_bytes) * scan_rate_hz);
}

void settle_command(comedi_cmd& cmd, const std::function<int(comedi_cmd&)>& test, const std::string& device_path,
                    unsigned subdevice, int max_passes) {
  // comedi_command_test return codes: 1 unsupported trigger source, 2 incompatible sources, 3 argument out of
  // range, 4 argument adjusted, 5 channel list rejected. It fixes what it can, so repeating usually settles.
  std::string unsettled;
  for (int pass = 0; pass < max_passes; ++pass) {
    const comedi_cmd before = cmd;
    const int r = test(cmd);
    if (r == 0) return;
    if (r < 0)
      throw std::runtime_error("comedi_command_test failed on " + where(device_path, subdevice) + ": " +
                               std::strerror(errno));
    unsettled.clear();
    auto note = [&](bool changed, const char* field) {
      if (changed) unsettled += (unsettled.empty() ? "" : ", ") + std::string(field);
    };
    note(before.start_src != cmd.start_src, "start_src");
    note(before.start_arg != cmd.start_arg, "start_arg");
    note(before.scan_begin_src != cmd.scan_begin_src, "scan_begin_src");
    note(before.scan_begin_arg != cmd.scan_begin_arg, "scan_begin_arg");
    note(before.convert_src != cmd.convert_src, "convert_src");
    note(before.convert_arg != cmd.convert_arg, "convert_arg");
    note(before.scan_end_src != cmd.scan_end_src, "scan_end_src");
    note(before.scan_end_arg != cmd.scan_end_arg, "scan_end_arg");
    note(before.stop_src != cmd.stop_src, "stop_src");
    note(before.stop_arg != cmd.stop_arg, "stop_arg");
    if (unsettled.empty()) {
      static const char* const kStage[] = {
          "", "trigger sources", "trigger source combination", "argument range", "adjusted arguments", "chanlist"};
      unsettled = (r >= 1 && r <= 5) ? kStage[r] : "unknown field";
    }
  }
  throw std::runtime_error("comedi command on " + where(device_path, subdevice) + " did not settle after " +
                           std::to_string(max_passes) + " passes: " + unsettled);
}

ComediDevice::ComediDevice(ComediAcquisitionConfig config) : config_(std::move(config)) {
  if (config_.channels.empty() || config_.channels.size() > ScanDecoder::kMaxChannels)
    throw std::invalid_argument("comedi acquisition on " + config_.device_path + " needs 1.." +
                                std::to_string(ScanDecoder::kMaxChannels) + " channels");
  dev_ = comedi_open(config_.device_path.c_str());
  if (!dev_) throw std::runtime_error("cannot open comedi device " + config_.device_path + ": " + comedi_error());
  try {
    const int sub = config_.subdevice >= 0 ? config_.subdevice : comedi_get_read_subdevice(dev_);
    if (sub < 0) throw std::runtime_error("comedi device " + config_.device_path + " has no streaming read subdevice");
    subdevice_ = static_cast<unsigned>(sub);
    const int flags = comedi_get_subdevice_flags(dev_, subdevice_);
    if (flags < 0)
      throw std::runtime_error("cannot query " + where(config_.device_path, subdevice_) + ": " + comedi_error());
    if (!(flags & SDF_CMD))
      throw std::runtime_error(where(config_.device_path, subdevice_) + " does not support streaming commands");
    width_ = (flags & SDF_LSAMPL) ? SampleWidth::k32Bit : SampleWidth::k16Bit;

    // Calibration: software polynomials when the card needs them and a calibration file exists, else the
    // hardware range.
    comedi_calibration_t* calibration = nullptr;
    if (config_.use_soft_calibration && (flags & SDF_SOFT_CALIBRATED)) {
      if (char* path = comedi_get_default_calibration_path(dev_)) {
        calibration = comedi_parse_calibration_file(path);
        std::free(path);
      }
    }
    for (const auto& ch : config_.channels) {
      if (ch.counter_mode >= 0 &&
          comedi_set_counter_mode(dev_, subdevice_, ch.channel, static_cast<unsigned>(ch.counter_mode)) < 0) {
        if (calibration) comedi_cleanup_calibration(calibration);
        throw std::runtime_error("cannot set counter mode " + std::to_string(ch.counter_mode) + " of channel " +
                                 std::to_string(ch.channel) + " on " + where(config_.device_path, subdevice_) + ": " +
                                 comedi_error());
      }
      if (ch.raw_counts) {
        const lsampl_t maxdata = comedi_get_maxdata(dev_, subdevice_, ch.channel);
        if (maxdata == 0) {
          if (calibration) comedi_cleanup_calibration(calibration);
          throw std::runtime_error("invalid counter channel " + std::to_string(ch.channel) + " on " +
                                   where(config_.device_path, subdevice_));
        }
        // Identity on the count: range [0, maxdata] over maxdata steps.
        conversions_.push_back(linear_conversion(0.0, static_cast<double>(maxdata), maxdata, 1.0));
        continue;
      }
      comedi_polynomial_t poly{};
      const bool soft = calibration && comedi_get_softcal_converter(subdevice_, ch.channel, ch.range,
                                                                    COMEDI_TO_PHYSICAL, calibration, &poly) == 0;
      if (soft) {
        conversions_.push_back(
            polynomial_conversion(poly.coefficients, poly.order, poly.expansion_origin, ch.si_per_volt, ch.si_offset));
        continue;
      }
      const comedi_range* range = comedi_get_range(dev_, subdevice_, ch.channel, ch.range);
      const lsampl_t maxdata = comedi_get_maxdata(dev_, subdevice_, ch.channel);
      if (!range || maxdata == 0) {
        if (calibration) comedi_cleanup_calibration(calibration);
        throw std::runtime_error("invalid channel " + std::to_string(ch.channel) + " range " +
                                 std::to_string(ch.range) + " on " + where(config_.device_path, subdevice_));
      }
      conversions_.push_back(linear_conversion(range->min, range->max, maxdata, ch.si_per_volt, ch.si_offset));
    }
    if (calibration) comedi_cleanup_calibration(calibration);
    chanlist_ = pack_channel_list(config_.channels);
    size_buffer();
  } catch (...) {
    comedi_close(dev_);
    throw;
  }
}

ComediDevice::~ComediDevice() {
  if (dev_) {
    comedi_cancel(dev_, subdevice_);
    comedi_close(dev_);
  }
}

int ComediDevice::fd() const { return comedi_fileno(dev_); }

void ComediDevice::size_buffer() {
  const KernelBufferCalls calls{
      .get_size = [this] { return comedi_get_buffer_size(dev_, subdevice_); },
      .get_max_size = [this] { return comedi_get_max_buffer_size(dev_, subdevice_); },
      .set_size = [this](unsigned n) { return comedi_set_buffer_size(dev_, subdevice_, n); },
      .set_max_size = [this](unsigned n) { return comedi_set_max_buffer_size(dev_, subdevice_, n); },
      .error = [] { return comedi_error(); }};
  buffer_bytes_ = size_kernel_buffer(config_.buffer_bytes, calls, config_.device_path, subdevice_);
}

void ComediDevice::build_command() {
  const auto n = static_cast<unsigned>(chanlist_.size());
  if (config_.clock == ScanClock::kTimed) {
    if (!(config_.scan_rate_hz > 0.0))
      throw std::invalid_argument("scan rate must be positive for " + where(config_.device_path, subdevice_));
    cmd_ = comedi_cmd{};
    const auto period_ns = static_cast<unsigned>(std::lround(1e9 / config_.scan_rate_hz));
    if (comedi_get_cmd_generic_timed(dev_, subdevice_, &cmd_, n, period_ns) < 0)
      throw std::runtime_error("comedi_get_cmd_generic_timed failed on " + where(config_.device_path, subdevice_) +
                               ": " + comedi_error());
    cmd_.chanlist = chanlist_.data();
    cmd_.chanlist_len = n;
    cmd_.stop_src = TRIG_NONE;  // continuous
    cmd_.stop_arg = 0;
  } else {
    cmd_ = external_scan_command(subdevice_, config_.external_trigger, chanlist_.data(), n, config_.start_trigger,
                                 config_.convert_src);
  }
  apply_wake_flag(cmd_, config_.wake_every_scan);
  settle_command(
      cmd_, [this](comedi_cmd& c) { return comedi_command_test(dev_, &c); }, config_.device_path, subdevice_);
  scan_period_s_ = cmd_.scan_begin_src == TRIG_TIMER ? cmd_.scan_begin_arg * 1e-9 : 0.0;
}

void ComediDevice::start() {
  build_command();
  if (comedi_command(dev_, &cmd_) < 0)
    throw std::runtime_error("comedi_command failed on " + where(config_.device_path, subdevice_) + ": " +
                             comedi_error());
}

bool ComediDevice::restart() {
  comedi_cancel(dev_, subdevice_);
  return comedi_command(dev_, &cmd_) >= 0;
}

void ComediDevice::cancel() { comedi_cancel(dev_, subdevice_); }

}  // namespace noisemon::drivers::comedi
