#include "drivers/formats/number_field.hpp"

#include <charconv>
#include <cmath>
#include <system_error>

namespace noisemon::drivers::formats {

bool parse_number_field(std::string_view field, double& out, bool decimal_comma) {
  constexpr std::size_t kLongestNumber = 64;
  while (!field.empty() && (field.front() == ' ' || field.front() == '\t')) field.remove_prefix(1);
  while (!field.empty() && (field.back() == ' ' || field.back() == '\t')) field.remove_suffix(1);
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  if (field.empty() || field.size() > kLongestNumber) return false;
  char buf[kLongestNumber];
  if (decimal_comma) {
    for (std::size_t i = 0; i < field.size(); ++i) buf[i] = field[i] == ',' ? '.' : field[i];
    field = std::string_view(buf, field.size());
  }
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), out);
  return ec == std::errc() && end == field.data() + field.size() && std::isfinite(out);
}

}  // namespace noisemon::drivers::formats
