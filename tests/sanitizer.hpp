// Whether this test program is built with a sanitizer (tests/sanitize/run_sanitized.sh). AddressSanitizer slows
// code about two-fold and ThreadSanitizer five- to fifteen-fold, more on a loaded machine: an assertion about
// speed (a paced source keeping up with the wall clock, a deadline) would then measure the sanitizer, not the code.
// The tests that make one check kSanitized and say what they relax.
#pragma once

namespace noisemon::test {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

}  // namespace noisemon::test
