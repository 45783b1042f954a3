#include "cli/band_data.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <stdexcept>

#include "drivers/formats/run_dir.hpp"

namespace noisemon::cli {

LoadedRecording loaded_run(const drivers::formats::RunDir& run, std::int64_t epoch_utime, std::string origin) {
  LoadedRecording r{formats::to_recording(run, epoch_utime), std::move(origin)};
  if (run.pressure_noise_floor_bar) r.pressure_floor_pa = *run.pressure_noise_floor_bar * 1e5;
  const std::size_t n = run.time_s.size();
  if (n >= 2) r.encoder_rate_hz = static_cast<double>(n - 1) / (run.time_s.back() - run.time_s.front());
  return r;
}

namespace {

// A run directory for the dataset: its condition must say whether the run is motored (a motored reference is
// used differently from a fired run); unknown SOI and load are only reported, so they may stay unknown.
LoadedRecording load_run_dir(const std::string& dir, std::int64_t epoch_utime) {
  const drivers::formats::RunDir run = drivers::formats::read_run_dir(dir);
  if (!run.condition.motored_known)
    throw std::runtime_error(dir +
                             ": key \"condition.motored\" is null (unknown) in run.json: the diagnosis must know "
                             "whether the run is motored (a motored reference) or fired; set it to true or false");
  LoadedRecording r = loaded_run(run, epoch_utime, dir);
  if (r.recording.condition.empty()) r.recording.condition = std::filesystem::path(dir).filename().string();
  return r;
}

}  // namespace

std::vector<LoadedRecording> load_recordings(const std::vector<std::string>& paths,
                                             const std::function<void(const std::string&)>& note) {
  namespace fs = std::filesystem;
  std::vector<LoadedRecording> out;
  std::int64_t epoch = 0;
  // A directory of run directories (what `noisemon sim -o DIR` writes) stands for its runs, in name order.
  std::vector<std::string> expanded;
  for (const std::string& p : paths) {
    std::error_code ec;
    if (fs::is_directory(p, ec) && !fs::exists(fs::path(p) / "run.json", ec)) {
      std::vector<std::string> runs;
      for (const auto& e : fs::directory_iterator(p, ec))
        if (e.is_directory() && fs::exists(e.path() / "run.json")) runs.push_back(e.path().string());
      if (runs.empty()) throw std::runtime_error(p + ": neither a run directory (no run.json) nor a directory of them");
      std::sort(runs.begin(), runs.end());
      expanded.insert(expanded.end(), runs.begin(), runs.end());
    } else {
      expanded.push_back(p);
    }
  }
  for (const std::string& p : expanded) {
    std::error_code ec;
    if (fs::is_regular_file(p, ec) && fs::path(p).extension() == ".json") {
      // e.g. the truth.json beside simulated runs when DATA is a glob: not data, said and passed over.
      if (note) note(p + ": a JSON file, not a run directory or LCM log: skipped");
      continue;
    }
    if (fs::is_directory(p, ec)) {
      LoadedRecording r = load_run_dir(p, epoch);
      epoch += 1'000'000'000;  // distinct epochs: recordings never share a time base
      if (note)
        note(p + ": condition " + r.recording.condition + ", " + std::to_string(r.recording.frames()) + " frames");
      out.push_back(std::move(r));
    } else if (fs::is_regular_file(p, ec)) {
      std::int64_t skipped = 0;
      std::vector<formats::Recording> recs = formats::read_recordings_log(p, {}, &skipped);
      if (note)
        note(p + ": " + std::to_string(recs.size()) + " recording(s)" +
             (skipped > 0 ? ", " + std::to_string(skipped) + " damaged event(s) skipped" : ""));
      for (formats::Recording& rec : recs) {
        if (rec.condition.empty()) rec.condition = fs::path(p).stem().string();
        out.push_back({std::move(rec), p});
      }
    } else {
      throw std::runtime_error(p + ": no such run directory or LCM log");
    }
  }
  if (out.empty()) throw std::runtime_error("no DATA given");
  return out;
}

model::fit::ConditionInfo condition_info(const formats::Recording& rec, const std::string& fallback_name) {
  model::fit::ConditionInfo info;
  info.name = rec.condition.empty() ? fallback_name : rec.condition;
  if (!rec.operating_points.empty()) {
    const drivers::OperatingPoint& op = rec.operating_points.front();
    info.speed_rpm = op.speed_rpm;
    info.load_nm = op.load_nm;
    info.soi_deg_btdc = op.soi_deg_btdc;
    info.motored = op.motored;
  }
  info.background = info.name.rfind("background", 0) == 0 ||
                    (!rec.operating_points.empty() && info.speed_rpm == 0.0 && rec.operating_points.front().motored);
  return info;
}

model::fit::ConditionInfo condition_info(const LoadedRecording& r) {
  model::fit::ConditionInfo info = condition_info(r.recording, r.origin);
  info.pressure_floor_pa = r.pressure_floor_pa;
  info.encoder_rate_hz = r.encoder_rate_hz;
  return info;
}

model::fit::BandDataset make_band_dataset(const std::vector<LoadedRecording>& recordings,
                                          const model::fit::DatasetOptions& options) {
  std::vector<std::string> order;
  std::map<std::string, std::vector<const LoadedRecording*>> groups;
  for (const LoadedRecording& r : recordings) {
    const std::string name = condition_info(r).name;
    if (!groups.count(name)) order.push_back(name);
    groups[name].push_back(&r);
  }
  std::vector<model::fit::ConditionData> conds;
  for (const std::string& name : order) {
    const auto& group = groups[name];
    std::vector<model::fit::ConditionRecording> parts;
    for (const LoadedRecording* r : group) {
      const formats::Recording& rec = r->recording;
      if (rec.info.mic_count == 0) throw std::runtime_error(r->origin + ": condition " + name + " has no microphones");
      model::fit::ConditionRecording cr;
      cr.pressure_pa = rec.pressure_pa;
      cr.crank_deg = rec.crank_deg;
      cr.mics_pa = rec.mics_pa;
      cr.mic_count = rec.info.mic_count;
      cr.delay_frames = std::llround(rec.info.acoustic_delay_s * model::fit::kDatasetRateHz);
      parts.push_back(std::move(cr));
    }
    try {
      model::fit::ConditionInfo info = condition_info(*group.front());  // the first recording's floor and encoder
      info.name = name;
      conds.push_back(model::fit::build_condition(info, parts, options));
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(group.front()->origin + ": " + e.what());
    }
  }
  return model::fit::make_dataset(std::move(conds));
}

model::fit::BandDataset load_band_dataset(const std::vector<std::string>& paths, std::FILE* out, ProgressLine& line) {
  const std::vector<LoadedRecording> recs =
      load_recordings(paths, [&](const std::string& note) { std::fprintf(out, "%s\n", note.c_str()); });
  line.show("measuring band spectra ...");
  model::fit::BandDataset data = make_band_dataset(recs);
  line.done();
  return data;
}

std::string condition_names(const model::fit::BandDataset& data) {
  std::string names;
  for (const auto& c : data.conditions) names += (names.empty() ? "" : ", ") + c.info.name;
  return names;
}

}  // namespace noisemon::cli
