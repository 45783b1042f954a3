// The clock-alignment proof: a front-end's microphones on a crystal +80 ppm and -50 ppm off the encoder's, with
// phase jitter and host readings late by up to a period, for an hour of engine time (unpaced), through the
// AlignedStreamAssembler as the ALSA source feeds it (tests/support/alignment_run.hpp; the card is written from the
// physics alone, tests/support/drifting_card.hpp). With the sync pulse the crank windows must stay within one
// 40 kHz sample all hour; without it, within the uncertainty the assembler states. Prints the error every ten
// minutes; exits 1 when either fails.
//
//   bench_clock_alignment [--minutes N]   (default 60)
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "tests/support/alignment_run.hpp"

int main(int argc, char** argv) {
  double minutes = 60.0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--minutes") == 0 && i + 1 < argc) {
      minutes = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: bench_clock_alignment [--minutes N]\n");
      return std::strcmp(argv[i], "--help") == 0 ? 0 : 2;
    }
  }
  constexpr double kSample = 1.0 / 40000.0;
  bool ok = true;
  for (double ppm : {80.0, -50.0}) {
    for (bool sync : {true, false}) {
      noisemon::test::DriftingCardSpec spec;
      spec.ppm = ppm;
      double worst_window = 0.0, worst_stated = 0.0;
      auto window = [&](double t, double error, double stated) {
        worst_window = std::max(worst_window, std::abs(error));
        worst_stated = std::max(worst_stated, stated);
        if (std::fmod(t, 600.0) < 1.0 || t + 1.0 >= minutes * 60.0) {
          std::printf("  %+5.0f ppm %-7s t %5.0f s: worst error %7.2f us, stated %7.2f us\n", ppm,
                      sync ? "sync" : "host", t, worst_window * 1e6, worst_stated * 1e6);
          std::fflush(stdout);
          worst_window = worst_stated = 0.0;
        }
      };
      const auto run = noisemon::test::run_card(spec, sync, minutes * 60.0, 1e300, window);
      const bool pass =
          sync ? run.worst_error_s < kSample && run.synced && run.sync_losses == 0 : run.worst_error_over_stated <= 1.0;
      std::printf(
          "%+4.0f ppm, %s: worst error %.2f us (%.3f of a 40 kHz sample), %.2f of the stated uncertainty; "
          "tracked %.3f ppm; realigned %llu times, sync lost %llu times: %s\n",
          ppm, sync ? "sync pulse" : "host clock only", run.worst_error_s * 1e6, run.worst_error_s / kSample,
          run.worst_error_over_stated, run.ppm, static_cast<unsigned long long>(run.realignments),
          static_cast<unsigned long long>(run.sync_losses), pass ? "PASS" : "FAIL");
      ok = ok && pass;
    }
  }
  return ok ? 0 : 1;
}
