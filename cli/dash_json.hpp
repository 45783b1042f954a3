// `noisemon dash`: the LCM messages as JSON for the page (NaN becomes null, as JSON has no NaN).
#pragma once

#include <nlohmann/json.hpp>

#include "noisemon/check_t.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "noisemon/gap_event_t.hpp"
#include "noisemon/gap_status_t.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::cli {

// Every field of the report but the combustion metrics' angles; arrays stay arrays.
nlohmann::json cycle_json(const noisemon::cycle_report_t& r);
// One point of the rolling trend: levels, operating point, flags, and the gap measured - predicted per band (0.1 dB,
// null where not measured: the page's heat map). `dropped`: cycles missing before this one.
nlohmann::json trend_point_json(const noisemon::cycle_report_t& r, std::int64_t dropped, bool restarted);
nlohmann::json status_json(const noisemon::status_t& s);
nlohmann::json operating_point_json(const noisemon::operating_point_t& op);
// noisemon gapwatch's event (with its evidence: the change per band and microphone) and state.
nlohmann::json gap_event_json(const noisemon::gap_event_t& e);
nlohmann::json gap_status_json(const noisemon::gap_status_t& s);
// noisemon check --publish's table: its rows as the terminal printed them.
nlohmann::json check_json(const noisemon::check_t& c);

}  // namespace noisemon::cli
