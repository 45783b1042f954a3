#include "cli/sim_command.hpp"

#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <utility>

#include "cli/cli_support.hpp"
#include "cli/sim_run.hpp"
#include "daemon/params_file.hpp"
#include "drivers/formats/run_dir.hpp"
#include "model/engine/effects.hpp"

namespace noisemon::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

double cpu_s() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

std::string safe_name(const std::string& name, std::size_t index) {
  std::string s;
  for (char c : name) s += (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_') ? c : '_';
  if (s.empty() || s == "." || s == "..") s = "run" + std::to_string(index);
  return s;
}

json block_json(const model::BlockParams& b) {
  return {{"m", b.m}, {"k1", b.k1}, {"k3", b.k3}, {"b1", b.b1}, {"b3", b.b3}, {"c0", b.c0}, {"c1", b.c1}};
}

json effects_json(const model::engine::Effects& effects) {
  json out = json::array();
  for (const auto& s : effects.settings) {
    const model::engine::EffectInfo* info = model::engine::find_effect(s.name);
    json q = json::object();
    for (const auto& qi : info->qualifiers) {
      double v = qi.default_value;
      for (const auto& [k, given] : s.qualifiers)
        if (k == qi.key) v = given;
      q[std::string(qi.key)] = v;
    }
    out.push_back({{"name", s.name},
                   {"magnitude", s.magnitude},
                   {"unit", std::string(info->unit)},
                   {"meaning", std::string(info->meaning)},
                   {"qualifiers", q},
                   {"test_only", info->test_only}});
  }
  return out;
}

}  // namespace

namespace {

// "noisemon sim: [3/12] name  generating" on the progress line.
void show_job(ProgressLine& line, std::size_t k, std::size_t n, const std::string& name, const char* what) {
  char text[160];
  std::snprintf(text, sizeof text, "noisemon sim: [%zu/%zu] %-16s %-12s", k + 1, n, name.c_str(), what);
  line.show(text);
}

struct Job {
  std::string name, dir;
  cli::SimCondition condition;
  std::string pressure_dir;
  bool background = false;
};

// The true block of --true-model, its error message naming --true-model.
model::BlockParams true_model(const SimOptions& o, std::string& model_name) {
  try {
    return daemon::resolve_model(o.true_model, &model_name);
  } catch (const std::exception& e) {
    std::string msg = e.what();
    const std::string echo = "--model " + o.true_model + ": ";  // resolve_model names its own option
    if (msg.rfind(echo, 0) == 0) msg.erase(0, echo.size());
    throw std::invalid_argument("--true-model " + o.true_model + ": " + msg);
  }
}

// The test cell of the campaign: realistic by default, the pressure floor as given.
drivers::sim::SimConfig campaign_engine(const SimOptions& o) {
  drivers::sim::SimConfig e = cli::SimRunSpec::default_engine();
  e.encoder_resolution_deg = o.encoder_deg;
  if (!(o.pressure_floor_bar >= 0.0 && o.pressure_floor_bar <= 10.0))
    throw std::invalid_argument("--pressure-floor must be in [0, 10] bar");
  if (o.ideal_cell) return drivers::sim::with_ideal_cell(e);
  if (o.pressure_floor_bar == 0.0)
    e.pressure_chain = model::engine::PressureChainConfig::ideal();
  else
    e.pressure_chain.noise_bar = o.pressure_floor_bar;
  return e;
}

std::vector<Job> make_jobs(const SimOptions& o) {
  std::vector<Job> jobs;
  for (const auto& c : cli::resolve_conditions(o.conditions)) jobs.push_back({c.name, c.name, c, "", false});
  for (std::size_t i = 0; i < o.pressure_dirs.size(); ++i) {
    const fs::path p(o.pressure_dirs[i]);
    if (!fs::is_regular_file(p / "run.json"))
      throw std::invalid_argument("--pressure " + p.string() + ": no run.json there");
    std::string name = p.filename().string();
    if (name.empty()) name = p.parent_path().filename().string();
    Job job;
    job.name = name;
    job.dir = safe_name(name, i);
    job.pressure_dir = p.string();
    jobs.push_back(std::move(job));
  }
  if (o.background_run) {
    const std::string name(cli::kBackgroundRunName);
    jobs.push_back({name, name, cli::resolve_conditions({"motored_idle"}).front(), "", true});
  }
  for (std::size_t i = 0; i < jobs.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (jobs[j].dir == jobs[i].dir) jobs[i].dir += "_" + std::to_string(i + 1);
  return jobs;
}

void check_outputs(const SimOptions& o, const std::vector<Job>& jobs) {
  const fs::path out(o.out_dir);
  if (fs::exists(out) && !fs::is_directory(out))
    throw std::invalid_argument("-o " + out.string() + " exists and is not a directory");
  if (o.force) return;
  for (const auto& j : jobs)
    if (fs::exists(out / j.dir / "run.json"))
      throw std::invalid_argument("" + (out / j.dir).string() + " already holds a run; use --force to replace it");
  if (fs::exists(out / "truth.json"))
    throw std::invalid_argument((out / "truth.json").string() +
                                " already records an earlier sim; use --force to replace it");
}

// Every setting of the virtual test cell (what the diagnosis has to cope with; for checking by hand).
json test_cell_json(const drivers::sim::SimConfig& e, bool ideal) {
  const auto& p = e.pressure_chain;
  const auto& m = e.mic_chain;
  const auto& g = e.gas_ringing;
  return {{"ideal_cell", ideal},
          {"pressure_chain",
           {{"noise_bar", p.noise_bar},
            {"flicker_bar", p.flicker_bar},
            {"adc_bits", p.adc_bits},
            {"adc_min_bar", p.adc_min_bar},
            {"adc_max_bar", p.adc_max_bar},
            {"floor_bar", p.floor_bar()}}},
          {"mic_chain",
           {{"self_noise_dba", m.has_self_noise() ? json(m.self_noise_dba) : json(nullptr)},
            {"directivity_db", m.directivity_db},
            {"adc_bits", m.adc_bits},
            {"adc_range_pa", m.adc_range_pa},
            {"gain_spread_db", e.mic_gain_spread_db},
            {"background_floor_db", e.background_noise_db}}},
          {"gas_ringing",
           {{"gain_us", 1e6 * g.gain_s},
            {"decay_ms", 1e3 * g.decay_s},
            {"mode_weights", g.mode_weights},
            {"draper_alpha", model::engine::kDraperAlpha}}}};
}

// One run: generated (or driven by a given pressure) and its clipping noted.
drivers::formats::RunDir generate(const Job& job, cli::SimRunSpec& spec, SimSummary& sum) {
  cli::SimRunStats stats;
  drivers::formats::RunDir run;
  if (job.background) {
    spec.condition = job.condition;
    run = cli::simulate_background_run(spec, &stats);
  } else if (job.pressure_dir.empty()) {
    spec.condition = job.condition;
    run = cli::simulate_run(spec, &stats);
  } else {
    const drivers::formats::RunDir given = drivers::formats::read_run_dir(job.pressure_dir);
    try {
      run = cli::simulate_acoustics(given, spec);
    } catch (const std::exception& e) {
      throw std::runtime_error("--pressure " + job.pressure_dir + ": " + e.what());
    }
  }
  sum.pressure_clipped += stats.pressure_clipped;
  sum.mic_clipped += stats.mic_clipped;
  if (stats.pressure_clipped + stats.mic_clipped > 0)
    sum.warnings.push_back("run " + job.name + ": the ADCs clipped " + std::to_string(stats.pressure_clipped) +
                           " pressure and " + std::to_string(stats.mic_clipped) + " microphone samples");
  return run;
}

}  // namespace

SimSummary run_sim(const SimOptions& o) {
  // Everything is checked before anything is written.
  if (o.out_dir.empty()) throw std::invalid_argument("no output directory (-o DIR)");
  if (o.conditions.empty() == o.pressure_dirs.empty())
    throw std::invalid_argument("give either --condition NAME|all or --pressure RUN_DIR (one of them)");
  if (o.cycles < 1 || o.cycles > 100000) throw std::invalid_argument("--cycles must be in [1, 100000]");
  const model::engine::Effects effects = model::engine::parse_effects(o.effects);
  std::string model_name;
  const model::BlockParams true_block = true_model(o, model_name);
  if (effects.mic_gain_db != 0.0 && o.pressure_dirs.empty() &&
      static_cast<std::uint32_t>(effects.mic_gain_mic) > cli::SimRunSpec::default_engine().mic_count)
    throw std::invalid_argument("effect mic_gain: microphone " + std::to_string(effects.mic_gain_mic) +
                                " does not exist (the layout has " +
                                std::to_string(cli::SimRunSpec::default_engine().mic_count) + ")");
  cli::SimRunSpec base;
  base.cycles = o.cycles;
  base.effects = effects;
  base.true_block = true_block;
  base.setup_seed = o.seed;
  base.engine = campaign_engine(o);
  const std::vector<Job> jobs = make_jobs(o);
  check_outputs(o, jobs);
  const fs::path out(o.out_dir);

  SimSummary sum;
  ProgressLine progress(o.progress);
  json runs = json::array();
  for (std::size_t k = 0; k < jobs.size(); ++k) {
    const Job& job = jobs[k];
    cli::SimRunSpec spec = base;
    spec.seed = cli::condition_seed(o.seed, job.name);
    show_job(progress, k, jobs.size(), job.name, "generating");
    double t0 = cpu_s();
    const drivers::formats::RunDir run = generate(job, spec, sum);
    sum.generate_s += cpu_s() - t0;
    show_job(progress, k, jobs.size(), job.name, "writing");
    const auto w0 = std::chrono::steady_clock::now();
    drivers::formats::write_run_dir(out / job.dir, run, "bar");
    sum.write_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
    sum.run_dirs.push_back((out / job.dir).string());
    runs.push_back({{"dir", job.dir},
                    {"condition", run.condition.name},
                    {"seed", spec.seed},
                    {"speed_rpm", run.condition.speed_rpm},
                    {"load_nm", run.condition.load_nm},
                    {"soi_deg_btdc", run.condition.soi_deg_btdc},
                    {"motored", run.condition.motored},
                    {"background", job.background},
                    {"pressure", job.background             ? json("engine off: ambient pressure through the chain")
                                 : job.pressure_dir.empty() ? json("engine model")
                                                            : json(job.pressure_dir)},
                    {"pressure_noise_floor_bar",
                     run.pressure_noise_floor_bar ? json(*run.pressure_noise_floor_bar) : json(nullptr)},
                    {"cycles", job.pressure_dir.empty() ? json(o.cycles) : json(nullptr)}});
  }
  progress.done();

  json truth = {
      {"generator", "noisemon sim"},
      {"note",
       "what was injected into the true engine: for checking by hand only; noisemon diagnose never reads this file"},
      {"seed", o.seed},
      {"true_model", {{"name", model_name}, {"params", block_json(true_block)}}},
      {"true_block_with_effects", block_json(model::engine::with_structural_effects(true_block, effects))},
      {"effects", effects_json(effects)},
      {"test_cell", test_cell_json(base.engine, o.ideal_cell)},
      {"adc_clipped", {{"pressure_samples", sum.pressure_clipped}, {"mic_samples", sum.mic_clipped}}},
      {"encoder_resolution_deg", o.encoder_deg},
      {"mic_rate_hz", base.engine.mic_rate_hz},
      {"runs", runs}};
  const fs::path truth_path = out / "truth.json";
  std::ofstream f(truth_path);
  f << truth.dump(2) << "\n";
  if (!f) throw std::runtime_error("cannot write " + truth_path.string());
  return sum;
}

SimCommand::SimCommand(CLI::App& app) {
  sim_ = app.add_subcommand(
      "sim",
      "generate run directories (run.json, pressure.csv, mics.wav) from the virtual engine, with effects injected "
      "into the true engine; DIR/truth.json records them");
  sim_->add_option("--condition", options_.conditions,
                   "condition to generate (repeatable): all, idle_mi12 .. idle_mi24, full_mi12 .. full_mi24 (3050 rpm "
                   "0 N m / 3450 rpm 20 N m, SOI deg BTDC), motored_idle, motored_full");
  sim_->add_option("--effect", options_.effects,
                   "effect injected into the true engine (repeatable): NAME[=MAGNITUDE][,key=value...]; see below");
  sim_->add_option("--cycles", options_.cycles, "engine cycles per run")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  sim_->add_option("--seed", options_.seed, "seed: the same seed gives the same runs, bit for bit")
      ->capture_default_str();
  sim_->add_option("--true-model", options_.true_model,
                   "the engine's true block before the effects: a preset (linear, nl_damper, nl_spring_damper, "
                   "nl_spring_damper_opt) or a parameter file from `noisemon fit`")
      ->capture_default_str();
  sim_->add_option(
          "--pressure", options_.pressure_dirs,
          "instead of --condition: run directories whose (true) pressure drives the virtual engine (repeatable); "
          "their condition is kept, the microphones are replaced")
      ->check(CLI::ExistingDirectory);
  sim_->add_option("--encoder-deg", options_.encoder_deg, "encoder resolution of pressure.csv, deg")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 6.0));
  sim_->add_option(
          "--pressure-floor", options_.pressure_floor_bar,
          "the pressure chain's configured white floor, bar rms per encoder sample (recorded in each run.json as "
          "pressure.noise_floor_bar; 0.02: a good piezo chain, the real Yanmar records carry about 0.2; 0: an ideal "
          "pressure chain, no floor and no ADC). The transducer_noise effect comes on top and is not recorded")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  sim_->add_flag(
      "--ideal-cell", options_.ideal_cell,
      "an ideal test cell: no pressure-chain floor or ADC, no microphone self-noise, directivity or ADC, no gas "
      "ringing (the 40 dB pink floor and the 0.3 dB gain spread stay)");
  sim_->add_flag("--background-run", options_.background_run,
                 "also write the engine-off run `background` (the microphones hear only the test cell: its floor, the "
                 "background_noise effect, their self-noise; the pressure reads ambient through the chain), which "
                 "`noisemon diagnose` takes as the floor");
  sim_->add_option("-o,--out", options_.out_dir, "output directory: one run directory per condition, and truth.json");
  sim_->add_flag("--force", options_.force, "replace run directories and a truth.json that already exist");
  sim_->add_flag("--list-effects", list_effects_,
                 "print every effect (unit, meaning, default, realistic range) and exit");
  sim_->add_flag("!--no-progress", options_.progress, "no progress display");
  sim_->footer(
      model::engine::effect_help_text() +
      "\nExamples:\n"
      "  noisemon sim --condition all -o runs/null\n"
      "  noisemon sim --condition all --effect cubic_stiffness -o runs/k3\n"
      "  noisemon sim --condition all --background-run --effect transducer_noise=0.1 -o runs/noisy_chain\n"
      "  noisemon sim --condition all --ideal-cell -o runs/ideal\n"
      "  noisemon sim --condition idle_mi18 --condition full_mi18 --effect second_mode=6,hz=3150 "
      "--effect background_noise=60 --cycles 20 --seed 7 -o runs/mix\n"
      "  # real Yanmar cycles driving the virtual engine (the pressure is kept, the microphones are the sim's):\n"
      "  noisemon import --cycles-table yanmar_l100v_fired_18Nm.txt --rpm 1799.9 --load 18 --soi 9.6 "
      "--condition yanmar_fired -o fired.lcmlog\n"
      "  noisemon export fired.lcmlog -o pressure/yanmar_fired\n"
      "  noisemon sim --pressure pressure/yanmar_fired --effect mechanical_noise=80 -o runs/yanmar_sim");
}

int SimCommand::run() {
  if (!sim_->parsed()) return -1;
  if (list_effects_) {
    std::fputs(model::engine::effect_help_text().c_str(), stdout);
    return 0;
  }
  return exit_status_of("sim", [&] {
    const SimSummary s = run_sim(options_);
    for (const auto& w : s.warnings) std::fprintf(stderr, "noisemon sim: warning: %s\n", w.c_str());
    std::fprintf(
        stderr,
        "noisemon sim: wrote %zu run director%s and truth.json under %s (generating %.2f s CPU, writing %.2f s)\n",
        s.run_dirs.size(), s.run_dirs.size() == 1 ? "y" : "ies", options_.out_dir.c_str(), s.generate_s, s.write_s);
  });
}

}  // namespace noisemon::cli
