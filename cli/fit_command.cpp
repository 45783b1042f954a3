#include "cli/fit_command.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "cli/band_data.hpp"
#include "cli/cli_support.hpp"
#include "cli/formats/waveform_csv.hpp"
#include "daemon/params_file.hpp"
#include "dsp/math_constants.hpp"
#include "model/diagnosis/diagnosis.hpp"
#include "model/fit/band_fit.hpp"
#include "model/fit/pressure_floor.hpp"
#include "model/fit/waveform_fit.hpp"

namespace noisemon::cli {
namespace {

std::string format_g(double v, int digits = 6) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

void check_output(const FitCommandOptions& o) {
  if (o.out.empty()) return;
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_directory(o.out, ec)) throw std::runtime_error("-o " + o.out + ": is a directory, expected a file");
  if (fs::exists(o.out, ec) && !o.force)
    throw std::runtime_error("-o " + o.out + ": exists (use --force to overwrite it)");
  const fs::path parent = fs::path(o.out).parent_path();
  if (!parent.empty() && !fs::is_directory(parent, ec))
    throw std::runtime_error("-o " + o.out + ": directory " + parent.string() + " does not exist");
}

void print_table(std::FILE* out, const FitCommandResult& r) {
  std::fprintf(out, "fitted parameters (start: %s; m = %g kg fixed):\n", r.start_name.c_str(), r.params.m);
  for (std::size_t k = 0; k < r.free.size(); ++k) {
    const double rel = r.values[k] != 0.0 ? 100.0 * r.sigma[k] / std::fabs(r.values[k]) : kNaN;
    std::fprintf(out, "  %-9s = %-14s +- %-11s (%s %%)", r.free[k].c_str(), format_g(r.values[k], 8).c_str(),
                 format_g(r.sigma[k], 3).c_str(), std::isfinite(rel) ? format_g(rel, 2).c_str() : "-");
    if (k < r.sigma_blocks.size())
      std::fprintf(out, "   correlated residuals: +- %s", format_g(r.sigma_blocks[k], 3).c_str());
    std::fputc('\n', out);
  }
  std::fprintf(out, "train RMS    %s %s (start %s) on %s\n", format_g(r.train_rms, 4).c_str(), r.units.c_str(),
               format_g(r.start_train_rms, 4).c_str(),
               [&] {
                 std::string s;
                 for (const auto& t : r.train_sets) s += (s.empty() ? "" : ", ") + t;
                 return s;
               }()
                   .c_str());
  if (std::isfinite(r.heldout_rms)) {
    std::string s;
    for (const auto& t : r.heldout_sets) s += (s.empty() ? "" : ", ") + t;
    std::fprintf(out, "held-out RMS %s %s on %s\n", format_g(r.heldout_rms, 4).c_str(), r.units.c_str(), s.c_str());
  } else {
    std::fprintf(out, "held-out RMS - (nothing held out)\n");
  }
}

// ------------------------------------------------------------------------------------------ waveform mode

std::string range_text(model::fit::SampleRange r) { return std::to_string(r.begin) + ":" + std::to_string(r.end); }

// Training ranges = the complement of the held-out ones within each file.
std::vector<model::fit::SampleRange> complement(const std::vector<model::fit::SampleRange>& held,
                                                const WaveformData& data) {
  std::vector<model::fit::SampleRange> out;
  for (const model::fit::SampleRange& f : data.file_ranges) {
    std::size_t pos = f.begin;
    std::vector<model::fit::SampleRange> inside;
    for (const auto& h : held)
      if (h.end > f.begin && h.begin < f.end) inside.push_back({std::max(h.begin, f.begin), std::min(h.end, f.end)});
    std::sort(inside.begin(), inside.end(), [](auto a, auto b) { return a.begin < b.begin; });
    for (const auto& h : inside) {
      if (h.begin > pos) out.push_back({pos, h.begin});
      pos = std::max(pos, h.end);
    }
    if (pos < f.end) out.push_back({pos, f.end});
  }
  return out;
}

}  // namespace

model::fit::SampleRange parse_range(const std::string& text, const WaveformData& data, const char* option) {
  for (std::size_t f = 0; f < data.file_ranges.size(); ++f)
    if (text == data.files[f] || text == std::filesystem::path(data.files[f]).filename().string())
      return data.file_ranges[f];
  const std::size_t colon = text.find(':');
  if (colon != std::string::npos) {
    try {
      std::size_t used_a = 0, used_b = 0;
      const std::string a = text.substr(0, colon), b = text.substr(colon + 1);
      const unsigned long long lo = a.empty() ? 0 : std::stoull(a, &used_a);
      const unsigned long long hi = b.empty() ? data.u.size() : std::stoull(b, &used_b);
      if ((a.empty() || used_a == a.size()) && (b.empty() || used_b == b.size())) {
        if (lo >= hi || hi > data.u.size())
          throw std::runtime_error(std::string(option) + " " + text + ": range outside the " +
                                   std::to_string(data.u.size()) + " samples or empty");
        return {static_cast<std::size_t>(lo), static_cast<std::size_t>(hi)};
      }
    } catch (const std::logic_error&) {
    }
  }
  throw std::runtime_error(std::string(option) + " " + text +
                           ": expected a sample range A:B (0-based, end excluded) or a DATA file name");
}

WaveformData load_waveform_data(const std::vector<std::string>& paths, const std::vector<std::string>& train,
                                const std::vector<std::string>& holdout, std::size_t settle, std::FILE* note) {
  WaveformData data;
  for (const std::string& path : paths) {
    formats::Waveform w = formats::read_waveform_csv(path);
    const std::size_t begin = data.u.size();
    data.u.insert(data.u.end(), w.u.begin(), w.u.end());
    data.y.insert(data.y.end(), w.y.begin(), w.y.end());
    data.files.push_back(path);
    data.file_ranges.push_back({begin, data.u.size()});
    if (note) std::fprintf(note, "%s: %zu samples\n", path.c_str(), w.u.size());
  }
  for (const std::string& h : flatten_lists(holdout)) data.heldout.push_back(parse_range(h, data, "--holdout"));
  for (const std::string& t : flatten_lists(train)) data.train.push_back(parse_range(t, data, "--train"));
  if (data.heldout.empty() && data.train.empty()) {  // default split: the last file, or the last 20 % of one file
    if (data.file_ranges.size() > 1) {
      data.heldout.push_back(data.file_ranges.back());
    } else {
      const std::size_t n = data.u.size(), cut = n - n / 5;
      if (n / 5 > 4 * settle) data.heldout.push_back({cut, n});
    }
  }
  if (data.train.empty()) data.train = complement(data.heldout, data);
  if (data.train.empty()) throw std::runtime_error("--holdout leaves no samples to train on");
  return data;
}

namespace {

FitCommandResult fit_waveform_mode(const FitCommandOptions& o, std::FILE* out) {
  if (!(o.fs_hz > 0.0))
    throw std::runtime_error("--fs: the sample rate of the waveform (Hz) is required in waveform mode");
  const WaveformData data = load_waveform_data(o.data, o.train, o.holdout, o.settle, out);

  model::fit::WaveformFitOptions fo;
  fo.fs_hz = o.fs_hz;
  fo.sim.settle_samples = o.settle;
  fo.max_iterations = o.max_iterations;
  fo.train = data.train;
  fo.heldout = data.heldout;

  if (!o.model.empty()) {
    model::fit::WaveformModel start;
    std::string name;
    start.block = daemon::resolve_model(o.model, &name);
    fo.start = start;
    fo.start_name = name;
  }
  if (!o.free.empty()) {
    fo.free_params = split_list(o.free);
    for (const std::string& p : fo.free_params) {
      const auto& names = model::fit::waveform_parameter_names();
      if (std::find(names.begin(), names.end(), p) == names.end()) {
        std::string list;
        for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
        throw std::runtime_error("--free: unknown parameter '" + p + "' (waveform mode knows " + list + ")");
      }
      if (p == "m") throw std::runtime_error("--free: m is fixed");
    }
  } else {
    fo.free_params = {"k1", "b1", "c0", "c1", "y_offset"};
    if (fo.start && fo.start->block.k3 != 0.0) fo.free_params.push_back("k3");
    if (fo.start && fo.start->block.b3 != 0.0) fo.free_params.push_back("b3");
  }

  ProgressLine line(o.progress);
  fo.progress = [&](const model::fit::WaveformFitProgress& p) {
    line.show("fit: iteration " + std::to_string(p.iteration) + "  train RMS " + format_g(p.train_rms, 5) + "  " +
              format_g(p.seconds, 3) + " s");
  };
  const model::fit::WaveformFitResult r = model::fit::fit_waveform(data.u, data.y, fo);
  line.done();
  std::fprintf(out, "Ceres: %d iterations, %s (%.2f s, %d integration steps per sample)\n", r.iterations,
               r.solver_message.c_str(), r.seconds, r.steps_per_sample);

  FitCommandResult res;
  res.mode = "waveform";
  res.start_name = r.start_name == "data" ? "the data's linear second-order estimate" : r.start_name;
  res.params = r.model.block;
  res.free = r.free_params;
  for (std::size_t k = 0; k < r.free_params.size(); ++k) {
    res.values.push_back(model::fit::get_parameter(r.model, r.free_params[k]));
    res.sigma.push_back(r.sigma[k]);
    if (k < r.sigma_blocks.size()) res.sigma_blocks.push_back(r.sigma_blocks[k]);
  }
  res.units = "(data units)";
  res.start_train_rms = r.start_train_rms;
  res.train_rms = r.train_rms;
  res.heldout_rms = fo.heldout.empty() ? kNaN : r.heldout_rms;
  for (const auto& t : fo.train) res.train_sets.push_back(range_text(t));
  for (const auto& h : fo.heldout) res.heldout_sets.push_back(range_text(h));
  res.seconds = r.seconds;
  for (std::size_t k = 0; k < r.at_bound.size(); ++k)
    if (r.at_bound[k]) std::fprintf(out, "note: %s ended on its bound\n", r.free_params[k].c_str());
  if (r.model.u_offset != 0.0 || r.model.y_offset != 0.0)
    std::fprintf(out,
                 "note: offsets u_offset = %s, y_offset = %s are part of the fit but not of the parameter file "
                 "(the daemon's model has none)\n",
                 format_g(r.model.u_offset).c_str(), format_g(r.model.y_offset).c_str());
  return res;
}

// ------------------------------------------------------------------------------------------ band mode

double condition_rms(const model::fit::BandDataset& data, std::size_t k, const model::fit::ExtendedModel& m,
                     const std::vector<char>& scored) {
  const model::fit::ConditionPrediction p = model::fit::predict_condition(data, k, m, false);
  return model::fit::rms_db(model::fit::condition_gaps(data.conditions[k], p.cycle_ms, scored, m));
}

double mean_rms(const model::fit::BandDataset& data, const std::vector<std::size_t>& conds,
                const model::fit::ExtendedModel& m, const std::vector<std::vector<char>>& scored) {
  if (conds.empty()) return kNaN;
  double s = 0.0;
  for (std::size_t k : conds) s += condition_rms(data, k, m, scored[k]);
  return s / static_cast<double>(conds.size());
}

bool matches_any(const std::vector<std::string>& patterns, const std::string& name) {
  for (const std::string& p : patterns)
    if (model::diagnosis::condition_matches(p, name)) return true;
  return false;
}

// Every --holdout / --train pattern must name at least one condition.
void check_patterns(const model::fit::BandDataset& data, const std::vector<std::string>& held,
                    const std::vector<std::string>& trn) {
  for (const auto* list : {&held, &trn})
    for (const std::string& p : *list) {
      bool any = false;
      for (const auto& c : data.conditions) any = any || model::diagnosis::condition_matches(p, c.info.name);
      if (!any)
        throw std::runtime_error(std::string(list == &held ? "--holdout " : "--train ") + p +
                                 ": matches no condition (the data hold " + condition_names(data) + ")");
    }
}

// Which fired conditions train and which are held out, and the bands each is scored on (none for the reference
// runs: motored and background).
struct BandSplit {
  std::vector<std::size_t> train, heldout;
  std::vector<std::vector<char>> scored;
};

BandSplit split_conditions(const model::fit::BandDataset& data, const std::vector<std::string>& held,
                           const std::vector<std::string>& trn, FitCommandResult& res) {
  BandSplit split;
  split.scored.assign(data.conditions.size(), std::vector<char>(data.band_count(), 0));
  const std::vector<std::vector<char>> at_floor = model::fit::floor_limited_bands(data);
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    const model::fit::ConditionInfo& info = data.conditions[k].info;
    if (info.motored || info.background) continue;  // reference runs: never scored
    for (std::size_t b = 0; b < data.band_count(); ++b)
      split.scored[k][b] = !data.bands[b].nyquist_cut && !data.band_line_free(k, b) && !at_floor[k][b];
    if (matches_any(held, info.name)) {
      split.heldout.push_back(k);
      res.heldout_sets.push_back(info.name);
    } else if (trn.empty() || matches_any(trn, info.name)) {
      split.train.push_back(k);
      res.train_sets.push_back(info.name);
    }
  }
  if (split.train.empty()) throw std::runtime_error("no fired condition left to train on (check --train / --holdout)");
  return split;
}

// The start: the given model, or the Table 4.1 preset with the lowest training gap (each one's gap printed).
model::fit::ExtendedModel start_model(const FitCommandOptions& o, const model::fit::FitSetup& setup, ProgressLine& line,
                                      std::FILE* out, std::string& start_name) {
  model::fit::ExtendedModel start;
  if (!o.model.empty()) {
    start.block = daemon::resolve_model(o.model, &start_name);
    return start;
  }
  double best = std::numeric_limits<double>::infinity();
  model::fit::FitSetup ev = setup;
  ev.evaluate_only = true;
  for (const std::string& name : model::preset_names()) {
    model::fit::ExtendedModel m;
    m.block = model::preset(name);
    line.show("start: trying preset " + name);
    const model::fit::Anchor an = model::fit::make_anchor(*setup.data, m.block, setup.train, o.fit_cycles, false);
    const double rms = model::fit::refit_on_anchor(ev, an, m).train_rms_db;
    line.done();
    std::fprintf(out, "preset %-22s train RMS %.3f dB\n", name.c_str(), rms);
    if (rms < best) {
      best = rms;
      start = m;
      start_name = name;
    }
  }
  return start;
}

FitCommandResult fit_band_mode(const FitCommandOptions& o, std::FILE* out) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<model::fit::BlockParam> free = parse_free_option(o.free);  // checked before the slow work
  ProgressLine line(o.progress);
  const model::fit::BandDataset data = load_band_dataset(o.data, out, line);
  const std::vector<std::string> held = flatten_lists(o.holdout), trn = flatten_lists(o.train);
  check_patterns(data, held, trn);

  FitCommandResult res;
  res.mode = "band";
  const BandSplit split = split_conditions(data, held, trn, res);
  model::fit::FitSetup setup;
  setup.data = &data;
  setup.train = split.train;
  setup.scored = split.scored;
  setup.fit_cycles = o.fit_cycles;
  const model::fit::ExtendedModel start = start_model(o, setup, line, out, res.start_name);
  setup.free = free.empty() ? model::fit::default_free_params(start.block) : free;
  setup.progress = [&](const model::fit::FitProgress& p) {
    line.show("fit: anchor " + std::to_string(p.anchor) + " iteration " + std::to_string(p.iteration) + "  train gap " +
              format_g(p.rms_db, 4) + " dB  " + p.note);
  };
  res.start_train_rms = mean_rms(data, split.train, start, split.scored);
  const model::fit::FitOutcome fit = model::fit::fit_model(setup, start);
  line.done();
  std::fprintf(out, "Ceres: %d iterations over %d time-domain anchors, %s\n", fit.iterations, fit.anchors,
               fit.converged ? "converged" : "not converged (the result is the last anchor's)");

  res.params = fit.model.block;
  for (std::size_t k = 0; k < fit.free.size(); ++k) {
    res.free.emplace_back(model::fit::param_name(fit.free[k]));
    res.values.push_back(model::fit::param_value(fit.model.block, fit.free[k]));
    res.sigma.push_back(k < fit.sigma.size() ? fit.sigma[k] : kNaN);
  }
  res.units = "dB";
  line.show("scoring every cycle ...");
  res.train_rms = mean_rms(data, split.train, fit.model, split.scored);
  res.heldout_rms = mean_rms(data, split.heldout, fit.model, split.scored);
  line.done();
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace

std::vector<model::fit::BlockParam> parse_free_option(const std::string& text) {
  if (text.empty()) return {};
  try {
    return model::fit::parse_free_params(text);
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    throw std::runtime_error(what.rfind("--free", 0) == 0 ? what : "--free: " + what);
  }
}

FitCommandResult run_fit(const FitCommandOptions& o, std::FILE* out) {
  const std::string mode = data_mode(o.data, o.mode);
  check_output(o);
  if (mode == "band" && o.fs_hz > 0.0) throw std::runtime_error("--fs applies to waveform mode only");

  FitCommandResult r = mode == "waveform" ? fit_waveform_mode(o, out) : fit_band_mode(o, out);
  print_table(out, r);

  if (!o.out.empty()) {
    std::vector<std::string> comments = {"noisemon fit (" + r.mode + " mode), started from " + r.start_name};
    std::string data_list;
    for (const auto& d : o.data) data_list += (data_list.empty() ? "" : " ") + d;
    comments.push_back("data: " + data_list);
    for (std::size_t k = 0; k < r.free.size(); ++k)
      comments.push_back(r.free[k] + " = " + format_g(r.values[k], 8) + " +- " + format_g(r.sigma[k], 3) +
                         " (1 sigma)");
    comments.push_back("train RMS " + format_g(r.train_rms, 4) + " " + r.units +
                       (std::isfinite(r.heldout_rms) ? ", held-out RMS " + format_g(r.heldout_rms, 4) + " " + r.units
                                                     : std::string()));
    // [model] preset must name a Table 4.1 preset; every parameter below it overrides the preset anyway.
    const auto& presets = model::preset_names();
    const bool is_preset = std::find(presets.begin(), presets.end(), r.start_name) != presets.end();
    if (!is_preset) comments.push_back("preset below is a placeholder: every parameter overrides it");
    daemon::write_params_file(o.out, r.params, is_preset ? r.start_name : "linear", comments);
    std::fprintf(out, "wrote %s\n", o.out.c_str());
  }
  return r;
}

FitCommand::FitCommand(CLI::App& app) {
  fit_ =
      app.add_subcommand("fit",
                         "tune the block model (k1, b1, k3, b3, c0, c1; m fixed) to band spectra (run directories, LCM "
                         "logs) or to a u,y waveform, and write a parameter file the daemon loads");
  fit_->add_option("DATA", options_.data,
                   "run directories or raw LCM logs (band mode), or CSV files of u,y (waveform mode)")
      ->required();
  fit_->add_option("-o,--out", options_.out, "parameter file to write (TOML [model], loads with --config / --model)")
      ->required();
  fit_->add_option("--mode", options_.mode, "band or waveform (default: waveform for .csv DATA, band otherwise)")
      ->check(CLI::IsMember({"band", "waveform"}));
  fit_->add_option("--fs", options_.fs_hz, "waveform mode: sample rate of the CSV, Hz")->check(CLI::PositiveNumber);
  fit_->add_option(
      "--free", options_.free,
      "parameters to fit, comma-separated: k1,b1,k3,b3,c0,c1 (waveform mode also k1_2,b1_2,c0_2,c1_2,"
      "u_offset,y_offset); default k1,b1,c0,c1 (+y_offset in waveform mode, +k3/b3 when the start has them)");
  fit_->add_option("--model", options_.model,
                   "start from this preset (linear, nl_damper, nl_spring_damper, nl_spring_damper_opt) or parameter "
                   "file; default: the preset nearest the data");
  fit_->add_option("--holdout", options_.holdout,
                   "held out (scored, not fitted): band mode condition names/patterns (idle, full_mi18, *_mi12); "
                   "waveform mode sample ranges A:B or DATA files; comma-separated or repeated");
  fit_->add_option("--train", options_.train,
                   "fit only on these (same syntax as --holdout); default: all not held out");
  fit_->add_option("--settle", options_.settle,
                   "waveform mode: samples at each segment's start that only settle the state")
      ->capture_default_str();
  fit_->add_option("--max-iterations", options_.max_iterations, "waveform mode: Ceres iterations")
      ->capture_default_str()
      ->check(CLI::Range(1, 10000));
  fit_->add_option("--fit-cycles", options_.fit_cycles, "band mode: cycles per condition re-simulated during the fit")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  fit_->add_flag("--force", options_.force, "overwrite the output file");
  fit_->add_flag("!--no-progress", options_.progress, "no progress display");
  fit_->footer(
      "\nExamples:\n"
      "  noisemon fit runs/idle_* runs/full_* --holdout full -o tuned.toml\n"
      "  noisemon fit recording.lcmlog --model nl_damper --free k1,b1,b3,c0,c1 -o tuned.toml\n"
      "  noisemon fit silverbox.csv --fs 610.35 --train 40650:105712 --holdout 105712:127400 -o silverbox.toml");
}

int FitCommand::run() {
  if (!fit_->parsed()) return -1;
  return exit_status_of("fit", [&] { run_fit(options_); });
}

}  // namespace noisemon::cli
