#include "cli/diagnose_command.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>

#include "cli/band_data.hpp"
#include "cli/cli_support.hpp"
#include "cli/fit_command.hpp"
#include "cli/report/diagnosis_report.hpp"
#include "cli/report/report_html.hpp"
#include "daemon/params_file.hpp"
#include "model/diagnosis/diagnosis.hpp"
#include "model/diagnosis/waveform_diagnosis.hpp"
#include "model/fit/band_fit.hpp"
#include "model/fit/pressure_floor.hpp"

namespace noisemon::cli {
namespace {

namespace fs = std::filesystem;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// Both files are written whole to temporary names and renamed: a failure leaves no half report.
void write_text(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw std::runtime_error(tmp.string() + ": cannot write");
    f << text;
    f.flush();
    if (!f) throw std::runtime_error(tmp.string() + ": write failed (disk full?)");
  }
  fs::rename(tmp, path);
}

void check_out_dir(const DiagnoseOptions& o) {
  if (o.out_dir.empty()) throw std::runtime_error("no output directory (-o DIR)");
  const fs::path dir(o.out_dir);
  if (fs::exists(dir) && !fs::is_directory(dir)) throw std::runtime_error("-o " + o.out_dir + ": not a directory");
  if (!o.force && fs::exists(dir / "report.json"))
    throw std::runtime_error((dir / "report.json").string() + " already exists; use --force to replace it");
}

void print_band_summary(std::FILE* out, const model::diagnosis::DiagnosisResult& r) {
  std::fprintf(out, "baseline %s (tuned): train %.2f dB, held-out gap %.2f dB (thesis metric %.2f dB)%s\n",
               r.model_name.c_str(), r.baseline.train_rms_db, r.baseline.heldout_gap_db,
               r.baseline.heldout_thesis_rms_db,
               std::isfinite(r.baseline.heldout_group_gap_db)
                   ? fmt("; leaving out one speed at a time %.2f dB", r.baseline.heldout_group_gap_db).c_str()
                   : "");
  // parameters: every fitted quantity (the block's four and the extension's), so that a flexible candidate's gap is
  // read beside what it took to get there.
  // group dB: the gap leaving out one operating speed at a time ("-": no speed holds several conditions). dIC: the
  // information criterion over the baseline's (negative: the closed gap pays for the parameters).
  std::fprintf(out, "%-18s %10s %10s %10s %8s %12s %11s %8s\n", "candidate", "gap dB", "thesis dB", "group dB",
               "closed", "significant", "parameters", "dIC");
  auto row = [&](const model::diagnosis::ModelScore& c) {
    const char* significant = c.significant ? "yes" : c.refuted ? "refuted" : "no";
    const std::string group = std::isfinite(c.heldout_group_gap_db) ? fmt("%.2f", c.heldout_group_gap_db) : "-";
    std::fprintf(out, "%-18s %10.2f %10.2f %10s %7.0f%% %12s %11d %8.0f\n", c.name.c_str(), c.heldout_gap_db,
                 c.heldout_thesis_rms_db, group.c_str(), 100.0 * c.gap_closed_fraction, significant, c.parameters,
                 c.information_criterion - r.baseline.information_criterion);
  };
  for (const auto& c : r.candidates) row(c);
  for (const auto& c : r.combinations) row(c);
  const model::diagnosis::Verdict& v = r.verdict;
  std::string also;
  for (const auto& a : v.also) also += " + " + a;
  std::fprintf(out,
               "verdict: %s%s  held-out gap %.2f -> %.2f dB (%.0f %% closed; thesis metric %.2f -> %.2f dB; "
               "noise %.2f dB)\n  %s\n",
               v.effect.c_str(), also.c_str(), v.heldout_rms_before_db, v.heldout_rms_after_db,
               100.0 * v.gap_closed_fraction, v.heldout_thesis_before_db, v.heldout_thesis_after_db, v.noise_db,
               v.explanation.c_str());
  std::fprintf(out, "  %s\n", v.remaining.summary.c_str());
  std::fprintf(out, "%.1f s\n", r.seconds);
}

// Which pressure-chain floor each run is judged by, and the cells at a floor.
void print_floors(std::FILE* out, const model::fit::BandDataset& data, const model::diagnosis::Where& w) {
  for (std::size_t k = 0; k < data.conditions.size() && k < w.pressure_floor_judged_by.size(); ++k) {
    const std::string stated = std::isfinite(w.pressure_floor_stated_bar[k])
                                   ? fmt("%.4g bar", w.pressure_floor_stated_bar[k])
                                   : std::string("not stated");
    const std::string est = std::isfinite(w.pressure_floor_estimated_bar[k])
                                ? fmt("%.4g bar rms per encoder sample", w.pressure_floor_estimated_bar[k])
                                : fmt("%.4g bar rms on the 40 kHz grid", w.pressure_floor_estimated_grid_bar[k]);
    std::fprintf(out, "pressure floor %-16s %s; estimated %s (judged by the %s floor)\n",
                 data.conditions[k].info.name.c_str(), stated.c_str(), est.c_str(),
                 w.pressure_floor_judged_by[k].c_str());
  }
  std::fprintf(out, "microphone floor from the %s\n", w.mic_floor_source.c_str());
  for (const std::string& line : w.floor_summary) std::fprintf(out, "  %s\n", line.c_str());
}

// --pressure-floor: the stated floor of every run replaced (bar) or ignored ("estimate").
void override_pressure_floor(const std::string& text, model::fit::BandDataset& data) {
  if (text.empty()) return;
  double bar = std::numeric_limits<double>::quiet_NaN();
  if (text != "estimate") {
    char* end = nullptr;
    bar = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0' || !(bar >= 0.0) || !std::isfinite(bar))
      throw std::runtime_error("--pressure-floor " + text +
                               ": expected bar rms per encoder sample (>= 0) or 'estimate'");
  }
  for (model::fit::ConditionData& d : data.conditions) d.info.pressure_floor_pa = bar * 1e5;
  model::fit::judge_pressure_floors(data);
}

nlohmann::json diagnose_band(const DiagnoseOptions& o, const report::ReportContext& ctx, std::FILE* out) {
  if (o.fs_hz > 0.0) throw std::runtime_error("--fs applies to waveform mode only");
  if (!o.tests.empty()) throw std::runtime_error("--test applies to waveform mode only");
  model::diagnosis::DiagnosisOptions opt;
  opt.train = flatten_lists(o.train);
  opt.holdout = flatten_lists(o.holdout);
  opt.fit_cycles = o.fit_cycles;
  opt.bootstrap = o.bootstrap;
  opt.seed = o.seed;
  opt.tolerance_db = o.tolerance_db;
  if (!o.candidates.empty()) {
    opt.candidates = split_list(o.candidates);
    const auto& known = model::diagnosis::candidate_effects();
    for (const auto& c : opt.candidates)
      if (std::find(known.begin(), known.end(), c) == known.end()) {
        std::string list;
        for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
        throw std::runtime_error("--candidates: unknown effect '" + c + "' (expected " + list + ")");
      }
  }
  opt.free = parse_free_option(o.free);
  std::string model_name = o.model.empty() ? "linear" : o.model;
  const model::BlockParams start = daemon::resolve_model(model_name, &model_name);

  ProgressLine line(o.progress);
  model::fit::BandDataset data = load_band_dataset(o.data, out, line);
  override_pressure_floor(o.pressure_floor, data);
  std::fprintf(out, "%zu condition(s), %zu bands\n", data.conditions.size(), data.band_count());
  opt.progress = [&](const std::string& stage) { line.show("diagnose: " + stage); };

  model::diagnosis::DiagnosisResult r;
  try {
    r = model::diagnosis::diagnose(data, start, model_name, opt);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string(e.what()) + " (the data hold " + condition_names(data) + ")");
  }
  line.done();
  print_floors(out, data, r.where);
  print_band_summary(out, r);
  return report::band_report_json(data, r, opt, ctx);
}

nlohmann::json diagnose_waveform(const DiagnoseOptions& o, const report::ReportContext& ctx, std::FILE* out) {
  if (!(o.fs_hz > 0.0))
    throw std::runtime_error("--fs: the sample rate of the waveform (Hz) is required in waveform mode");
  std::vector<std::pair<std::string, std::string>> test_specs;
  for (const std::string& t : o.tests) {
    const auto eq = t.find('=');
    if (eq == std::string::npos || eq == 0) throw std::runtime_error("--test " + t + ": expected NAME=A:B");
    test_specs.emplace_back(t.substr(0, eq), t.substr(eq + 1));
  }
  const WaveformData data = load_waveform_data(o.data, o.train, o.holdout, o.settle, out);
  if (data.heldout.empty()) throw std::runtime_error("nothing is held out: give --holdout (ranges A:B or DATA names)");
  std::vector<report::WaveformTestSet> tests;
  for (const auto& [name, range] : test_specs) tests.push_back({name, parse_range(range, data, "--test"), 0.0, 0.0});

  model::diagnosis::WaveformDiagnosisOptions opt;
  opt.fs_hz = o.fs_hz;
  opt.train = data.train;
  opt.heldout = data.heldout;
  opt.sim.settle_samples = o.settle;
  opt.max_iterations = o.max_iterations;
  opt.seed = o.seed;
  if (!o.free.empty()) opt.baseline_free = split_list(o.free);
  if (!o.candidates.empty()) opt.candidates = split_list(o.candidates);
  if (!o.model.empty()) {
    model::fit::WaveformModel m;
    m.block = daemon::resolve_model(o.model, &opt.start_name);
    opt.start = m;
  }
  ProgressLine line(o.progress);
  opt.log = [&](const std::string& s) { line.show("diagnose: " + s); };
  opt.fit_progress = [&](const model::fit::WaveformFitProgress& p) {
    line.show("diagnose: fit iteration " + std::to_string(p.iteration) + ", train RMS " + fmt("%.4g", p.train_rms));
  };
  model::diagnosis::WaveformDiagnosis d;
  try {
    d = model::diagnosis::diagnose_waveform(data.u, data.y, opt);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(e.what());
  }
  line.done();
  for (report::WaveformTestSet& t : tests) {
    const std::vector<model::fit::SampleRange> one = {t.range};
    model::fit::WaveformSimOptions sb = opt.sim, sa = opt.sim;
    sb.steps_per_sample = d.baseline.steps_per_sample;
    sa.steps_per_sample = d.best_steps_per_sample;
    t.baseline_rms = model::fit::free_run_errors(d.baseline.model, o.fs_hz, sb, data.u, data.y, one).front().rms();
    t.best_rms = model::fit::free_run_errors(d.best_model, o.fs_hz, sa, data.u, data.y, one).front().rms();
  }

  std::fprintf(out, "baseline (%s, tuned): train RMS %.4g, held-out RMS %.4g\n", d.baseline.start_name.c_str(),
               d.baseline.train_rms, d.baseline.heldout_rms);
  std::fprintf(out, "%-18s %12s %8s %10s %12s\n", "candidate", "held-out", "closed", "p", "significant");
  auto row = [&](const model::diagnosis::CandidateResult& c, const char* note) {
    std::fprintf(out, "%-18s %12.4g %7.0f%% %10.4f %12s%s\n", c.effect.c_str(), c.heldout_rms,
                 100.0 * c.gap_closed_fraction, c.test.p_value, c.significant ? "yes" : "no", note);
  };
  for (const auto& c : d.candidates) row(c, "");
  for (const auto& c : d.second_round) row(c, "  (on top of the first)");
  for (const auto& n : d.not_applicable)
    std::fprintf(out, "%-18s not applicable: %s\n", n.effect.c_str(), n.reason.c_str());
  std::fprintf(out, "verdict: %s  held-out RMS %.4g -> %.4g (%.0f %% closed)\n", d.verdict.c_str(),
               d.heldout_rms_before, d.heldout_rms_after,
               d.heldout_rms_before > 0 ? 100.0 * (1.0 - d.heldout_rms_after / d.heldout_rms_before) : 0.0);
  if (!tests.empty()) {
    std::size_t width = 28;
    for (const auto& t : tests) width = std::max(width, t.name.size() + 18);
    std::fprintf(out, "%-*s %12s %12s\n", static_cast<int>(width + 2), "free-run RMS on the test sets", "baseline",
                 "best model");
    for (const auto& t : tests)
      std::fprintf(out, "  %-*s %12.4g %12.4g\n", static_cast<int>(width),
                   (t.name + " [" + std::to_string(t.range.begin) + ":" + std::to_string(t.range.end) + ")").c_str(),
                   t.baseline_rms, t.best_rms);
  }
  std::fprintf(out, "%.1f s\n", d.seconds);
  return report::waveform_report_json(d, "data units (the CSV's y)", tests, ctx);
}

}  // namespace

DiagnoseOutcome run_diagnose(const DiagnoseOptions& o, std::FILE* out) {
  static std::FILE* const nowhere = std::fopen("/dev/null", "w");
  if (!out) out = nowhere;  // nullptr: print nothing
  const std::string mode = data_mode(o.data, o.mode);
  check_out_dir(o);
  report::ReportContext ctx;
  ctx.data = o.data;
  ctx.command = o.command_line;

  DiagnoseOutcome res;
  res.report = mode == "band" ? diagnose_band(o, ctx, out) : diagnose_waveform(o, ctx, out);
  const std::string html = report::report_html(res.report);
  const fs::path dir(o.out_dir);
  fs::create_directories(dir);
  res.json_path = (dir / "report.json").string();
  res.html_path = (dir / "report.html").string();
  write_text(res.json_path, res.report.dump(2) + "\n");
  write_text(res.html_path, html);
  std::fprintf(out, "wrote %s and %s\n", res.json_path.c_str(), res.html_path.c_str());
  return res;
}

DiagnoseCommand::DiagnoseCommand(CLI::App& app) {
  cmd_ = app.add_subcommand(
      "diagnose",
      "find the sim-to-real gap: where the tuned model and the data disagree, which unmodelled effect causes it, and "
      "how far the held-out gap shrinks with it; writes DIR/report.json and DIR/report.html");
  cmd_->add_option("DATA", options_.data,
                   "run directories or raw LCM logs (band mode), or CSV files of u,y (waveform mode)")
      ->required();
  cmd_->add_option("-o,--out", options_.out_dir, "output directory for report.json and report.html")->required();
  cmd_->add_option("--mode", options_.mode, "band or waveform (default: waveform for .csv DATA, band otherwise)")
      ->check(CLI::IsMember({"band", "waveform"}));
  cmd_->add_option("--model", options_.model,
                   "the model the baseline is tuned from: a preset (linear, nl_damper, nl_spring_damper, "
                   "nl_spring_damper_opt) or a parameter file from `noisemon fit` (default: band mode linear, so the "
                   "cubic terms are candidates; waveform mode the nearest preset or the data's linear estimate)");
  cmd_->add_option("--holdout", options_.holdout,
                   "held out (scored, never fitted): band mode condition names or patterns (full, idle_mi12, *_mi18; "
                   "default: leave-one-condition-out), waveform mode sample ranges A:B or DATA files");
  cmd_->add_option("--train", options_.train, "fit only on these (same syntax); default: every condition not held out");
  cmd_->add_option("--candidates", options_.candidates,
                   "comma-separated effects to try (default: every listed effect that applies to the mode)");
  cmd_->add_option("--free", options_.free,
                   "baseline free parameters (default: k1,b1,c0,c1, +y_offset in waveform mode)");
  cmd_->add_option("--fs", options_.fs_hz, "waveform mode: sample rate of the CSV, Hz")->check(CLI::PositiveNumber);
  cmd_->add_option("--settle", options_.settle,
                   "waveform mode: samples at each segment's start that only settle the state")
      ->capture_default_str();
  cmd_->add_option("--max-iterations", options_.max_iterations, "waveform mode: Ceres iterations per fit")
      ->capture_default_str()
      ->check(CLI::Range(1, 10000));
  cmd_->add_option("--test", options_.tests,
                   "waveform mode: NAME=A:B, a further range on which the baseline and the best model are scored "
                   "(free run), e.g. a benchmark's test set; repeatable");
  cmd_->add_option("--fit-cycles", options_.fit_cycles, "band mode: cycles per condition re-simulated in the fits")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd_->add_option("--bootstrap", options_.bootstrap, "band mode: bootstrap replicates over cycles (significance)")
      ->capture_default_str()
      ->check(CLI::Range(20, 100000));
  cmd_->add_option("--tolerance", options_.tolerance_db, "band mode: a held-out gap below this (dB) is `none`")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 20.0));
  cmd_->add_option("--pressure-floor", options_.pressure_floor,
                   "band mode: the pressure chain's noise floor, bar rms per encoder sample, for every run (replaces "
                   "run.json's pressure.noise_floor_bar), or 'estimate' to judge by the floor estimated from the quiet "
                   "crank windows (the default where a run states none)");
  cmd_->add_option("--seed", options_.seed, "seed of the bootstrap")->capture_default_str();
  cmd_->add_flag("--force", options_.force, "replace a report already in DIR");
  cmd_->add_flag("!--no-progress", options_.progress, "no progress display");
  cmd_->footer(
      "\nExamples:\n"
      "  noisemon sim --condition all --effect second_mode -o runs/withheld\n"
      "  noisemon diagnose runs/withheld -o diag                        # leave-one-condition-out\n"
      "  noisemon diagnose runs/withheld --train idle --holdout full -o diag_thesis   # the thesis's protocol\n"
      "  noisemon diagnose silverbox.csv --fs 610.3515625 --train 40650:105712 --holdout 105712:127400 \\\n"
      "      --test arrow=100:40575 -o diag_silverbox");
}

int DiagnoseCommand::run(int argc, char** argv) {
  if (!cmd_->parsed()) return -1;
  for (int i = 0; i < argc; ++i) options_.command_line += (i ? " " : "") + std::string(argv[i]);
  return exit_status_of("diagnose", [&] { run_diagnose(options_); });
}

}  // namespace noisemon::cli
