#include "cli/import_export.hpp"
#include "cli/tdc_command.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>
#include <stdexcept>

#include "cli/sim_run.hpp"
#include "drivers/source.hpp"

namespace noisemon::cli {
namespace {

namespace fs = std::filesystem;

// "label  42%" redrawn on stderr at most every 100 ms, only when stderr is a terminal.
class PercentProgress {
 public:
  explicit PercentProgress(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO)) {}
  ~PercentProgress() { done(); }
  void stage(std::string label) {
    label_ = std::move(label);
    last_ = {};
    show(0.0);
  }
  void show(double fraction) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (fraction < 1.0 && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    std::fprintf(stderr, "\r\033[K%s %3.0f%%", label_.c_str(), 100.0 * std::clamp(fraction, 0.0, 1.0));
    drawn_ = true;
  }
  formats::ProgressFn fn() {
    if (!enabled_) return {};
    return [this](double f) { show(f); };
  }
  void done() {
    if (drawn_) std::fprintf(stderr, "\n");
    drawn_ = false;
  }

 private:
  bool enabled_;
  bool drawn_ = false;
  std::string label_;
  std::chrono::steady_clock::time_point last_{};
};

// Removes a half-written output when the import fails.
class OutputGuard {
 public:
  explicit OutputGuard(std::string path) : path_(std::move(path)) {}
  ~OutputGuard() {
    if (!kept_) {
      std::error_code ec;
      fs::remove(path_, ec);
    }
  }
  void keep() { kept_ = true; }

 private:
  std::string path_;
  bool kept_ = false;
};

std::int64_t first_epoch(std::int64_t requested) { return requested != 0 ? requested : drivers::wall_utime(); }

// The next run starts a second after this one ends, so the log's time stamps keep increasing.
std::int64_t next_epoch(const formats::Recording& rec) {
  const double end_s =
      static_cast<double>(rec.first_index + static_cast<std::int64_t>(rec.frames())) / drivers::kPipelineRateHz;
  return rec.info.epoch_utime + std::llround(end_s * 1e6) + 1'000'000;
}

void synthesize(const MicSynthesizer& synth, formats::Recording& rec) {
  if (!synth) return;
  const std::size_t frames = rec.frames();
  synth(rec);
  if (rec.frames() != frames || rec.info.mic_count == 0 || rec.mics_pa.size() != frames * rec.info.mic_count ||
      rec.info.mic_positions_m.size() != rec.info.mic_count)
    throw std::logic_error("microphone synthesizer left the recording inconsistent");
}

// Cycle reports `noisemon replay` will give: one per pair of consecutive crank wraps (the stretch before the
// first wrap only warms the filters up; the one after the last never closes).
std::size_t expected_reports(const formats::Recording& rec) {
  std::size_t wraps = 0;
  for (std::size_t i = 1; i < rec.crank_deg.size(); ++i)
    if (rec.crank_deg[i] < rec.crank_deg[i - 1] - 360.0) ++wraps;
  return wraps > 0 ? wraps - 1 : 0;
}

ImportedRun describe(const std::string& source, const formats::Recording& rec) {
  return {source, rec.condition, rec.info.epoch_utime, rec.frames(), rec.info.mic_count};
}

// A condition value for import's messages: "n/a" when unknown (NaN).
std::string value_text(double v, const char* unit) {
  if (std::isnan(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g %s", v, unit);
  return buf;
}

// What became of a run's null values (nothing to say when it has none): unknowns are n/a, a null speed is
// measured from the encoder, a null `motored` is published as false.
void note_unknowns(const std::string& dir, const drivers::formats::RunCondition& c, const drivers::OperatingPoint& op,
                   std::vector<std::string>& notes) {
  const bool speed_null = std::isnan(c.speed_rpm);
  if (!speed_null && !std::isnan(c.load_nm) && !std::isnan(c.soi_deg_btdc) && c.rail_pressure_bar && c.motored_known)
    return;
  notes.push_back(dir + ": condition '" + c.name + "' (null in run.json: n/a): speed " +
                  value_text(op.speed_rpm, "rpm") +
                  (speed_null ? " (speed_rpm null: measured from the encoder, mean over the run)" : "") + ", load " +
                  value_text(c.load_nm, "N m") + ", SOI " + value_text(c.soi_deg_btdc, "deg BTDC") +
                  ", rail pressure " + (c.rail_pressure_bar ? value_text(*c.rail_pressure_bar, "bar") : "n/a") +
                  ", motored " + (c.motored_known ? (c.motored ? "yes" : "no") : "n/a"));
  if (!c.motored_known)
    notes.push_back(dir +
                    ": condition.motored is null: published as false (the operating point's field is a boolean); "
                    "noisemon diagnose needs it and refuses this run directory until it is true or false");
}

std::string dir_name_for(const std::string& condition, std::size_t index) {
  std::string s;
  for (char c : condition)
    s += (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_') ? c : '_';
  if (s.empty() || s == "." || s == "..") s = "run" + std::to_string(index);
  return s;
}

// The motored table's thermodynamic TDC on the tables' scale (about the nominal tdc_deg), for the fired table:
// the same resolution and (within 2 %) speed, or a clear error naming the file.
model::MotoredTdc table_tdc(const CycleTableImportOptions& o, const formats::CycleTable& fired) {
  const formats::CycleTable m = formats::read_cycle_table(o.motored_table);
  const auto step = [](const formats::CycleTable& t) {
    return (t.crank_deg.back() - t.crank_deg.front()) / static_cast<double>(t.crank_deg.size() - 1);
  };
  if (std::abs(step(m) - step(fired)) > 1e-6 * step(fired))
    throw std::runtime_error(o.motored_table + ": " + value_text(step(m), "deg") + " steps, the fired table " +
                             o.table + " has " + value_text(step(fired), "deg") +
                             ": give a motored table of the same resolution");
  const double rpm = o.motored_rpm > 0 ? o.motored_rpm : o.table_options.speed_rpm;
  if (std::abs(rpm / o.table_options.speed_rpm - 1.0) > 0.02)
    throw std::runtime_error(o.motored_table + ": motored at " + value_text(rpm, "rpm") + ", the fired table at " +
                             value_text(o.table_options.speed_rpm, "rpm") +
                             ": the loss angle depends on speed; record the motored cycles at the fired speed");
  return motored_table_tdc(m, o.motored_table, o.table_options.tdc_deg, o.loss_angle_deg);
}

void note_tdc(const model::MotoredTdc& t, std::vector<std::string>& notes) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "thermodynamic TDC from %d motored cycles: peak %.2f bar at %+.2f deg; + loss angle %.2f deg = "
                "%+.2f deg (used: the fired angles move by %+.2f deg); the polytropic fit, which needs no loss angle: "
                "%+.2f deg (n %.3f)",
                t.cycles, t.peak_bar, t.peak_deg, t.loss_angle_deg, t.tdc_by_loss_angle_deg, -t.tdc_by_loss_angle_deg,
                t.tdc_by_polytropic_deg, t.polytropic_exponent);
  notes.push_back(buf);
}

}  // namespace

MicSynthesizer mic_synthesizer(const std::string& name) {
  if (name == "sim")
    return [](formats::Recording& rec) {
      // The virtual engine's acoustic side driven by the imported pressure, with its default installation
      // (thesis microphone layout, linear true block, no effects). The virtual engine is set up with the run's
      // load and SOI: an unknown one is named rather than replaced by a made-up number.
      const drivers::OperatingPoint op =
          rec.operating_points.empty() ? drivers::OperatingPoint{} : rec.operating_points.front();
      for (const auto& [value, key] : {std::pair{op.load_nm, "load_nm"}, std::pair{op.soi_deg_btdc, "soi_deg_btdc"}})
        if (std::isnan(value))
          throw std::invalid_argument(std::string("--mics sim: the virtual engine needs condition.") + key +
                                      ", which is null (unknown)");
      const cli::SimRunSpec installation;  // the defaults
      cli::synthesize_recording_mics(rec, installation);
    };
  throw std::invalid_argument("--mics " + name + ": unknown, expected \"sim\"");
}

model::MotoredTdc motored_table_tdc(const formats::CycleTable& table, const std::string& file, double nominal_tdc_deg,
                                    double loss_angle_deg) {
  const bool drop = formats::drops_pegging_row(table, formats::PeggingRow::kAuto);
  std::vector<std::vector<double>> cycles;
  for (const std::vector<double>& c : table.cycles_bar) cycles.emplace_back(c.begin() + (drop ? 1 : 0), c.end());
  const double step =
      (table.crank_deg.back() - table.crank_deg.front()) / static_cast<double>(table.crank_deg.size() - 1);
  try {
    return model::motored_tdc(cycles, table.crank_deg[drop ? 1 : 0] - nominal_tdc_deg, step, model::EngineGeometry{},
                              loss_angle_deg);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(file + ": " + e.what());
  }
}

ImportSummary run_import(const ImportOptions& o) {
  if (o.run_dirs.empty()) throw std::invalid_argument("import: no run directory given");
  ImportSummary sum;
  OutputGuard guard(o.out_log);
  formats::RecordingLogWriter writer(o.out_log, o.channels);
  PercentProgress progress(o.progress);
  std::int64_t epoch = first_epoch(o.epoch_utime);
  if (!o.motored_run.empty()) {
    progress.stage("import: thermodynamic TDC from " + o.motored_run);
    sum.tdc = motored_run_tdc(o.motored_run, o.loss_angle_deg);
    note_tdc(*sum.tdc, sum.notes);
  }
  for (std::size_t i = 0; i < o.run_dirs.size(); ++i) {
    const std::string& dir = o.run_dirs[i];
    const std::string prefix =
        "import " + std::to_string(i + 1) + "/" + std::to_string(o.run_dirs.size()) + " " + dir + ":";
    progress.stage(prefix + " reading");
    formats::Recording rec;
    {
      drivers::formats::RunDir run = drivers::formats::read_run_dir(dir);
      if (sum.tdc)  // firing TDC at the encoder's tdc: the piston's angle is the encoder's less it
        for (double& a : run.crank_deg) a -= sum.tdc->tdc_by_loss_angle_deg;
      const drivers::formats::RunCondition condition = run.condition;
      progress.stage(prefix + " resampling to 40 kHz");
      rec = formats::to_recording(std::move(run), epoch);  // frees the run's samples as they are resampled
      note_unknowns(dir, condition, rec.operating_points.front(), sum.notes);
    }
    try {
      synthesize(o.synthesize_mics, rec);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(dir + ": " + e.what());
    }
    progress.stage(prefix + " writing");
    writer.write(rec, progress.fn());
    sum.runs.push_back(describe(dir, rec));
    if (rec.info.mic_count == 0)
      sum.notes.push_back(dir + ": no microphones: replay reports CPL and predicted levels, measured levels are n/a");
    epoch = next_epoch(rec);
  }
  progress.done();
  guard.keep();
  return sum;
}

ImportSummary run_import_cycle_table(const CycleTableImportOptions& o) {
  ImportSummary sum;
  PercentProgress progress(o.progress);
  progress.stage("import " + o.table + ": reading");
  const formats::CycleTable table = formats::read_cycle_table(o.table);
  formats::CycleTableOptions to = o.table_options;
  if (!o.motored_table.empty()) {
    progress.stage("import " + o.table + ": thermodynamic TDC from " + o.motored_table);
    const model::MotoredTdc tdc = table_tdc(o, table);
    to.tdc_deg += tdc.tdc_by_loss_angle_deg;
    sum.tdc = tdc;
    note_tdc(tdc, sum.notes);
  }
  if (to.condition.name.empty()) to.condition.name = fs::path(o.table).stem().string();
  const formats::CycleTableConversion conv = formats::cycle_table_to_run(table, to, o.table);
  progress.stage("import " + o.table + ": resampling to 40 kHz");
  formats::Recording rec = formats::to_recording(conv.run, first_epoch(o.epoch_utime));
  synthesize(o.synthesize_mics, rec);
  OutputGuard guard(o.out_log);
  formats::RecordingLogWriter writer(o.out_log, o.channels);
  progress.stage("import " + o.table + ": writing");
  writer.write(rec, progress.fn());
  progress.done();
  guard.keep();
  sum.runs.push_back(describe(o.table, rec));
  char buf[512];
  const double step =
      (table.crank_deg.back() - table.crank_deg.front()) / static_cast<double>(table.crank_deg.size() - 1);
  std::snprintf(buf, sizeof buf, "%zu cycles of %zu rows (%.3g deg steps, %.0f Hz at %.1f rpm); first row %s",
                conv.cycles, table.crank_deg.size(), step, 6.0 * to.speed_rpm / step, to.speed_rpm,
                conv.pegging_row_dropped ? "taken as the pegging value and dropped" : "kept as a sample");
  sum.notes.push_back(buf);
  std::snprintf(buf, sizeof buf,
                "replay will report %zu cycles, each one column whole: the pipeline's cycles run from -360 to +360 deg "
                "and are counted from boundary to boundary, so the first column only warms the filters up and the "
                "last has no boundary after it",
                expected_reports(rec));
  sum.notes.push_back(buf);
  if (rec.info.mic_count == 0)
    sum.notes.push_back("no microphones: replay reports CPL and predicted levels, measured levels are n/a");
  return sum;
}

ExportSummary run_export(const ExportOptions& o) {
  ExportSummary sum;
  PercentProgress progress(o.progress);
  progress.stage("export " + o.log + ": reading");
  std::vector<formats::Recording> recs =
      formats::read_recordings_log(o.log, o.channels, nullptr, &sum.stats, progress.fn());
  // Name every directory and check them all before writing anything.
  std::vector<fs::path> dirs;
  std::set<std::string> used;
  for (std::size_t i = 0; i < recs.size(); ++i) {
    if (recs.size() == 1) {
      dirs.emplace_back(o.out_dir);
      break;
    }
    const std::string base = dir_name_for(recs[i].condition, i);
    std::string name = base;
    for (int n = 2; used.count(name); ++n) name = base + "_" + std::to_string(n);
    used.insert(name);
    dirs.push_back(fs::path(o.out_dir) / name);
  }
  for (const fs::path& d : dirs)
    if (!o.force && fs::exists(d / "run.json"))
      throw std::runtime_error((d / "run.json").string() + ": exists; not overwritten (use --force)");
  for (std::size_t i = 0; i < recs.size(); ++i) {
    progress.stage("export " + dirs[i].string() + ": writing");
    drivers::formats::write_run_dir(dirs[i], formats::to_run_dir(recs[i]), o.pressure_units);
    recs[i] = formats::Recording{};
    sum.run_dirs.push_back(dirs[i].string());
  }
  progress.done();
  return sum;
}

}  // namespace noisemon::cli
