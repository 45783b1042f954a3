// A driver counter by name, as every source test reads them.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "drivers/source.hpp"

namespace noisemon::test {

// The value of the counter `name`; -1, and a failure of the test, when there is none.
inline std::int64_t counter(const std::vector<drivers::DriverCounter>& counters, const std::string& name) {
  for (const drivers::DriverCounter& c : counters)
    if (c.name == name) return c.value;
  ADD_FAILURE() << "no counter " << name;
  return -1;
}
inline std::int64_t counter(const drivers::SourceBase& source, const std::string& name) {
  return counter(source.counters(), name);
}

}  // namespace noisemon::test
