#include "daemon/sim_dataset.hpp"

#include "daemon/band_data.hpp"
#include "drivers/recording.hpp"

namespace noisemon::daemon {

model::BandDataset simulate_band_dataset(const SimCampaign& campaign) {
  std::vector<LoadedRecording> recordings;
  std::int64_t epoch = 0;
  for (const drivers::SimCondition& c : campaign.conditions) {
    drivers::SimRunSpec spec;
    spec.condition = c;
    spec.cycles = campaign.cycles;
    spec.effects = campaign.effects;
    spec.true_block = campaign.true_block;
    spec.seed = drivers::condition_seed(campaign.seed, c.name);
    spec.setup_seed = campaign.setup_seed;
    drivers::RunDir run = drivers::simulate_run(spec);
    if (campaign.modify) campaign.modify(run);
    LoadedRecording r{drivers::to_recording(run, epoch), "sim:" + c.name};
    if (r.recording.condition.empty()) r.recording.condition = c.name;
    epoch += 1'000'000'000;  // distinct time bases, as load_recordings gives run directories
    recordings.push_back(std::move(r));
  }
  return make_band_dataset(recordings, campaign.dataset);
}

}  // namespace noisemon::daemon
