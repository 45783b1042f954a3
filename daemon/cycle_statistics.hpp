// Statistics over engine cycles, as a test engineer reports them: the energy mean of every level (a sound level
// is averaged as energy, never as dB), the arithmetic mean, standard deviation, coefficient of variation, minimum
// and maximum of every other scalar, the counts of valid and flagged cycles, and Leq(A) over the time the cycles
// cover. Used for a whole recording (`noisemon summary`) and for the daemon's rolling window.
//
// Only valid cycles (flags without settling, a gap or an encoder fault) enter the statistics; the others are
// counted. A value a valid cycle does not have (NaN: no microphone left, a pressure fault) is left out of that
// quantity's statistics, and its Leq(A) covers only the time of the cycles that have it.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "noisemon/cycle_report_t.hpp"
#include "noisemon/cycle_stats_t.hpp"

namespace noisemon::daemon {

struct ScalarStats {
  std::string name;  // the cycle_report_t field, e.g. "imep_net_bar"
  std::string unit;
  bool level = false;  // a level in dB: its mean is the energy mean, its std the std of the dB values
  std::int64_t n = 0;  // cycles with a finite value
  double mean = 0, std = 0, cov = 0, min = 0, max = 0;    // NaN when n == 0 (std, cov: n < 2; cov: a level, an
                                                          // angle, or values of both signs)
  double lnv = std::numeric_limits<double>::quiet_NaN();  // lowest normalised value, min / mean: where COV is, for
                                                          // positive values (the IMEPs' stability figure)
};

struct CycleStatistics {
  std::int64_t cycles = 0;       // every cycle seen
  std::int64_t valid = 0;        // the ones in the statistics
  std::int64_t flagged = 0;      // settling, with a gap or an encoder fault: counted, not averaged
  double seconds = 0;            // time the valid cycles cover
  double leq_a_measured_db = 0;  // Leq(A) over that time: energy mean of Lp(A) weighted by each cycle's duration
  double leq_a_predicted_db = 0;
  std::vector<ScalarStats> scalars;
  std::vector<float> band_hz;                                         // of the first valid cycle
  std::vector<double> spl_a_measured_db, spl_a_predicted_db, cpl_db;  // energy means per band
  // Sound power over the cycles as ISO 3744:2010 computes it over a measurement time: each band's energy mean, its K1
  // against the background (the reports' background_db; 15 dB limit; 1.3 dB within 6 dB of it, which makes the
  // result an upper bound), less K2, plus 10 lg(S / S0), C1 and C2 (the reports'); over the reports' LW band range
  // and the bands every valid cycle kept in its overall levels (none BELOW_FIRING or beyond a passband). The
  // per-cycle LW(A)s' energy mean is the scalar lwa_measured_db.
  double lwa_run_measured_db = std::numeric_limits<double>::quiet_NaN();
  double lwa_run_predicted_db = std::numeric_limits<double>::quiet_NaN();
  bool lwa_run_upper_bound = false;        // a band of lwa_run_measured_db lies within 6 dB of the background
  double c1_db = 0, c2_db = 0;             // in lwa_run_* (of the first valid cycle)
  float lw_low_hz = 0, lw_high_hz = 0;     // the nominal band range of lwa_run_*
  std::vector<double> k1_db;               // per band, of the energy mean (NaN: out of the sound power)
  std::vector<std::int8_t> band_validity;  // per band: BandRunValidity
};
enum BandRunValidity : std::int8_t {
  kBandUncorrected = 0,     // more than 15 dB above the background, or none
  kBandCorrected = 1,       // 6 ... 15 dB above it: K1 by the formula
  kBandUpperBound = 2,      // 6 dB or less above it: K1 1.3 dB, an upper bound (in the sound power)
  kBandNotInOverall = 3,    // not in the overall levels (below the firing frequency, beyond a passband)
  kBandOutsideLwRange = 4,  // outside the sound power's band range (100 Hz ... 10 kHz unless full_range)
};

class CycleStatisticsAccumulator {
 public:
  void add(const noisemon::cycle_report_t& r);
  CycleStatistics result() const;
  void clear();

 private:
  void add_run_sound_power(CycleStatistics& s) const;
  struct Running {
    std::int64_t n = 0;
    double sum = 0, sum_sq = 0, energy = 0, min = 0, max = 0;
  };
  std::int64_t cycles_ = 0, valid_ = 0, flagged_ = 0;
  double seconds_ = 0, energy_measured_s_ = 0, energy_predicted_s_ = 0, seconds_measured_ = 0, seconds_predicted_ = 0;
  std::vector<Running> scalars_;
  std::vector<float> band_hz_;
  std::vector<Running> bands_measured_, bands_predicted_, bands_cpl_;
  std::vector<std::int8_t> band_flags_seen_;  // OR of the valid cycles' band flags
  std::vector<float> background_db_;          // of the first valid cycle
  double k2_db_ = 0, radius_m_ = 0, c1_db_ = 0, c2_db_ = 0;
  float lw_low_hz_ = 0, lw_high_hz_ = 0;
};

// The statistics of a whole recording's reports.
CycleStatistics statistics_of(const std::vector<noisemon::cycle_report_t>& reports);

// The daemon's rolling statistics as the message it publishes (window_cycles: the configured window), and back.
noisemon::cycle_stats_t to_message(const CycleStatistics& s, std::int64_t window_cycles, std::int64_t utime);
CycleStatistics from_message(const noisemon::cycle_stats_t& m);

// The counts and Leq(A), then one "name unit mean std cov min max n" line per scalar.
std::string statistics_text(const CycleStatistics& s);
std::string statistics_json(const CycleStatistics& s);  // one JSON object
std::string statistics_csv_header();
std::string statistics_csv_rows(const CycleStatistics& s, const std::string& run);  // one row per scalar

}  // namespace noisemon::daemon
