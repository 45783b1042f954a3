// Conversions between the daemon's internal structs and the LCM message types, and the one-line text form of
// a cycle report that `noisemond --live` and `noisemon watch` print.
#pragma once

#include <string>

#include "daemon/cycle_report.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/raw_block_t.hpp"
#include "noisemon/session_t.hpp"

namespace noisemon::daemon {

noisemon::cycle_report_t to_message(const CycleReport& r);
noisemon::operating_point_t to_message(const drivers::OperatingPoint& op);
noisemon::raw_block_t to_message(const drivers::SampleBlock& b, std::int8_t stream, std::int64_t epoch_utime);
noisemon::session_t to_message(const drivers::StreamInfo& info, const std::string& source, std::int64_t utime);
// Back from the messages a log holds (replay). Throw std::invalid_argument naming what does not fit.
drivers::StreamInfo from_message(const noisemon::session_t& m);
drivers::SampleBlock from_message(const noisemon::raw_block_t& m);
drivers::OperatingPoint from_message(const noisemon::operating_point_t& m);

// CSV form of cycle reports (noisemon watch --csv, noisemon replay --csv).
std::string cycle_csv_header();
std::string cycle_csv_row(const noisemon::cycle_report_t& r);

// Column header and one line per cycle: cycle, speed, SOI, measured/predicted Lp(A) and LW(A), difference.
std::string cycle_line_header();
std::string cycle_line(const noisemon::cycle_report_t& r);
// Short names of the set CYCLE_* flags, e.g. "settling,gap"; "ok" when none.
std::string cycle_flags_text(std::int32_t flags);

}  // namespace noisemon::daemon
