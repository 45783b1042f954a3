// `noisemon dash`: the LCM messages as JSON for the page (NaN becomes null, as JSON has no NaN).
#pragma once

#include <nlohmann/json.hpp>

#include "noisemon/cycle_report_t.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::daemon {

// Every field of the report but the combustion metrics' angles; arrays stay arrays.
nlohmann::json cycle_json(const noisemon::cycle_report_t& r);
// One point of the rolling trend: levels, operating point, flags. `dropped`: cycles missing before this one.
nlohmann::json trend_point_json(const noisemon::cycle_report_t& r, std::int64_t dropped, bool restarted);
nlohmann::json status_json(const noisemon::status_t& s);
nlohmann::json operating_point_json(const noisemon::operating_point_t& op);

}  // namespace noisemon::daemon
