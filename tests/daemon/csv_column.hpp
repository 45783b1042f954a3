// Field `column` (0-based) of every data row of a comma-separated file with one header line (the replay and watch
// CSVs), for the tests that check what a column says.
#pragma once

#include <cstddef>
#include <istream>
#include <sstream>
#include <string>
#include <vector>

namespace noisemon::test {

inline std::vector<std::string> csv_column(std::istream& in, std::size_t column) {
  std::vector<std::string> out;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string field;
    for (std::size_t c = 0; c <= column; ++c) std::getline(row, field, ',');
    out.push_back(field);
  }
  return out;
}

}  // namespace noisemon::test
