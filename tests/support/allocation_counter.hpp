// Every heap allocation of a test program, counted: the program's operator new and delete are replaced (in
// allocation_counter.cpp, linked into a test program that calls these) by malloc and free with a count beside them.
// Tests check that a real-time path allocates nothing, or that a damaged length never becomes a huge allocation.
#pragma once

#include <cstddef>

namespace noisemon::test {

// Starts counting again from nothing.
void reset_allocation_counts();
// Allocations (any operator new, any thread) since the last reset.
[[nodiscard]] long allocations_since_reset();
// The largest single allocation since the last reset, in bytes.
[[nodiscard]] std::size_t largest_allocation_since_reset();

}  // namespace noisemon::test
