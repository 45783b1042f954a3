#include "drivers/mic_positions.hpp"

namespace noisemon::drivers {

std::vector<std::array<double, 3>> thesis_mic_positions(double scale) {
  // Thesis Table 3.1 (x, y, z in m), hemisphere r = 1.75 m over the reflecting floor.
  std::vector<std::array<double, 3>> positions{
      {-1.35, 0.78, 0.79}, {0.00, 1.73, 0.26},  {0.00, 1.16, 1.31},  {1.00, -0.58, 1.31},  {0.00, 0.00, 1.75},
      {1.35, 0.78, 0.79},  {1.50, -0.87, 0.26}, {0.00, -1.16, 1.31}, {-1.00, -0.58, 1.31}, {-1.50, -0.87, 0.26}};
  for (auto& p : positions)
    for (double& v : p) v *= scale;
  return positions;
}

}  // namespace noisemon::drivers
