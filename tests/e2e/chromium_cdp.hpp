// Debian's headless Chromium driven over the DevTools protocol on a pipe (--remote-debugging-pipe: commands on
// the browser's fd 3, replies and events on its fd 4, each a JSON text ended by a NUL byte). No WebSocket client
// and no port needed: the test evaluates JavaScript in the page and takes screenshots.
#pragma once

#include <fcntl.h>
#include <linux/capability.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/sanitizer.hpp"

namespace noisemon::test {

inline const char* const kChromium = "/usr/bin/chromium";

class Chromium {
 public:
  // Starts the browser (its stderr, full of D-Bus complaints in a namespace, into `log_path`) and opens `url`.
  Chromium(const std::string& url, const std::string& profile_dir, const std::string& log_path) {
    int to_browser[2], from_browser[2];
    if (pipe(to_browser) != 0 || pipe(from_browser) != 0) throw std::runtime_error("pipe failed");
    pid_ = fork();
    if (pid_ == 0) exec_browser(to_browser, from_browser, profile_dir, log_path);
    close(to_browser[0]);
    close(from_browser[1]);
    out_ = to_browser[1];
    in_ = from_browser[0];
    const std::string target = call("Target.createTarget", {{"url", "about:blank"}})["targetId"];
    session_ = call("Target.attachToTarget", {{"targetId", target}, {"flatten", true}})["sessionId"];
    call("Page.navigate", {{"url", url}});
  }
  ~Chromium() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
    close(out_);
    close(in_);
  }

  // The value of a JavaScript expression in the page (JSON-serialisable values).
  nlohmann::json evaluate(const std::string& expression) {
    const auto r = call("Runtime.evaluate", {{"expression", expression}, {"returnByValue", true}});
    if (r.contains("exceptionDetails")) throw std::runtime_error("page: " + r["exceptionDetails"].dump());
    return r["result"].value("value", nlohmann::json());
  }

  void screenshot(const std::string& png_path) {
    const std::string data = call("Page.captureScreenshot", {{"format", "png"}})["data"];
    std::ofstream(png_path, std::ios::binary) << decode_base64(data);
  }

 private:
  [[noreturn]] static void exec_browser(int to_browser[2], int from_browser[2], const std::string& profile,
                                        const std::string& log_path) {
    const int in = dup(to_browser[0]), out = dup(from_browser[1]);  // above 4 before placing them at 3 and 4
    dup2(in, 3);
    dup2(out, 4);
    const int log = open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (log >= 0) dup2(log, 2);
    // As root, Chromium raises its browser and GPU processes to nice -8, and then a daemon or subscriber of a test
    // beside it waited seconds for a core. Without CAP_SYS_NICE it runs at the priority a user's browser has.
    prctl(PR_CAPBSET_DROP, CAP_SYS_NICE, 0, 0, 0);
    const std::vector<std::string> args{kChromium,
                                        "--headless",
                                        "--no-sandbox",
                                        "--disable-gpu",
                                        "--disable-quic",
                                        "--no-first-run",
                                        "--disable-background-networking",
                                        "--disable-component-update",
                                        "--disable-sync",
                                        "--remote-debugging-pipe",
                                        "--window-size=1400,1900",
                                        "--user-data-dir=" + profile,
                                        "about:blank"};
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(kChromium, argv.data());
    _exit(127);
  }

  nlohmann::json call(const std::string& method, const nlohmann::json& params) {
    nlohmann::json m{{"id", ++id_}, {"method", method}, {"params", params}};
    if (!session_.empty()) m["sessionId"] = session_;
    const std::string text = m.dump() + '\0';
    if (write(out_, text.data(), text.size()) != static_cast<ssize_t>(text.size()))
      throw std::runtime_error("browser gone");
    for (;;) {  // skip events and other replies until ours
      const auto reply = nlohmann::json::parse(read_message());
      if (reply.value("id", 0) != id_) continue;
      if (reply.contains("error")) throw std::runtime_error(method + ": " + reply["error"].dump());
      return reply["result"];
    }
  }

  std::string read_message() {
    // A reply is work of seconds for the browser (a page's load, a screenshot): stretched as every wait of the tests,
    // since several browsers, daemons and dashes share the cores while the end-to-end tests run side by side.
    const auto deadline = std::chrono::steady_clock::now() + allowance(std::chrono::seconds(20));
    for (;;) {
      if (const auto end = buffer_.find('\0'); end != std::string::npos) {
        std::string message = buffer_.substr(0, end);
        buffer_.erase(0, end + 1);
        return message;
      }
      pollfd p{in_, POLLIN, 0};
      if (std::chrono::steady_clock::now() > deadline || poll(&p, 1, 1000) < 0)
        throw std::runtime_error("browser silent");
      if (!(p.revents & (POLLIN | POLLHUP))) continue;
      char chunk[65536];
      const ssize_t n = read(in_, chunk, sizeof chunk);
      if (n <= 0) throw std::runtime_error("browser closed the pipe");
      buffer_.append(chunk, static_cast<std::size_t>(n));
    }
  }

  static std::string decode_base64(const std::string& in) {
    std::string out;
    int bits = 0, value = 0;
    for (const char c : in) {
      const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
      const char* p = std::char_traits<char>::find(table, 64, c);
      if (!p) continue;  // padding
      value = (value << 6) | static_cast<int>(p - table);
      if ((bits += 6) >= 8) out.push_back(static_cast<char>((value >> (bits -= 8)) & 0xff));
    }
    return out;
  }

  pid_t pid_ = -1;
  int out_ = -1, in_ = -1;
  int id_ = 0;
  std::string session_, buffer_;
};

}  // namespace noisemon::test
