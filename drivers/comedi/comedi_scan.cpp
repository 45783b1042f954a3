#include "drivers/comedi/comedi_scan.hpp"

#include <stdexcept>
#include <string>

namespace noisemon::drivers::comedi {

namespace {
void require_positive(double value, const char* what) {
  if (!(value > 0.0)) throw std::invalid_argument(std::string(what) + " must be positive");
}
}  // namespace

double microphone_pa_per_volt(double mv_per_pa) {
  require_positive(mv_per_pa, "microphone sensitivity (mV/Pa)");
  return 1.0 / (mv_per_pa * 1e-3);
}

double pressure_pa_per_volt(double mv_per_bar) {
  require_positive(mv_per_bar, "pressure sensitivity (mV/bar)");
  return 1e5 / (mv_per_bar * 1e-3);
}

double charge_pressure_pa_per_volt(double pc_per_bar, double amplifier_mv_per_pc) {
  require_positive(pc_per_bar, "pressure sensitivity (pC/bar)");
  require_positive(amplifier_mv_per_pc, "charge amplifier gain (mV/pC)");
  // V -> mV (1e3) -> pC (/gain) -> bar (/sensitivity) -> Pa (1e5).
  return 1e3 * 1e5 / (amplifier_mv_per_pc * pc_per_bar);
}

ChannelConversion linear_conversion(double range_min, double range_max, std::uint32_t maxdata, double si_per_volt,
                                    double si_offset) {
  if (maxdata == 0 || !(range_max > range_min)) throw std::invalid_argument("invalid comedi range");
  ChannelConversion c;
  c.kind = ChannelConversion::Kind::kLinear;
  c.range_min = range_min;
  c.range_max = range_max;
  c.maxdata = static_cast<double>(maxdata);
  c.si_per_volt = si_per_volt;
  c.si_offset = si_offset;
  return c;
}

ChannelConversion polynomial_conversion(const double* coefficients, unsigned order, double expansion_origin,
                                        double si_per_volt, double si_offset) {
  if (order >= ChannelConversion::kMaxCoefficients) throw std::invalid_argument("polynomial order too high");
  ChannelConversion c;
  c.kind = ChannelConversion::Kind::kPolynomial;
  for (unsigned i = 0; i <= order; ++i) c.coefficients[i] = coefficients[i];
  c.order = order;
  c.expansion_origin = expansion_origin;
  c.si_per_volt = si_per_volt;
  c.si_offset = si_offset;
  return c;
}

ScanDecoder::ScanDecoder(SampleWidth width, std::vector<ChannelConversion> channels)
    : width_(width), channels_(std::move(channels)), scan_bytes_(channels_.size() * static_cast<std::size_t>(width)) {
  if (channels_.empty() || channels_.size() > kMaxChannels)
    throw std::invalid_argument("comedi scan needs 1.." + std::to_string(kMaxChannels) + " channels");
}

void ScanDecoder::decode_scan(const std::byte* scan) {
  const std::size_t n = channels_.size();
  if (width_ == SampleWidth::k16Bit) {
    for (std::size_t c = 0; c < n; ++c) {
      std::uint16_t raw;
      std::memcpy(&raw, scan + 2 * c, 2);
      values_[c] = channels_[c].to_si(raw);
    }
  } else {
    for (std::size_t c = 0; c < n; ++c) {
      std::uint32_t raw;
      std::memcpy(&raw, scan + 4 * c, 4);
      values_[c] = channels_[c].to_si(raw);
    }
  }
}

}  // namespace noisemon::drivers::comedi
