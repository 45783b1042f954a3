// The constants every layer's arithmetic names, declared once: a file's own copy would collide with another's when
// the build compiles several sources as one (CMake's unity build).
#pragma once

#include <limits>
#include <numbers>

namespace noisemon {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace noisemon
