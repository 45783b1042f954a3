// Full band-mode diagnosis of the benchmark campaign: the 12 thesis conditions (10 fired, 2 motored) of
// 40 cycles each, every candidate, leave-one-condition-out, bootstrap. Prints the total and the stage breakdown
// (DiagnosisResult::timing). The data carry one withheld effect (second_mode at its catalogue default) so the
// candidates have something to find; generating them is timed separately (it is not part of the diagnosis).
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "cli/sim_dataset.hpp"
#include "model/diagnosis/diagnosis.hpp"

namespace {

const noisemon::model::fit::BandDataset& campaign() {
  static const noisemon::model::fit::BandDataset data = [] {
    const auto t0 = std::chrono::steady_clock::now();
    noisemon::cli::SimCampaign c;
    c.conditions = noisemon::cli::thesis_conditions();
    c.cycles = 40;
    // NOISEMON_BENCH_EFFECT=NAME[=MAGNITUDE] (or "none") swaps the withheld effect, for a quick look at a verdict.
    const char* env = std::getenv("NOISEMON_BENCH_EFFECT");
    const std::string effect = env ? env : "second_mode";
    if (effect != "none") c.effects = noisemon::model::engine::parse_effects({effect});
    auto d = noisemon::cli::simulate_band_dataset(c);
    std::printf("generating 12 conditions x 40 cycles (sim + 40 kHz conversion + bank): %.1f s\n",
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    return d;
  }();
  return data;
}

void BM_DiagnoseBand12x40(benchmark::State& state) {
  const auto& data = campaign();
  noisemon::model::diagnosis::DiagnosisResult last;
  for (auto _ : state) {
    noisemon::model::diagnosis::DiagnosisOptions opt;
    last = noisemon::model::diagnosis::diagnose(data, noisemon::model::preset("linear"), "linear", opt);
    benchmark::DoNotOptimize(last.verdict.effect);
  }
  std::printf("\nfull diagnosis: %.2f s total, verdict %s (held-out gap %.2f -> %.2f dB)\n", last.seconds,
              last.verdict.effect.c_str(), last.verdict.heldout_rms_before_db, last.verdict.heldout_rms_after_db);
  for (const auto& [stage, s] : last.timing)
    std::printf("  %-58s %7.2f s  %5.1f %%\n", stage.c_str(), s, 100.0 * s / last.seconds);
  state.counters["seconds"] = last.seconds;
}
BENCHMARK(BM_DiagnoseBand12x40)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
