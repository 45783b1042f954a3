#include "cli/tdc_command.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>

#include "cli/formats/cycle_table.hpp"
#include "cli/formats/recording.hpp"
#include "cli/import_export.hpp"
#include "drivers/formats/run_dir.hpp"

namespace noisemon::cli {
namespace {

constexpr double kRunGridStepDeg = 0.25;  // a run directory's cycles are put on this grid (the daemon's)

void print(const std::string& source, const model::MotoredTdc& t, const char* scale) {
  std::printf("%s: %d motored cycles, peak %.2f bar at %+.2f deg (%s)\n", source.c_str(), t.cycles, t.peak_bar,
              t.peak_deg, scale);
  std::printf("  firing TDC by the loss angle (%.2f deg): %+.2f deg\n", t.loss_angle_deg, t.tdc_by_loss_angle_deg);
  std::printf("  firing TDC by the polytropic fit (no loss angle): %+.2f deg (n %.3f, rms %.2f %%)\n",
              t.tdc_by_polytropic_deg, t.polytropic_exponent, 100 * t.fit_rms);
}

}  // namespace

std::vector<std::vector<double>> motored_cycles_bar(const std::vector<double>& crank_deg,
                                                    const std::vector<double>& pressure_pa, double step_deg) {
  std::vector<std::vector<double>> cycles;
  if (crank_deg.size() < 2) return cycles;
  const auto points = static_cast<std::size_t>(std::lround(720.0 / step_deg));
  std::size_t j = 0;
  for (double k = std::ceil((crank_deg.front() + 360.0) / 720.0); 720.0 * k + 360.0 <= crank_deg.back(); k += 1.0) {
    std::vector<double> cycle(points);
    for (std::size_t i = 0; i < points; ++i) {
      const double a = 720.0 * k - 360.0 + step_deg * static_cast<double>(i);
      while (j + 2 < crank_deg.size() && crank_deg[j + 1] < a) ++j;
      const double x = (a - crank_deg[j]) / (crank_deg[j + 1] - crank_deg[j]);
      cycle[i] = (pressure_pa[j] + std::clamp(x, 0.0, 1.0) * (pressure_pa[j + 1] - pressure_pa[j])) / 1e5;
    }
    cycles.push_back(std::move(cycle));
  }
  return cycles;
}

model::MotoredTdc motored_run_tdc(const std::string& path, double loss_angle_deg) {
  drivers::formats::RunDir run;
  if (std::filesystem::is_directory(path)) {
    run = drivers::formats::read_run_dir(path);
  } else {  // a raw log the daemon recorded while motoring: its first run, unwrapped as export writes it
    const std::vector<formats::Recording> recs = formats::read_recordings_log(path);
    if (recs.front().operating_points.front().motored == false &&
        recs.front().operating_points.front().soi_deg_btdc > 0)
      throw std::runtime_error(path + ": the log's first run was fired (its operating point); record a motored run");
    run = formats::to_run_dir(recs.front());
  }
  if (run.condition.motored_known && !run.condition.motored)
    throw std::runtime_error(path + ": run.json says the engine was fired; give a motored run");
  const auto cycles = motored_cycles_bar(run.crank_deg, run.pressure_pa, kRunGridStepDeg);
  return model::motored_tdc(cycles, -360.0, kRunGridStepDeg, model::EngineGeometry{}, loss_angle_deg);
}

void write_tdc_deg(const std::string& path, double tdc_deg) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot read the configuration");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  char value[64];
  std::snprintf(value, sizeof value, "tdc_deg = %.2f", tdc_deg);
  const std::regex table(R"(^\s*\[([^\]]+)\]\s*(#.*)?$)"), key(R"(^\s*tdc_deg\s*=.*$)");
  std::size_t at = lines.size(), in_table = lines.size();
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::smatch m;
    if (std::regex_match(lines[i], m, table))
      in_table = m[1] == "combustion" ? i : lines.size();
    else if (in_table < lines.size() && std::regex_match(lines[i], key))
      at = i;
  }
  std::size_t combustion = lines.size();
  for (std::size_t i = 0; i < lines.size(); ++i) {
    std::smatch m;
    if (std::regex_match(lines[i], m, table) && m[1] == "combustion") combustion = i;
  }
  if (at < lines.size())
    lines[at] = value;
  else if (combustion < lines.size())
    lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(combustion) + 1, value);
  else
    lines.insert(lines.end(), {"", "[combustion]", value});
  std::ostringstream out;
  for (const std::string& l : lines) out << l << '\n';
  std::ofstream(path) << out.str();
}

TdcCommand::TdcCommand(CLI::App& app) {
  tdc_ = app.add_subcommand("tdc",
                            "thermodynamic TDC from motored cycles: the motored pressure peak plus the loss angle, "
                            "and a polytropic fit that needs none (model/motored_tdc.hpp)");
  CLI::Option* dir = tdc_->add_option("RUN", run_dir_,
                                      "a motored run directory, or a raw log (.lcmlog) the daemon "
                                      "recorded while motoring (its first run): the result is on the "
                                      "encoder's scale, [combustion] tdc_deg")
                         ->check(CLI::ExistingPath);
  CLI::Option* table = tdc_->add_option("--cycles-table", table_, "a motored cycle table instead (its own scale)")
                           ->check(CLI::ExistingFile)
                           ->excludes(dir);
  tdc_->add_option("--tdc-deg", table_tdc_deg_, "the table's nominal angle of firing TDC")
      ->capture_default_str()
      ->needs(table);
  tdc_->add_option("--loss-angle-deg", loss_angle_deg_,
                   "how far before TDC the motored peak lies (0 ... 3; measured "
                   "0.4 ... 1.3)")
      ->capture_default_str();
  tdc_->add_option("--write-config", write_config_,
                   "set [combustion] tdc_deg in this TOML configuration (by the loss "
                   "angle; the rest of the file kept)")
      ->check(CLI::ExistingFile)
      ->excludes(table);
  tdc_->footer(
      "Examples:\n"
      "  noisemon tdc runs/motored_1800 --write-config /etc/noisemon/noisemond.toml\n"
      "  noisemon tdc --cycles-table yanmar_l100v_motored.txt");
}

int TdcCommand::run() {
  if (!tdc_->parsed()) return -1;
  try {
    if (run_dir_.empty() == table_.empty()) {
      std::fprintf(stderr, "noisemon tdc: give a motored run directory or --cycles-table FILE\n");
      return 2;
    }
    if (!table_.empty()) {
      print(table_, motored_table_tdc(formats::read_cycle_table(table_), table_, table_tdc_deg_, loss_angle_deg_),
            "the table's scale");
      return 0;
    }
    const model::MotoredTdc t = motored_run_tdc(run_dir_, loss_angle_deg_);
    print(run_dir_, t, "the encoder's scale");
    if (!write_config_.empty()) {
      write_tdc_deg(write_config_, t.tdc_by_loss_angle_deg);
      std::printf("wrote [combustion] tdc_deg = %.2f into %s\n", t.tdc_by_loss_angle_deg, write_config_.c_str());
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "noisemon tdc: %s\n", e.what());
    return 1;
  }
}

}  // namespace noisemon::cli
