#include "cli/sim_dataset.hpp"

#include "cli/band_data.hpp"
#include "cli/formats/recording.hpp"

namespace noisemon::cli {

model::fit::BandDataset simulate_band_dataset(const SimCampaign& campaign) {
  std::vector<LoadedRecording> recordings;
  std::int64_t epoch = 0;
  std::vector<cli::SimCondition> conditions = campaign.conditions;
  if (campaign.background_run) conditions.push_back(cli::resolve_conditions({"motored_idle"}).front());
  for (std::size_t k = 0; k < conditions.size(); ++k) {
    const bool background = campaign.background_run && k + 1 == conditions.size();
    const cli::SimCondition& c = conditions[k];
    cli::SimRunSpec spec;
    spec.condition = c;
    spec.cycles = campaign.cycles;
    spec.effects = campaign.effects;
    spec.true_block = campaign.true_block;
    spec.seed = cli::condition_seed(campaign.seed, background ? cli::kBackgroundRunName : c.name);
    spec.setup_seed = campaign.setup_seed;
    spec.engine = campaign.engine;
    drivers::formats::RunDir run = background ? cli::simulate_background_run(spec) : cli::simulate_run(spec);
    if (campaign.modify) campaign.modify(run);
    // As load_recordings reads a run directory: the configured pressure floor travels with the recording.
    LoadedRecording r = loaded_run(run, epoch, "sim:" + run.condition.name);
    if (r.recording.condition.empty()) r.recording.condition = run.condition.name;
    epoch += 1'000'000'000;  // distinct time bases, as load_recordings gives run directories
    recordings.push_back(std::move(r));
  }
  return make_band_dataset(recordings, campaign.dataset);
}

}  // namespace noisemon::cli
