// report.html of `noisemon diagnose`: one self-contained page (inline CSS and SVG; no scripts, fonts, images or URLs)
// rendered from report.json (cli/report/diagnosis_report.hpp), so the page shows nothing the JSON does not hold. Any
// JSON renders without throwing: a missing key, a null (NaN, an unscored band) or a value of the wrong type shows as
// a dash or as a "Not in this report" note in its section, all listed at the top; JSON strings are HTML-escaped.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace noisemon::cli::report {

std::string report_html(const nlohmann::json& report);

}  // namespace noisemon::cli::report
