// noisemond: the engine-noise monitor service. Runs a source (the simulated engine by default), predicts and
// measures dB(A) every engine cycle, and publishes over LCM until SIGINT/SIGTERM (or --cycles N). Under systemd
// (Type=notify): READY=1 once the drivers deliver data, STATUS= once a second, WATCHDOG=1 only while every thread
// runs and the processing and publishing loops go round; SIGHUP reloads the configuration file (a broken one is
// logged and the running configuration stays).
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <memory>
#include <span>

#include "daemon/command_listener.hpp"
#include "daemon/config.hpp"
#include "daemon/lcm_publisher.hpp"
#include "daemon/pipeline.hpp"
#include "daemon/recorder.hpp"
#include "daemon/report_messages.hpp"
#include "daemon/sources.hpp"
#include "drivers/worker_thread.hpp"

namespace {

using namespace noisemon;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string config_path, source, microphones, lcm_url, log_level;
  std::int64_t cycles = -1;
  bool live = false;
};

// An option naming one of a registry's kinds, its help listing each with what it is.
template <class Kind>
void add_kind_option(CLI::App& app, const std::string& name, std::string& out, std::string help,
                     std::span<const Kind> kinds) {
  std::vector<std::string> names;
  for (const Kind& k : kinds) {
    help += (names.empty() ? " " : ", ") + std::string(k.name) + " (" + std::string(k.what) + ")";
    names.emplace_back(k.name);
  }
  app.add_option(name, out, help)->check(CLI::IsMember(names));
}

void add_options(CLI::App& app, Options& o) {
  app.add_option("--config", o.config_path,
                 "TOML configuration file (default: built-in defaults, simulated engine); "
                 "SIGHUP reads it again")
      ->check(CLI::ExistingFile);
  add_kind_option(app, "--source", o.source,
                  "acquisition source, overrides [daemon] source:", noisemon::daemon::stream_sources());
  add_kind_option(app, "--microphones", o.microphones,
                  "the microphones from a front-end of their own, overrides [daemon] microphones:",
                  noisemon::daemon::mic_sources());
  app.add_option("--lcm", o.lcm_url, "LCM URL, overrides [lcm] url (e.g. udpm://239.255.76.67:7667?ttl=0)");
  app.add_option("--cycles", o.cycles, "stop after publishing N cycles (0 = run until SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--live", o.live, "print one line per cycle on stdout (predicted and measured Lp(A), LW(A))");
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error, critical or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}));
}

// The configuration file with the command line's overrides. Throws naming the file, line and key.
daemon::Config effective_config(const Options& o) {
  daemon::Config config = o.config_path.empty() ? daemon::Config{} : daemon::load_config(o.config_path);
  if (!o.source.empty()) config.source = o.source;
  if (!o.microphones.empty()) config.microphones = o.microphones;
  if (!o.lcm_url.empty()) config.lcm.url = o.lcm_url;
  if (o.cycles >= 0) config.cycles = o.cycles;
  if (o.live) config.live = true;
  if (!o.log_level.empty()) config.log_level = o.log_level;
  if (config.source == "lcm") {
    // The streams come from the bus: publishing them again would feed them back to ourselves.
    config.lcm.publish_raw = false;
    config.lcm.publish_operating_point = false;
  }
  return config;
}

// A running pipeline, and the listener of the test bed's commands to its recorder (stopped first).
struct Running {
  std::unique_ptr<daemon::Pipeline> pipeline;
  std::unique_ptr<daemon::CommandListener> commands;

  void stop() {
    commands.reset();
    pipeline->stop();
  }
};

// The bus, and the recorder when [record] is enabled. Every message goes to both, but the raw streams go on the bus
// only with publish_raw (else they are the recorder's alone), and a daemon whose source is the bus publishes no
// streams or session back onto it. After the source: a missing device is the error reported first.
std::shared_ptr<daemon::Publisher> make_publisher(const daemon::Config& config,
                                                  const std::shared_ptr<daemon::Recorder>& recorder) {
  std::vector<std::string> kept_off;
  if (!config.lcm.publish_raw) kept_off.push_back(config.lcm.raw_channel);
  if (config.source == "lcm") kept_off.push_back(config.lcm.session_channel);
  auto bus = std::make_shared<daemon::LcmPublisher>(config.lcm.url, std::move(kept_off));
  if (!recorder) return bus;
  auto both = std::make_shared<daemon::FanoutPublisher>();
  both->add(bus);
  both->add(recorder);
  return both;
}

Running start_pipeline(const daemon::Config& config) {
  spdlog::set_level(spdlog::level::from_str(config.log_level));
  daemon::PipelineOptions options;
  if (config.live) {
    std::cout << daemon::cycle_line_header() << std::endl;
    options.on_report = [](const daemon::CycleReport& r) {
      std::cout << daemon::cycle_line(daemon::to_message(r)) << std::endl;
    };
  }
  auto acquisition = daemon::make_source(config);
  if (config.threads.lock_memory) {
    // After the devices are open, so that a missing device is the error reported first; MCL_CURRENT locks what
    // is mapped now, MCL_FUTURE the rings and threads that follow.
    drivers::lock_memory();
    spdlog::info("memory locked (mlockall MCL_CURRENT | MCL_FUTURE)");
  }
  std::shared_ptr<daemon::Recorder> recorder;
  if (config.record.enabled)
    recorder = std::make_shared<daemon::Recorder>(config.record, config.lcm, config.threads.recording);
  Running running;
  running.pipeline =
      std::make_unique<daemon::Pipeline>(config, std::move(acquisition), make_publisher(config, recorder), options);
  running.pipeline->start();
  if (daemon::CommandListener::listens_on(config.lcm.url))
    running.commands = std::make_unique<daemon::CommandListener>(config.lcm, recorder);
  return running;
}

// SIGHUP: the configuration file again. A broken one changes nothing; a good one restarts the pipeline with it.
void reload(const Options& o, Running& running) {
  daemon::Config fresh;
  try {
    fresh = effective_config(o);
  } catch (const std::exception& e) {
    spdlog::error("SIGHUP: {}: keeping the running configuration", e.what());
    return;
  }
  spdlog::info("SIGHUP: {} read: restarting the pipeline with it",
               o.config_path.empty() ? "(built-in defaults)" : o.config_path);
  sd_notify(0, "RELOADING=1");
  running.stop();
  running = Running{};
  running = start_pipeline(fresh);
}

// The systemd side while the pipeline runs: READY=1, STATUS= each second, WATCHDOG=1 while healthy.
class Supervisor {
 public:
  Supervisor() {
    std::uint64_t usec = 0;
    if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) watchdog_ = std::chrono::microseconds(usec);
  }
  void restarted() { ready_ = false; }
  void tick(const daemon::Pipeline& pipeline) {
    const auto now = Clock::now();
    if (!ready_ && pipeline.ready()) {
      sd_notify(0, "READY=1\nSTATUS=acquiring");
      spdlog::info("ready: all driver threads deliver data");
      ready_ = true;
    }
    if (now >= next_status_) {
      const std::string status = "STATUS=" + std::string(ready_ ? "acquiring" : "starting") + ": " +
                                 std::to_string(pipeline.cycles_published()) + " cycles published, " +
                                 std::to_string(pipeline.cycles_dropped()) + " dropped";
      sd_notify(0, status.c_str());
      next_status_ = now + std::chrono::seconds(1);
    }
    // Fed at a quarter of the period, and only while every thread's loop went round within half of it.
    const double fresh_s = std::chrono::duration<double>(watchdog_).count() / 2;
    if (watchdog_.count() > 0 && ready_ && now >= next_ping_ && pipeline.healthy(fresh_s)) {
      sd_notify(0, "WATCHDOG=1");
      next_ping_ = now + watchdog_ / 4;
    }
  }

 private:
  std::chrono::microseconds watchdog_{0};
  bool ready_ = false;
  Clock::time_point next_status_ = Clock::now(), next_ping_ = Clock::now();
};

int run(int argc, char** argv) {
  CLI::App app{"noisemond - engine-noise monitor: predicted and measured dB(A) per engine cycle over LCM"};
  Options options;
  add_options(app, options);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  spdlog::set_default_logger(spdlog::stderr_color_mt("noisemond"));
  const daemon::Config config = effective_config(options);

  // Signals are taken synchronously by this thread; every thread started below inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&signals, s);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  Running running = start_pipeline(config);
  Supervisor supervisor;
  while (!running.pipeline->finished()) {
    supervisor.tick(*running.pipeline);
    const timespec timeout{0, 50'000'000};
    const int sig = sigtimedwait(&signals, nullptr, &timeout);
    if (sig == SIGHUP) {
      reload(options, running);
      supervisor.restarted();
    } else if (sig > 0) {
      spdlog::info("{} received: finishing the last complete cycle", sig == SIGINT ? "SIGINT" : "SIGTERM");
      break;
    }
  }
  sd_notify(0, "STOPPING=1");
  running.stop();
  if (const std::string why = running.pipeline->failure(); !why.empty()) {
    spdlog::error("{}", why);
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "noisemond: %s\n", e.what());
    return 1;
  }
}
