#include "cli/check_command.hpp"

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/chain_check.hpp"
#include "cli/lcm_loop.hpp"
#include "daemon/config.hpp"
#include "noisemon/check_t.hpp"

namespace noisemon::cli {
namespace {

// The table on LCM for the dashboard: the rows as printed.
void publish_table(const std::vector<CheckRow>& rows, int problems, const std::string& summary,
                   const daemon::Config& config, double seconds) {
  noisemon::check_t m{};
  m.utime = std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
                .count();
  m.source = config.source;
  m.seconds = seconds;
  for (const CheckRow& r : rows) {
    m.item.push_back(r.item);
    m.value.push_back(r.value);
    m.verdict.push_back(r.verdict);
    m.failed.push_back(r.failed);
  }
  m.problems = problems;
  m.nrows = static_cast<std::int32_t>(rows.size());
  m.summary = summary;
  ::lcm::LCM bus(config.lcm.url);
  if (!bus.good() || bus.publish(config.lcm.check_channel, &m) != 0)
    throw std::runtime_error("--publish: " + lcm_open_error(config.lcm.url));
}

}  // namespace

CheckCommand::CheckCommand(CLI::App& app) {
  check_ = app.add_subcommand("check",
                              "check the measurement chain before a test: microphones (dead, clipped, implausible), "
                              "the pressure's offset, the encoder, CAN; exit status 1 when something is wrong");
  check_->add_option("--config", config_path_, "the daemon's configuration file (default: the simulated engine)")
      ->check(CLI::ExistingFile);
  check_->add_option("--seconds", seconds_, "how long to listen")->capture_default_str()->check(CLI::Range(1.0, 60.0));
  check_->add_flag("--publish", publish_,
                   "also publish the table on the configuration's LCM ([lcm] check_channel, NOISEMON_CHECK), where "
                   "noisemon dash shows it");
}

int CheckCommand::run() {
  if (!check_->parsed()) return -1;
  const daemon::Config config = config_path_.empty() ? daemon::Config{} : daemon::load_config(config_path_);
  std::fprintf(stderr, "check: listening to %s for %.0f s\n", config.source.c_str(), seconds_);
  const std::vector<CheckRow> rows = check_measurement_chain(config, seconds_);
  int failed = 0;
  std::printf("%-28s %-44s %s\n", "check", "value", "verdict");
  for (const CheckRow& r : rows) {
    std::printf("%-28s %-44s %s%s\n", r.item.c_str(), r.value.c_str(), r.failed ? "FAIL " : "", r.verdict.c_str());
    failed += r.failed ? 1 : 0;
  }
  const std::string summary =
      failed ? std::to_string(failed) + " problems: fix them before the test" : "the measurement chain is ready";
  std::printf("%s\n", summary.c_str());
  std::fflush(stdout);
  if (publish_) publish_table(rows, failed, summary, config, seconds_);
  return failed ? 1 : 0;
}

}  // namespace noisemon::cli
