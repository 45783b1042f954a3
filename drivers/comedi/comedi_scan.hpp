// Decoding of the byte stream a comedi streaming subdevice delivers through read() on its file descriptor.
//
// Pure (no libcomedi calls) so it can be fed from a pipe or a test buffer. Samples are host-endian, 2 bytes
// (sampl_t) or 4 bytes (lsampl_t, subdevice flag SDF_LSAMPL), one scan = one sample per channel in channel-list
// order. read() may split samples and scans anywhere; the decoder keeps the partial scan between feeds.
// Conversion: raw -> volts with the card's calibration (comedi_to_phys linear range or comedi_to_physical
// polynomial), then volts -> SI (Pa) with the sensor chain's sensitivity, less the chain's zero offset (SI).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "drivers/source.hpp"

namespace noisemon::drivers::comedi {

enum class SampleWidth : std::uint8_t { k16Bit = 2, k32Bit = 4 };

// Sensor-chain sensitivities, returned as the factor from volts at the card input to Pa.
double microphone_pa_per_volt(double mv_per_pa);
double pressure_pa_per_volt(double mv_per_bar);
// Piezoelectric transducer (pC/bar) behind a charge amplifier whose gain is given in mV/pC.
double charge_pressure_pa_per_volt(double pc_per_bar, double amplifier_mv_per_pc);

// Raw sample -> SI for one channel.
struct ChannelConversion {
  static constexpr std::size_t kMaxCoefficients = 4;  // COMEDI_MAX_NUM_POLYNOMIAL_COEFFICIENTS
  enum class Kind : std::uint8_t { kLinear, kPolynomial };
  Kind kind = Kind::kLinear;
  // Hard calibration (comedi_range + maxdata).
  double range_min = 0.0;
  double range_max = 0.0;
  double maxdata = 1.0;
  // Soft calibration (comedi_polynomial_t): sum_i c[i] * (raw - origin)^i, i = 0..order.
  std::array<double, kMaxCoefficients> coefficients{};
  double expansion_origin = 0.0;
  unsigned order = 0;
  double si_per_volt = 1.0;
  // The chain's zero error, SI, subtracted after the conversion (a voltage-output pressure chain's offset_bar:
  // what it reads above the reference at ambient).
  double si_offset = 0.0;

  double to_volts(std::uint32_t raw) const {
    const double x = static_cast<double>(raw);
    if (kind == Kind::kLinear) return range_min + x * (range_max - range_min) / maxdata;
    const double dx = x - expansion_origin;
    double sum = 0.0;
    for (unsigned i = order + 1; i-- > 0;) sum = sum * dx + coefficients[i];  // Horner
    return sum;
  }
  double to_si(std::uint32_t raw) const { return to_volts(raw) * si_per_volt - si_offset; }
};

ChannelConversion linear_conversion(double range_min, double range_max, std::uint32_t maxdata, double si_per_volt,
                                    double si_offset = 0.0);
ChannelConversion polynomial_conversion(const double* coefficients, unsigned order, double expansion_origin,
                                        double si_per_volt, double si_offset = 0.0);

class ScanDecoder {
 public:
  static constexpr std::size_t kMaxChannels = SampleBlock::kMaxChannels;

  // Throws std::invalid_argument for 0 or more than kMaxChannels channels.
  ScanDecoder(SampleWidth width, std::vector<ChannelConversion> channels);

  std::size_t channels() const { return channels_.size(); }
  std::size_t scan_bytes() const { return scan_bytes_; }
  std::size_t pending_bytes() const { return pending_size_; }
  // Drops a partial scan (after an acquisition restart the card starts again at a scan boundary).
  void reset() { pending_size_ = 0; }

  // Decodes every scan completed by these bytes; sink(const double* values) gets channels() values in SI.
  // No allocation.
  template <class Sink>
  void feed(const std::byte* data, std::size_t size, Sink&& sink) {
    if (pending_size_ > 0) {
      const std::size_t take = std::min(size, scan_bytes_ - pending_size_);
      std::memcpy(pending_.data() + pending_size_, data, take);
      pending_size_ += take;
      data += take;
      size -= take;
      if (pending_size_ < scan_bytes_) return;
      decode_scan(pending_.data());
      sink(static_cast<const double*>(values_.data()));
      pending_size_ = 0;
    }
    while (size >= scan_bytes_) {
      decode_scan(data);
      sink(static_cast<const double*>(values_.data()));
      data += scan_bytes_;
      size -= scan_bytes_;
    }
    std::memcpy(pending_.data(), data, size);
    pending_size_ = size;
  }

 private:
  void decode_scan(const std::byte* scan);

  SampleWidth width_;
  std::vector<ChannelConversion> channels_;
  std::size_t scan_bytes_;
  std::array<std::byte, kMaxChannels * 4> pending_{};
  std::size_t pending_size_ = 0;
  std::array<double, kMaxChannels> values_{};
};

}  // namespace noisemon::drivers::comedi
