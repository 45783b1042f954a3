// The one reader of a number in a text file's field (the pressure CSV, cycle tables, waveform CSV).
#pragma once

#include <string_view>

namespace noisemon::drivers::formats {

// A field as a finite number: blanks around it and a leading '+' allowed, nothing else. With decimal_comma,
// "0,969" reads as 0.969 (a European spreadsheet's export). False, `out` unspecified, for anything else.
[[nodiscard]] bool parse_number_field(std::string_view field, double& out, bool decimal_comma = false);

}  // namespace noisemon::drivers::formats
