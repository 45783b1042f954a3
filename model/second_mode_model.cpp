#include "model/second_mode_model.hpp"

#include <algorithm>

namespace noisemon::model {
namespace {

BlockParams as_block(const SecondModeParams& s) {
  BlockParams p;
  p.m = 1.0;
  p.k1 = s.k1;
  p.b1 = s.b1;
  p.k3 = 0.0;
  p.b3 = 0.0;
  p.c0 = s.c0;
  p.c1 = s.c1;
  return p;
}

}  // namespace

SecondModeModel::SecondModeModel(const BlockParams& primary, const SecondModeParams& second, double fs_hz,
                                 const BlockModelOptions& options)
    : primary_(primary, fs_hz, options), second_(as_block(second), fs_hz, options) {}

void SecondModeModel::process(const double* u, double* y, std::size_t n) {
  for (std::size_t done = 0; done < n;) {
    const std::size_t k = std::min(kChunk, n - done);
    std::copy(u + done, u + done + k, in_.begin());  // u may alias y
    primary_.process(in_.data(), y + done, k);
    second_.process(in_.data(), out_.data(), k);
    for (std::size_t i = 0; i < k; ++i) y[done + i] += out_[i];
    done += k;
  }
}

void SecondModeModel::reset() {
  primary_.reset();
  second_.reset();
}

void SecondModeModel::set_state(double z, double v, double w, double w_dot) {
  primary_.set_state(z, v);
  second_.set_state(w, w_dot);
}

}  // namespace noisemon::model
