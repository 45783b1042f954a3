// Conversion of the daemon's cycle report to its LCM message (the stream messages are in
// drivers/formats/stream_messages.hpp), and the one-line text form of
// a cycle report that `noisemond --live` and `noisemon watch` print.
#pragma once

#include <string>

#include "daemon/cycle_report.hpp"
#include "drivers/formats/stream_messages.hpp"
#include "noisemon/cycle_report_t.hpp"

namespace noisemon::daemon {

noisemon::cycle_report_t to_message(const CycleReport& r);
using drivers::formats::from_message;
using drivers::formats::to_message;

// CSV form of cycle reports (noisemon watch --csv, noisemon replay --csv). The last column is the run's
// condition name (session_t::condition; empty for a live daemon). Levels that were not measured (no
// microphones) are written as "nan".
std::string cycle_csv_header();
std::string cycle_csv_row(const noisemon::cycle_report_t& r, const std::string& condition = "");

// Column header and one line per cycle: cycle, speed, SOI, measured/predicted Lp(A) and LW(A), difference.
std::string cycle_line_header();
std::string cycle_line(const noisemon::cycle_report_t& r);
// Short names of the set CYCLE_* flags, e.g. "settling,gap"; "ok" when none.
std::string cycle_flags_text(std::int32_t flags);

// A band whose levels say nothing of the engine: beyond a passband or the Nyquist cut, below the firing frequency,
// or still settling (its gap measured - predicted is no gap of the model's).
[[nodiscard]] constexpr bool band_says_nothing(std::int32_t band_flags) {
  using R = noisemon::cycle_report_t;
  return (band_flags & (R::BAND_NYQUIST_CUT | R::BAND_BELOW_FIRING | R::BAND_PRESSURE_PASSBAND | R::BAND_MIC_PASSBAND |
                        R::BAND_SETTLING)) != 0;
}

}  // namespace noisemon::daemon
