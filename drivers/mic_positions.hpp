// Microphone positions a source reports when its configuration gives none.
#pragma once

#include <array>
#include <vector>

namespace noisemon::drivers {

// Thesis Table 3.1 microphone positions (x, y, z in m): ten on a hemisphere of r = 1.75 m over the reflecting floor,
// times `scale` (radius / 1.75 m for another hemisphere).
std::vector<std::array<double, 3>> thesis_mic_positions(double scale = 1.0);

}  // namespace noisemon::drivers
