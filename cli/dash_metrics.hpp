// `noisemon dash`: GET /metrics, the daemon's status and last levels in the Prometheus text exposition format
// (version 0.0.4), every sample labelled with the cell.
#pragma once

#include <map>
#include <optional>
#include <string>

#include "noisemon/check_t.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "noisemon/gap_status_t.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::cli {

struct MetricsInput {
  std::string cell;
  std::optional<noisemon::status_t> status;               // the last status message, if any
  std::optional<noisemon::cycle_report_t> cycle;          // the last cycle report, if any
  double status_age_s = 0;                                // seconds since the status arrived
  long long cycles_received = 0;                          // by the dash since it started
  std::optional<noisemon::gap_status_t> gap_status;       // noisemon gapwatch's last state, if any
  std::map<std::string, long long> gap_events_by_effect;  // its events since the dash started
  std::optional<noisemon::check_t> check;                 // noisemon check --publish's last table, if any
};

std::string prometheus_text(const MetricsInput& in);

// A label value with backslash, double quote and newline escaped, as the format requires.
std::string prometheus_label_value(const std::string& value);

}  // namespace noisemon::cli
