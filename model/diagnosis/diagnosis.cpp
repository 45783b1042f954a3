// diagnose(): the stages of the band diagnosis in order (stages.hpp), with progress lines and stage timing.
#include "model/diagnosis/diagnosis.hpp"

#include <stdexcept>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {

StageLog::StageLog(const DiagnosisOptions& opt, DiagnosisResult& res)
    : opt_(&opt), res_(&res), start_(clock::now()), last_(start_) {}

void StageLog::say(const std::string& line) const {
  if (opt_->progress) opt_->progress(line);
}

void StageLog::stage(const std::string& name) {
  const auto now = clock::now();
  res_->timing.emplace_back(name, std::chrono::duration<double>(now - last_).count());
  last_ = now;
}

double StageLog::seconds() const { return std::chrono::duration<double>(clock::now() - start_).count(); }

DiagnosisResult diagnose(const fit::BandDataset& data, const BlockParams& start, const std::string& model_name,
                         const DiagnosisOptions& opt) {
  using namespace diagnosis;
  DiagnosisResult res;
  StageLog log(opt, res);
  res.model_name = model_name;
  if (data.conditions.empty()) throw std::invalid_argument("diagnose: no condition in the data");
  Context cx;
  cx.data = &data;
  cx.opt = &opt;
  assign_roles(cx);
  res.heldout = cx.heldout;
  res.train = cx.train_fired;
  res.reference = cx.refs;
  res.leave_one_out = cx.loo;
  const std::vector<fit::BlockParam> base_free = opt.free.empty() ? fit::default_free_params(start) : opt.free;

  log.say("bands and floors");
  mark_bands_and_floors(cx, start);
  draw_bootstrap(cx);
  log.stage("bands and floors");

  log.say("baseline: tuning " + model_name + " on " + std::to_string(cx.train_fired.size()) + " fired and " +
          std::to_string(cx.refs.size()) + " motored condition(s)");
  Evaluated base = tune_baseline(cx, start, base_free);
  // The start model may be far from the engine: what the motored runs hear beyond it is then mostly its own error,
  // not combustion-independent noise. Judged again beyond the tuned block, and the baseline tuned once more if the
  // bands it may be tuned on changed.
  if (remark_noise_dominated(cx, base.score.model.block)) {
    log.say("baseline: tuning again on the bands where the motored runs hear no more than the tuned model predicts");
    base = tune_baseline(cx, base.score.model.block, base_free);
  }
  res.baseline = base.score;
  log.stage("baseline");

  const CandidateRound round = evaluate_candidates(cx, start, base, base_free, log);
  for (std::size_t i : round.order) res.candidates.push_back(round.evals[i].score);
  judge(cx, round, base_free, res, log);

  describe_where(cx, base, res);
  log.stage("report figures");
  res.timing.emplace_back("(of which) fits on all training conditions", cx.t_fit);
  res.timing.emplace_back("(of which) fold refits", cx.t_folds);
  res.timing.emplace_back("(of which) held-out re-simulation and scoring", cx.t_heldout);
  res.timing.emplace_back("(of which) leave-one-group-out refits and scoring", cx.t_groups);
  res.timing.emplace_back("(of which) stationary floors (training re-simulation)", cx.t_floors);
  res.timing.emplace_back("(of which) bootstrap", cx.t_bootstrap);
  res.seconds = log.seconds();
  return res;
}

}  // namespace noisemon::model::diagnosis
