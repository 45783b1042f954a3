// The live gap watch's messages and files: a cycle report as the watch reads it, an event as noisemon.gap_event_t
// and as one JSON line, and the reference as a JSON file (`noisemon gapwatch --save-reference`, `--reference`).
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "model/diagnosis/gap_watch.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "noisemon/gap_event_t.hpp"
#include "noisemon/gap_status_t.hpp"

namespace noisemon::cli {

// The report's bands, microphones and overall levels; a band flagged as saying nothing (Nyquist, below the firing
// frequency, beyond a converter's passband, settling) and a flagged microphone read NaN; a cycle with a fault flag
// is not usable.
[[nodiscard]] model::diagnosis::CycleGap cycle_gap(const noisemon::cycle_report_t& report);

[[nodiscard]] noisemon::gap_event_t gap_event_message(const model::diagnosis::GapEvent& event, std::int64_t utime);
[[nodiscard]] noisemon::gap_status_t gap_status_message(const model::diagnosis::GapWatch& watch, std::int64_t utime,
                                                        std::int32_t events);
// effect, params (the effect's own keys), onset_s, detected_s, onset_cycle, detected_cycle, gap_before_db,
// gap_after_db, confidence, explained, features, the operating point, explanation and the candidates' weights.
[[nodiscard]] nlohmann::json gap_event_json(const model::diagnosis::GapEvent& event);

[[nodiscard]] nlohmann::json reference_json(const model::diagnosis::GapReference& reference);
// Throws std::runtime_error naming the file and the field that is missing or wrong.
[[nodiscard]] model::diagnosis::GapReference load_reference(const std::string& path);

}  // namespace noisemon::cli
