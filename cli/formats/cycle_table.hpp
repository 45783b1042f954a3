// Cycle tables: the common export of indicating systems (AVL IndiCom, Kistler KiBox, lab heat-release scripts):
// a text table whose first column is the crank angle over one 720-degree cycle and whose further columns are
// consecutive cycles of cylinder pressure in bar, separated by tabs or semicolons (a decimal comma is then allowed:
// "-180,0;0,969", the export of comma-decimal locales), or by blanks or commas ("-180.0, 0.969"), e.g.
//
//   -180.0   0.969  0.969  ...      <- first row: the pegging value (the same in every cycle), see below
//   -179.8   1.024  0.859  ...
//   ...
//    539.8   1.262  1.170  ...
//
// Conversion to a run directory keeps every column whole: column j becomes the pipeline's cycle j, crank angles
// [720 j - 360, 720 j + 360) with 0 at the column's firing TDC (table angle tdc_deg), and time from a constant
// speed. Each column of an indicating system's export is one recorded cycle with its own pegging offset (the Yanmar
// tables: a column's end and its own start differ by 0.05 bar rms, consecutive columns by 0.4), so the pipeline's
// cycle must not take its intake stroke from one column and the rest from the next. A table whose window is not
// centred on TDC (the Yanmar tables run -180 .. 539.8) has the part of each column past +360 (its next intake, the
// same recording) rotated to the front of its cycle: the seams between recordings fall on the cycle boundaries
// (gas-exchange TDC, where dV/dtheta = 0), never inside a cycle. A table of N cycles gives N whole cycles, of which
// replay reports N - 2: the pipeline counts cycles from boundary to boundary, so the first only warms its filters
// up and the last has no boundary after it.
//
// Pegging row: many exports write the pegging (absolute-pressure reference) value into the first row of every
// cycle instead of a measured sample. It is not a sample of the cycle: the converter drops it, which leaves one
// missing encoder step per cycle that resampling to 40 kHz fills by interpolation (as for any missing encoder
// sample). PeggingRow::kAuto treats the first row as pegging when it holds exactly the same value in every
// cycle (a measured, noisy sample never does) and the table has at least two cycles.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/formats/run_dir.hpp"

namespace noisemon::cli::formats {

struct CycleTable {
  std::vector<double> crank_deg;                // one per row, strictly increasing, uniform step
  std::vector<std::vector<double>> cycles_bar;  // one vector per cycle (column), crank_deg.size() values each
  std::size_t first_data_line = 1;              // line number of the first row (after a header line, if any)
};

// Reads a table; throws RunDirError naming the file, the line and column and what was expected (a numeric
// table of at least two columns, the same number of columns on every line, crank angle increasing in a uniform
// step covering exactly 720 degrees). Up to 20 header lines of text before the first row of numbers (names,
// units, a title) and lines starting with '#' are skipped.
CycleTable read_cycle_table(const std::filesystem::path& file);
CycleTable parse_cycle_table(std::string_view text, const std::string& file);

enum class PeggingRow { kAuto, kFirstRow, kNone };

// Whether the first row is a pegging value, not a sample (PeggingRow::kAuto: the same value in every one of two or
// more cycles).
bool drops_pegging_row(const CycleTable& table, PeggingRow pegging);

struct CycleTableOptions {
  double speed_rpm = 0.0;  // required: the speed the cycles were recorded at
  double tdc_deg = 0.0;    // table crank angle of firing TDC (0 for the Yanmar tables, 360 for 0..720 tables)
  PeggingRow pegging = PeggingRow::kAuto;
  drivers::formats::RunCondition condition;  // name, load, SOI, rail pressure, motored (speed_rpm is taken from above)
};

struct CycleTableConversion {
  drivers::formats::RunDir run;
  bool pegging_row_dropped = false;
  std::size_t cycles = 0;
};

// The table's cycles as a pressure-only run directory (no microphones).
CycleTableConversion cycle_table_to_run(const CycleTable& table, const CycleTableOptions& options,
                                        const std::string& file);

}  // namespace noisemon::cli::formats
