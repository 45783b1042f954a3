// Whether this test program is built with a sanitizer (tests/sanitize/run_sanitized.sh), and how long a test may
// wait for the work it starts. AddressSanitizer slows code about two-fold and ThreadSanitizer five- to fifteen-fold,
// more on a loaded machine: an assertion about speed (a paced source keeping up with the wall clock, a deadline)
// would then measure the sanitizer, not the code. Under a sanitizer the tests run the virtual engine unpaced and
// assert counts and exit statuses; the real-time assertions are left to the normal build, and every wait's deadline
// is the work it waits for, stretched by `allowance`.
#pragma once

#include <chrono>
#include <string>

namespace noisemon::test {

#if defined(NOISEMON_SANITIZE_THREAD)
inline constexpr bool kSanitized = true;
inline constexpr double kSanitizerSlowdown = 15.0;
#elif defined(NOISEMON_SANITIZE_ADDRESS)
inline constexpr bool kSanitized = true;
inline constexpr double kSanitizerSlowdown = 3.0;
#else
inline constexpr bool kSanitized = false;
inline constexpr double kSanitizerSlowdown = 1.0;
#endif

// Two CPU-bound processes beside a test on the 2-core machine leave its processes a third of the cores or less.
inline constexpr double kLoadedMachineSlowdown = 4.0;

// A process's start, from its exec to the daemon's first cycle, in the normal build on an idle machine.
inline constexpr std::chrono::duration<double> kStartUp{1.5};

// How long to wait for work that takes `idle` in the normal build on an idle machine, before calling it a hang: the
// work stretched by this build's sanitizer and by a loaded machine. A guard, never a measure of speed.
inline std::chrono::milliseconds allowance(std::chrono::duration<double> idle) {
  const double ms = 1000.0 * idle.count() * kSanitizerSlowdown * kLoadedMachineSlowdown;
  return std::chrono::milliseconds(static_cast<long long>(ms + 0.5));
}

// The same, in seconds (a command-line --timeout).
inline double allowance_s(double idle_s) { return idle_s * kSanitizerSlowdown * kLoadedMachineSlowdown; }

// A noisemond configuration's [sim] pacing: at the wall clock's pace in the normal build; under a sanitizer, which
// cannot keep that pace, as fast as the processing takes the data (nothing lost to the pace, the same cycles).
inline std::string sim_pacing_toml() { return kSanitized ? "[sim]\npaced = false\n" : ""; }

}  // namespace noisemon::test
