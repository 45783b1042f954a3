// The independent test cell's writers (see cell_synth.hpp): run.json, pressure.csv and mics.wav of a run directory,
// in the interchange format of docs/sources-and-formats.md, by the cell's own code (nlohmann-json, libsndfile).
#include <sndfile.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "cell_synth.hpp"

namespace indep {
namespace {

constexpr double kFiredLoadNm = 18.0;  // the record's operating point (data README)
constexpr double kSoiDegBtdc = 9.6;
constexpr double kRailBar = 470.0;

nlohmann::ordered_json run_json(const Run& run, const Chain& chain) {
  using json = nlohmann::ordered_json;
  const Condition& c = run.condition;
  json cond = {{"name", c.name}, {"speed_rpm", run.time.speed_rpm}};
  cond["load_nm"] = c.motored ? json(0.0) : c.load_unknown ? json(nullptr) : json(kFiredLoadNm * c.load_scale);
  cond["soi_deg_btdc"] = c.motored ? json(nullptr) : json(kSoiDegBtdc);
  cond["rail_pressure_bar"] = c.motored ? json(nullptr) : json(kRailBar);
  cond["motored"] = c.motored;
  json positions = json::array();
  for (const auto& p : mic_positions_m()) positions.push_back({p[0], p[1], p[2]});
  json pressure = {{"file", "pressure.csv"}, {"units", "bar"}};
  if (std::isfinite(run.stated_floor_bar)) pressure["noise_floor_bar"] = run.stated_floor_bar;
  return {{"condition", cond},
          {"pressure", pressure},
          {"mics", {{"file", "mics.wav"}, {"units", "Pa"}, {"positions_m", positions}, {"radius_m", chain.radius_m}}},
          {"source",
           "tests/independent/cell_synth: real Yanmar L100V pressure record, eq. 4.1 with the cell's own constants in "
           "the frequency domain"}};
}

void write_pressure_csv(const Run& run, const std::filesystem::path& file) {
  std::string text = "time_s,crank_deg,pressure\n";
  const std::vector<double>& p = run.pressure.recorded_bar;
  text.reserve(p.size() * 40);
  char line[96];
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double t = static_cast<double>(i) * run.time.period_s / static_cast<double>(p.size());
    std::snprintf(line, sizeof line, "%.9f,%.1f,%.6f\n", t, -360.0 + kRecordStepDeg * static_cast<double>(i), p[i]);
    text += line;
  }
  std::ofstream out(file, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error(file.string() + ": cannot write");
}

void write_wav(const Run& run, const std::filesystem::path& file) {
  SF_INFO info{};
  info.samplerate = static_cast<int>(run.fs_hz);
  info.channels = static_cast<int>(run.mics_pa.size());
  info.format = SF_FORMAT_WAV | SF_FORMAT_FLOAT;
  SNDFILE* sf = sf_open(file.c_str(), SFM_WRITE, &info);
  if (!sf) throw std::runtime_error(file.string() + ": cannot write (" + sf_strerror(nullptr) + ")");
  const std::size_t n = run.time.n_out, ch = run.mics_pa.size();
  std::vector<float> frames(n * ch);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t m = 0; m < ch; ++m) frames[i * ch + m] = static_cast<float>(run.mics_pa[m][i]);
  const sf_count_t written = sf_writef_float(sf, frames.data(), static_cast<sf_count_t>(n));
  sf_close(sf);
  if (written != static_cast<sf_count_t>(n)) throw std::runtime_error(file.string() + ": short write");
}

}  // namespace

void write_run_dir(const Run& run, const Chain& chain, const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "run.json") << run_json(run, chain).dump(2) << "\n";
  write_pressure_csv(run, dir / "pressure.csv");
  write_wav(run, dir / "mics.wav");
}

std::vector<std::filesystem::path> write_campaign(const Sources& src, const std::vector<Condition>& conditions,
                                                  const Chain& chain, const Effects& fx,
                                                  const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> out;
  for (std::size_t i = 0; i < conditions.size(); ++i) {
    const Run run = synthesize(src, conditions[i], static_cast<int>(i), chain, fx);
    out.push_back(dir / conditions[i].name);
    write_run_dir(run, chain, out.back());
  }
  return out;
}

}  // namespace indep
