// A comedi DAQ subdevice running a streaming command, and the read loop that drains its file descriptor.
//
// ComediDevice holds the libcomedi calls: open, check the subdevice can stream (SDF_CMD), read its sample
// width and calibration, build and settle the command, start/restart/cancel. The read loops are independent of
// libcomedi (fds, read functions and a restart callback) so the device path and tests share them.
#pragma once

#include <comedilib.h>
#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "drivers/comedi/comedi_scan.hpp"

namespace noisemon::drivers::comedi {

// ---- read loop -------------------------------------------------------------------------------------------

struct ReadLoopConfig {
  std::string device_path;                           // for messages only
  unsigned subdevice = 0;                            // for messages only
  std::chrono::microseconds initial_backoff{10000};  // wait before the first restart after an overrun
  std::chrono::microseconds max_backoff{1000000};    // backoff doubles per consecutive overrun up to this
  unsigned max_consecutive_overruns = 16;            // then give up (the card cannot be kept up with)
};

struct ReadLoopResult {
  bool failed = false;  // false: clean end (EOF or stop requested)
  std::uint64_t bytes = 0;
  std::uint64_t overruns = 0;  // EPIPE (comedi buffer overrun) occurrences
  std::string message;         // names device and subdevice
};

using ReadFunction = std::function<ssize_t(int fd, void* buffer, std::size_t size)>;

// Reads fd into buffer until EOF, error or stop, handing each chunk to on_bytes. EINTR is retried. EPIPE (the
// comedi buffer overran) counts an overrun, sleeps the backoff and calls restart (which must re-arm
// acquisition and return false if it cannot). Stop is checked between reads; a blocked read is unblocked by
// cancelling the command (read then returns EOF).
ReadLoopResult run_read_loop(int fd, std::span<std::byte> buffer,
                             const std::function<void(const std::byte*, std::size_t)>& on_bytes,
                             const std::function<bool()>& restart, const std::atomic<bool>& stop,
                             const ReadLoopConfig& config, const ReadFunction& read_fn = {});

// One descriptor of a group read together (e.g. the pressure input and the encoder counter, both clocked by
// the encoder edge, whose scans must pair up).
struct ReadStream {
  int fd = -1;
  std::span<std::byte> buffer;
  std::function<void(const std::byte*, std::size_t)> on_bytes;
  ReadFunction read_fn;  // empty: ::read
  std::string where;     // "device subdevice N", for messages
};

// Polls the group (poll_ms timeout, so stop is seen without a cancel), reads each ready descriptor once per
// pass and then calls after_pass (e.g. to deliver what the bytes completed). EPIPE on any member is one
// overrun of the group: count, back off as above, and restart() re-arms every member (the scans must pair up
// again). Ends at stop, on a read error (naming the member), or once every member reached end of stream.
// config.device_path/subdevice are unused here: each member names itself.
ReadLoopResult run_group_read_loop(std::span<ReadStream> streams, const std::function<void()>& after_pass,
                                   const std::function<bool()>& restart, const std::atomic<bool>& stop,
                                   const ReadLoopConfig& config, int poll_ms = 100);

// ---- command construction --------------------------------------------------------------------------------

enum class ScanClock : std::uint8_t {
  kTimed,     // card timer (microphones)
  kExternal,  // one scan per external trigger edge (encoder-clocked pressure)
};

struct ComediChannelConfig {
  unsigned channel = 0;
  unsigned range = 0;
  unsigned aref = AREF_GROUND;
  double si_per_volt = 1.0;  // from microphone_pa_per_volt / pressure_pa_per_volt / charge_pressure_pa_per_volt
  double si_offset = 0.0;    // SI subtracted after the conversion (the pressure chain's zero, offset_bar)
  bool raw_counts = false;   // counter channels: deliver the raw count (no range, no calibration)
  int counter_mode = -1;     // >= 0: comedi_set_counter_mode bits applied before the command (card-specific)
};

struct ComediAcquisitionConfig {
  std::string device_path = "/dev/comedi0";
  int subdevice = -1;  // -1: the device's default read subdevice
  std::vector<ComediChannelConfig> channels;
  ScanClock clock = ScanClock::kTimed;
  double scan_rate_hz = 51200.0;      // kTimed
  unsigned external_trigger = 0;      // kExternal: scan_begin_arg (trigger input number, driver-specific)
  int start_trigger = -1;             // kExternal: >= 0 starts on that external trigger (start_src TRIG_EXT)
  unsigned convert_src = TRIG_TIMER;  // kExternal: TRIG_TIMER (fastest the card allows), TRIG_NOW or TRIG_FOLLOW
  bool use_soft_calibration = true;   // when the subdevice is SDF_SOFT_CALIBRATED and a calibration file exists
  unsigned buffer_bytes = 0;          // > 0: size the kernel's acquisition buffer to this; 0: leave it as it is
  bool wake_every_scan = false;       // CMDF_WAKE_EOS: the kernel wakes the reader after every scan
};

// Channel list entries CR_PACK(channel, range, aref) in configuration order.
std::vector<unsigned> pack_channel_list(const std::vector<ComediChannelConfig>& channels);

// Fields of an externally clocked scan command: start now (or on external trigger start_trigger >= 0),
// scan_begin TRIG_EXT, conversions as fast as the card allows (convert TRIG_TIMER 0, raised by command_test;
// or convert_src TRIG_NOW / TRIG_FOLLOW), run until cancelled.
comedi_cmd external_scan_command(unsigned subdevice, unsigned external_trigger, unsigned* chanlist,
                                 unsigned chanlist_len, int start_trigger = -1, unsigned convert_src = TRIG_TIMER);

// Sets (or clears) CMDF_WAKE_EOS in cmd.flags: the kernel wakes a reader after every scan instead of per DMA
// block or FIFO interrupt (lowest latency to the driver thread, more interrupts and wake-ups).
void apply_wake_flag(comedi_cmd& cmd, bool wake_every_scan);

// The libcomedi calls that size a subdevice's kernel buffer (injected, so tests need no card).
struct KernelBufferCalls {
  std::function<int()> get_size, get_max_size;          // comedi_get_buffer_size / _max_buffer_size
  std::function<int(unsigned)> set_size, set_max_size;  // comedi_set_buffer_size / _max_buffer_size
  std::function<std::string()> error;                   // the last call's error text
};

// Sizes the kernel buffer to bytes (0: leaves it), raising the subdevice's maximum first when bytes exceeds it
// (that needs root, CAP_SYS_ADMIN). Returns the size the kernel reports afterwards (it rounds up to whole
// pages). Throws std::runtime_error naming the device, the subdevice and the size.
unsigned size_kernel_buffer(unsigned bytes, const KernelBufferCalls& calls, const std::string& device_path,
                            unsigned subdevice);

// How long a buffer of buffer_bytes holds scans of scan_bytes arriving at scan_rate_hz: the time the driver
// thread may stall before the card overruns. 0 when the rate or the scan size is not positive.
double buffer_seconds(std::size_t buffer_bytes, std::size_t scan_bytes, double scan_rate_hz);

// Runs test until it returns 0 (at most max_passes). Throws std::runtime_error naming the device, the
// subdevice and the command fields it could not settle, or the errno of a failing test.
void settle_command(comedi_cmd& cmd, const std::function<int(comedi_cmd&)>& test, const std::string& device_path,
                    unsigned subdevice, int max_passes = 5);

// ---- device --------------------------------------------------------------------------------------------------

class ComediDevice {
 public:
  // Opens the device, inspects the subdevice and sizes its kernel buffer (config.buffer_bytes); throws
  // std::runtime_error naming the device path on failure.
  explicit ComediDevice(ComediAcquisitionConfig config);
  ~ComediDevice();
  ComediDevice(const ComediDevice&) = delete;
  ComediDevice& operator=(const ComediDevice&) = delete;

  const std::string& device_path() const { return config_.device_path; }
  unsigned subdevice() const { return subdevice_; }
  SampleWidth sample_width() const { return width_; }
  // Raw -> SI per configured channel (calibration x sensor sensitivity), for a ScanDecoder.
  const std::vector<ChannelConversion>& conversions() const { return conversions_; }
  double scan_period_s() const { return scan_period_s_; }  // kTimed: the period the card settled on
  unsigned buffer_bytes() const { return buffer_bytes_; }  // the kernel buffer's size (what the kernel gave)
  int fd() const;

  void start();    // builds, settles and issues the command
  bool restart();  // cancel + re-issue (after an overrun); false on failure
  void cancel();   // stops acquisition; unblocks a pending read

 private:
  void build_command();
  void size_buffer();

  ComediAcquisitionConfig config_;
  comedi_t* dev_ = nullptr;
  unsigned subdevice_ = 0;
  SampleWidth width_ = SampleWidth::k16Bit;
  std::vector<ChannelConversion> conversions_;
  std::vector<unsigned> chanlist_;
  comedi_cmd cmd_{};
  double scan_period_s_ = 0.0;
  unsigned buffer_bytes_ = 0;
};

}  // namespace noisemon::drivers::comedi
