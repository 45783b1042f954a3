// A command line run as a real process, for the tests that drive the `noisemon` binary: its exit status and
// everything it printed (stdout and stderr together).
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace noisemon::test {

struct CommandOutput {
  int status = -1;  // the exit status; -1 when it could not start or did not exit normally
  std::string text;
};

inline CommandOutput run_command(const std::string& command_line) {
  CommandOutput o;
  FILE* p = popen((command_line + " 2>&1").c_str(), "r");
  if (!p) return o;
  char buf[4096];
  while (std::size_t n = std::fread(buf, 1, sizeof buf, p)) o.text.append(buf, n);
  const int status = pclose(p);
  o.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return o;
}

}  // namespace noisemon::test
