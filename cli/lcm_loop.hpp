// What the `noisemon` commands that use LCM share: a callable as LCM's member-function handler, the loop that
// handles messages until SIGINT or SIGTERM, and what to say when the bus cannot be opened.
#pragma once

#include <poll.h>

#include <csignal>
#include <functional>
#include <string>

#include <lcm/lcm-cpp.hpp>

namespace noisemon::cli {

template <class Message>
struct LcmHandler {
  std::function<void(const Message&)> fn;
  void on(const lcm::ReceiveBuffer*, const std::string&, const Message* m) { fn(*m); }
};

// "cannot open LCM at 'URL': ..." for an LCM whose good() is false (url empty: LCM's default).
inline std::string lcm_open_error(const std::string& url) {
  return "cannot open LCM at '" + (url.empty() ? std::string("default URL") : url) +
         "': the network needs a multicast route (docs/sources-and-formats.md, 'LCM and multicast')";
}

namespace lcm_loop_detail {
inline volatile std::sig_atomic_t stop = 0;
inline void on_signal(int) { stop = 1; }
}  // namespace lcm_loop_detail

// Handles messages (polling every 100 ms) until SIGINT or SIGTERM.
inline void handle_until_signal(lcm::LCM& lcm) {
  lcm_loop_detail::stop = 0;
  std::signal(SIGINT, lcm_loop_detail::on_signal);
  std::signal(SIGTERM, lcm_loop_detail::on_signal);
  while (!lcm_loop_detail::stop) {
    pollfd pfd{lcm.getFileno(), POLLIN, 0};
    if (::poll(&pfd, 1, 100) > 0) lcm.handle();
  }
}

}  // namespace noisemon::cli
