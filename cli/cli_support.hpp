// Small pieces the `noisemon` subcommands share: a progress line on the terminal and comma-separated option
// lists.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace noisemon::cli {

// One progress line on stderr, rewritten in place; only when stderr is a terminal (never in a pipe or a log).
class ProgressLine {
 public:
  explicit ProgressLine(bool enabled) : on_(enabled && isatty(STDERR_FILENO)) {}
  ~ProgressLine() { done(); }
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;
  void show(const std::string& text) {
    if (!on_) return;
    std::fprintf(stderr, "\r\033[K%s", text.c_str());
    std::fflush(stderr);
    shown_ = true;
  }
  // Ends the line (the next show starts a new one).
  void done() {
    if (on_ && shown_) std::fputc('\n', stderr);
    shown_ = false;
  }

 private:
  bool on_;
  bool shown_ = false;
};

// A subcommand's body: an exception becomes "noisemon COMMAND: message" on stderr and exit status 1.
template <class Body>
int exit_status_of(const char* command, Body&& body) {
  try {
    body();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "noisemon %s: %s\n", command, e.what());
    return 1;
  }
  return 0;
}

// "a, b,c" -> {"a", "b", "c"} (blank items dropped).
inline std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// A repeated option whose values may themselves be comma-separated lists, flattened.
inline std::vector<std::string> flatten_lists(const std::vector<std::string>& items) {
  std::vector<std::string> out;
  for (const std::string& s : items)
    for (std::string& t : split_list(s)) out.push_back(std::move(t));
  return out;
}

inline bool is_csv_path(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".csv";
}

// The DATA of `fit` and `diagnose`: every path must exist; the mode is `given` ("band" or "waveform") or, when
// empty, follows from DATA (.csv files: waveform; run directories and logs: band; a mix is an error).
inline std::string data_mode(const std::vector<std::string>& data, const std::string& given) {
  if (data.empty()) throw std::runtime_error("no DATA given");
  for (const std::string& p : data)
    if (!std::filesystem::exists(p)) throw std::runtime_error(p + ": no such file or directory");
  std::string mode = given;
  if (mode.empty()) {
    const bool csv = std::all_of(data.begin(), data.end(), is_csv_path);
    const bool none = std::none_of(data.begin(), data.end(), is_csv_path);
    if (!csv && !none) throw std::runtime_error("DATA mixes .csv waveforms and band data: give --mode");
    mode = csv ? "waveform" : "band";
  }
  if (mode != "band" && mode != "waveform") throw std::runtime_error("--mode " + mode + ": expected band or waveform");
  return mode;
}

}  // namespace noisemon::cli
