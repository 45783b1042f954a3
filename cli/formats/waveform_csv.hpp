// Input/output waveforms for waveform-mode fitting and diagnosis: a two-column `u,y` text file, one sample
// per line, uniformly sampled (the rate is given separately, e.g. `--fs`).
//
// Accepted: an optional header line (the first non-empty line, when it is not two numbers, e.g. `u,y`);
// columns separated by a comma, a tab or spaces (the first data line sets which, every row must agree);
// CRLF line ends; empty lines and lines starting with '#'. Everything else is an error naming the file, the
// line and what was expected: a row with other than two fields, a field that is not a finite number.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace noisemon::cli::formats {

struct Waveform {
  std::vector<double> u;  // input, one per sample
  std::vector<double> y;  // output, same length
  std::string header;     // the header line as read ("" when there was none)
};

struct WaveformCsvError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// `file` is the name used in messages.
Waveform parse_waveform_csv(std::string_view text, const std::string& file);
// Throws WaveformCsvError naming the file when it cannot be read or holds no data row.
Waveform read_waveform_csv(const std::string& path);

}  // namespace noisemon::cli::formats
