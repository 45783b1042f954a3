// 32-byte vectors for the resamplers' hot loops (dsp/resample.cpp): a load, a lane sum and dot products, forced
// inline so that each is compiled inside the cloned kernel that calls it (kernel_clones.hpp). Internal to dsp/.
#pragma once

#include <cstddef>
#include <cstring>

#include "dsp/kernel_clones.hpp"

namespace noisemon::dsp::simd {

// 32 bytes of samples as one vector (GCC vector extension: one AVX register in the x86-64-v3 clone, two SSE
// ones in the default): 4 doubles or 8 floats. Only used inside always-inline helpers, never across a call, so
// the ABI note is moot.
#pragma GCC diagnostic ignored "-Wpsabi"
template <class T>
struct Simd {
  typedef T V __attribute__((vector_size(32)));
  static constexpr std::size_t kLanes = 32 / sizeof(T);
};
using Vd = Simd<double>::V;
constexpr std::size_t kVd = Simd<double>::kLanes;

template <class T>
NOISEMON_INLINE typename Simd<T>::V load(const T* p) {
  typename Simd<T>::V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

template <class V>
NOISEMON_INLINE auto lane_sum(V v) {
  auto sum = v[0];
  for (std::size_t l = 1; l < sizeof(V) / sizeof(v[0]); ++l) sum += v[l];
  return sum;
}

// Two vector accumulators so consecutive multiply-adds do not wait on each other.
template <class T>
NOISEMON_INLINE T dot(const T* a, const T* b, std::size_t n) {
  constexpr std::size_t kL = Simd<T>::kLanes;
  typename Simd<T>::V acc0 = {}, acc1 = {};
  std::size_t i = 0;
  for (; i + 2 * kL <= n; i += 2 * kL) {
    acc0 += load(a + i) * load(b + i);
    acc1 += load(a + i + kL) * load(b + i + kL);
  }
  T sum = lane_sum(acc0 + acc1);
  for (; i < n; ++i) sum += a[i] * b[i];
  return sum;
}

// Four dot products sharing `a` (one load of a per four multiply-adds: the loads, not the arithmetic, bound a
// single dot product). b[c] + i is channel c's history.
template <class T>
NOISEMON_INLINE void dot4(const T* a, const T* const b[4], std::size_t n, T sums[4]) {
  constexpr std::size_t kL = Simd<T>::kLanes;
  typename Simd<T>::V acc[4] = {};
  std::size_t i = 0;
  for (; i + kL <= n; i += kL) {
    const auto av = load(a + i);
    for (int c = 0; c < 4; ++c) acc[c] += av * load(b[c] + i);
  }
  for (int c = 0; c < 4; ++c) {
    sums[c] = lane_sum(acc[c]);
    for (std::size_t k = i; k < n; ++k) sums[c] += a[k] * b[c][k];
  }
}

}  // namespace noisemon::dsp::simd
