// The programs the tests run: this tree's noisemon tool (or the one NOISEMON_TOOL_PATH names) and its daemon.
#pragma once

#include <string>

namespace noisemon::test {

inline const std::string kNoisemon = NOISEMON_TOOL;
inline const std::string kNoisemond = std::string(NOISEMON_BINARY_DIR) + "/daemon/noisemond";

}  // namespace noisemon::test
