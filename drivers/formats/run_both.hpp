// Two pieces of work at once, with the errors of running them one after the other.
#pragma once

#include <exception>
#include <thread>

namespace noisemon::drivers::formats {

// Runs a on this thread and b on another, each to its end; then rethrows a's exception, else b's: what running a
// and then b would have thrown.
template <class A, class B>
void run_both(A&& a, B&& b) {
  std::exception_ptr b_error;
  {
    std::jthread other([&b, &b_error] {
      try {
        b();
      } catch (...) {
        b_error = std::current_exception();
      }
    });
    a();  // should it throw, `other` is joined first
  }
  if (b_error) std::rethrow_exception(b_error);
}

}  // namespace noisemon::drivers::formats
