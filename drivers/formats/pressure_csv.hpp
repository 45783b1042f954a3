// pressure.csv of a run directory (time_s,crank_deg,pressure): the reader, with a parallel fast path for plain
// rows and a sequential one that names the line of any problem, and the writer. parse_pressure_csv and
// crank_step_deg (run_dir.hpp) are its public face.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "drivers/formats/mapped_file.hpp"
#include "drivers/formats/run_dir.hpp"

namespace noisemon::drivers::formats {

inline constexpr const char* kPressureCsvHeader = "time_s,crank_deg,pressure";

// pressure.csv's text into run's columns; map: the file it is mapped from, whose pages are released as they are
// parsed (or null). Throws RunDirError naming the file and line.
void parse_pressure_text(std::string_view text, const std::string& file, double to_pa, RunDir& run,
                         const MappedFile* map);

// run's columns as the pressure file at `path`, the pressure times from_pa (1e-5: bar). Throws RunDirError.
void write_pressure_csv(const std::filesystem::path& path, const RunDir& run, double from_pa);

}  // namespace noisemon::drivers::formats
