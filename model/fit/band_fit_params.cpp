// Block parameters by name, and their place among the surrogate's structural variables; the second mode's level
// change at its frequency.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit {

double mode_phase_rad(const ExtensionParams& e) { return e.mode_phase_deg * std::numbers::pi / 180.0; }

double mode_rise_db(const ExtensionParams& e) {
  const double a = std::pow(10.0, e.mode_db / 20.0) - 1.0, phi = mode_phase_rad(e);
  return 10.0 * std::log10(std::pow(1.0 + a * std::cos(phi), 2) + std::pow(a * std::sin(phi), 2));
}

std::string_view param_name(BlockParam p) {
  switch (p) {
    case BlockParam::kK1:
      return "k1";
    case BlockParam::kB1:
      return "b1";
    case BlockParam::kK3:
      return "k3";
    case BlockParam::kB3:
      return "b3";
    case BlockParam::kC0:
      return "c0";
    case BlockParam::kC1:
      return "c1";
  }
  return "?";
}

double param_value(const BlockParams& q, BlockParam p) {
  switch (p) {
    case BlockParam::kK1:
      return q.k1;
    case BlockParam::kB1:
      return q.b1;
    case BlockParam::kK3:
      return q.k3;
    case BlockParam::kB3:
      return q.b3;
    case BlockParam::kC0:
      return q.c0;
    case BlockParam::kC1:
      return q.c1;
  }
  return 0.0;
}

void set_param(BlockParams& q, BlockParam p, double v) {
  switch (p) {
    case BlockParam::kK1:
      q.k1 = v;
      break;
    case BlockParam::kB1:
      q.b1 = v;
      break;
    case BlockParam::kK3:
      q.k3 = v;
      break;
    case BlockParam::kB3:
      q.b3 = v;
      break;
    case BlockParam::kC0:
      q.c0 = v;
      break;
    case BlockParam::kC1:
      q.c1 = v;
      break;
  }
}

std::vector<BlockParam> parse_free_params(std::string_view text) {
  std::vector<BlockParam> out;
  const BlockParam all[] = {BlockParam::kK1, BlockParam::kB1, BlockParam::kK3,
                            BlockParam::kB3, BlockParam::kC0, BlockParam::kC1};
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t comma = text.find(',', pos);
    std::string_view item = text.substr(pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    if (!item.empty()) {
      bool found = false;
      for (BlockParam p : all)
        if (param_name(p) == item) {
          if (std::find(out.begin(), out.end(), p) == out.end()) out.push_back(p);
          found = true;
        }
      if (!found)
        throw std::invalid_argument("--free: unknown parameter '" + std::string(item) +
                                    "' (valid: k1, b1, k3, b3, c0, c1; m is fixed)");
    }
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  if (out.empty()) throw std::invalid_argument("--free: no parameter given (valid: k1, b1, k3, b3, c0, c1)");
  return out;
}

std::vector<BlockParam> default_free_params(const BlockParams& start) {
  std::vector<BlockParam> out{BlockParam::kK1, BlockParam::kB1, BlockParam::kC0, BlockParam::kC1};
  if (start.k3 > 0) out.push_back(BlockParam::kK3);
  if (start.b3 > 0) out.push_back(BlockParam::kB3);
  return out;
}

namespace band_fit_internal {

int struct_index(BlockParam p) {
  switch (p) {
    case BlockParam::kK1:
      return kSK1;
    case BlockParam::kB1:
      return kSB1;
    case BlockParam::kC0:
      return kSC0;
    case BlockParam::kC1:
      return kSC1;
    case BlockParam::kK3:
      return kSK3;
    case BlockParam::kB3:
      return kSB3;
  }
  return kSK1;
}

BlockParam param_of_struct(int idx) {
  switch (idx) {
    case kSK1:
      return BlockParam::kK1;
    case kSB1:
      return BlockParam::kB1;
    case kSC0:
      return BlockParam::kC0;
    case kSC1:
      return BlockParam::kC1;
    case kSK3:
      return BlockParam::kK3;
    default:
      return BlockParam::kB3;
  }
}

bool is_cubic(BlockParam p) { return p == BlockParam::kK3 || p == BlockParam::kB3; }

}  // namespace band_fit_internal
}  // namespace noisemon::model::fit
