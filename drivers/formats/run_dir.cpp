#include "drivers/formats/run_dir.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "drivers/formats/mapped_file.hpp"
#include "drivers/formats/mics_wav.hpp"
#include "drivers/formats/pressure_csv.hpp"
#include "drivers/formats/run_both.hpp"

namespace noisemon::drivers::formats {
namespace {

std::string read_text_file(const std::filesystem::path& file, const char* what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw RunDirError(file.string() + ": cannot open " + what + " (" + std::strerror(errno) + ")");
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw RunDirError(file.string() + ": read error");
  return std::move(s).str();
}

}  // namespace

RunManifest read_run_manifest(const std::filesystem::path& dir) {
  const std::filesystem::path json_path = dir / "run.json";
  return parse_run_json(read_text_file(json_path, "run.json (is this a run directory?)"), json_path.string());
}

namespace {

// DIR's pressure file into run, its rows' mean speed checked against run.json's.
void read_pressure(const std::filesystem::path& dir, const RunManifest& m, RunDir& run) {
  const std::filesystem::path csv = dir / m.pressure_file;
  if (const MappedFile map(csv); map.mapped())
    parse_pressure_text(map.text(), csv.string(), m.pressure_to_pa, run, &map);
  else  // not a regular file, empty, or not there: the reader names the problem
    parse_pressure_csv(read_text_file(csv, "the pressure file named by pressure.file in run.json"), csv.string(),
                       m.pressure_to_pa, run);
  // The rows' mean speed must be the declared one: otherwise time_s or crank_deg is in other units (ms, rad)
  // or rows are missing, and every frequency downstream would be silently wrong. (A null speed is unknown: the
  // rows' speed is then the run's.)
  const double mean_rpm = encoder_speed_rpm(run);
  if (!std::isnan(m.condition.speed_rpm) &&
      !(std::abs(mean_rpm - m.condition.speed_rpm) <= kSpeedTolerance * m.condition.speed_rpm)) {
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  ": the rows imply %.6g rpm (crank_deg %.6g..%.6g over time_s %.9g..%.9g s), run.json's "
                  "condition.speed_rpm is %.6g (expected within %.0f %%: time in s, crank angle in deg)",
                  mean_rpm, run.crank_deg.front(), run.crank_deg.back(), run.time_s.front(), run.time_s.back(),
                  m.condition.speed_rpm, 100 * kSpeedTolerance);
    throw RunDirError(csv.string() + buf);
  }
}

}  // namespace

RunDir read_run_dir(const std::filesystem::path& dir) {
  const RunManifest m = read_run_manifest(dir);
  RunDir run;
  run.condition = m.condition;
  // The microphones are read on another thread while the pressure is parsed (each fills its own members of run);
  // a problem with the pressure file is still reported before one with the microphones'.
  run_both([&] { read_pressure(dir, m, run); },
           [&] {
             if (m.has_mics)
               read_mics_wav(dir / m.mics_file, static_cast<std::uint32_t>(m.mic_positions_m.size()), m.full_scale_pa,
                             run);
           });
  if (m.has_mics) {
    run.mic_positions_m = m.mic_positions_m;
    run.radius_m = m.radius_m;
    run.acoustic_delay_s = m.acoustic_delay_s;
    run.mic_passband_hz = m.mic_passband_hz;
  }
  run.pressure_noise_floor_bar = m.pressure_noise_floor_bar;
  run.pressure_edges_per_rev = m.pressure_edges_per_rev;
  return run;
}

double encoder_speed_rpm(const RunDir& run) {
  const std::size_t n = std::min(run.time_s.size(), run.crank_deg.size());
  if (n < 2) return std::numeric_limits<double>::quiet_NaN();
  return (run.crank_deg[n - 1] - run.crank_deg.front()) / (run.time_s[n - 1] - run.time_s.front()) / 6.0;
}

void write_run_dir(const std::filesystem::path& dir, const RunDir& run, const std::string& pressure_units) {
  double from_pa;
  if (pressure_units == "bar")
    from_pa = 1e-5;
  else if (pressure_units == "Pa")
    from_pa = 1.0;
  else
    throw RunDirError(dir.string() + ": pressure units \"" + pressure_units + "\", expected \"bar\" or \"Pa\"");
  const std::size_t n = run.time_s.size();
  if (run.crank_deg.size() != n || run.pressure_pa.size() != n)
    throw RunDirError(dir.string() + ": time, crank and pressure columns of different lengths");
  if (run.mic_count > 0 && (run.mic_positions_m.size() != run.mic_count || run.mic_pa.size() % run.mic_count != 0))
    throw RunDirError(dir.string() + ": microphone data does not match the " + std::to_string(run.mic_count) +
                      " positions");
  if (const auto& floor = run.pressure_noise_floor_bar; floor && !(*floor >= 0 && std::isfinite(*floor)))
    throw RunDirError(dir.string() + ": pressure noise floor " + std::to_string(*floor) +
                      " bar, expected a finite value >= 0");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw RunDirError(dir.string() + ": cannot create directory (" + ec.message() + ")");

  {
    const auto path = dir / "run.json";
    std::ofstream out(path);
    out << run_json_text(run, pressure_units);
    if (!out) throw RunDirError(path.string() + ": cannot write");
  }
  write_pressure_csv(dir / "pressure.csv", run, from_pa);
  if (run.mic_count > 0) write_mics_wav(dir / "mics.wav", run);
}

}  // namespace noisemon::drivers::formats
