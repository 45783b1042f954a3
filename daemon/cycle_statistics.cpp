#include "daemon/cycle_statistics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <string_view>

#include <nlohmann/json.hpp>

#include "dsp/levels.hpp"
#include "dsp/math_constants.hpp"
#include "dsp/sound_power.hpp"
#include "dsp/third_octave_bank.hpp"
#include "dsp/weighting.hpp"

namespace noisemon::daemon {
namespace {

using Report = noisemon::cycle_report_t;

struct Field {
  const char* name;
  const char* unit;
  bool level;
  std::function<double(const Report&)> get;
};

const std::vector<Field>& fields() {
  static const std::vector<Field> f = {
      {"speed_rpm", "rpm", false, [](const Report& r) { return r.speed_rpm; }},
      {"load_nm", "N m", false, [](const Report& r) { return r.load_nm; }},
      {"soi_deg_btdc", "deg", false, [](const Report& r) { return r.soi_deg_btdc; }},
      {"rail_pressure_bar", "bar", false, [](const Report& r) { return r.rail_pressure_bar; }},
      {"lpa_measured_db", "dB(A)", true, [](const Report& r) { return r.lpa_measured_db; }},
      {"lpa_predicted_db", "dB(A)", true, [](const Report& r) { return r.lpa_predicted_db; }},
      {"lwa_measured_db", "dB(A)", true, [](const Report& r) { return r.lwa_measured_db; }},
      {"lwa_predicted_db", "dB(A)", true, [](const Report& r) { return r.lwa_predicted_db; }},
      {"peak_pressure_bar", "bar", false, [](const Report& r) { return r.peak_pressure_bar; }},
      {"peak_pressure_deg", "deg", false, [](const Report& r) { return r.peak_pressure_deg; }},
      {"max_rise_bar_per_deg", "bar/deg", false, [](const Report& r) { return r.max_rise_bar_per_deg; }},
      {"max_rise_deg", "deg", false, [](const Report& r) { return r.max_rise_deg; }},
      {"max_rise_motored_bar_per_deg", "bar/deg", false,
       [](const Report& r) { return r.max_rise_motored_bar_per_deg; }},
      {"imep_gross_bar", "bar", false, [](const Report& r) { return r.imep_gross_bar; }},
      {"imep_net_bar", "bar", false, [](const Report& r) { return r.imep_net_bar; }},
      {"heat_release_j", "J", false, [](const Report& r) { return r.heat_release_j; }},
      {"ca10_deg", "deg", false, [](const Report& r) { return r.ca10_deg; }},
      {"ca50_deg", "deg", false, [](const Report& r) { return r.ca50_deg; }},
      {"ca90_deg", "deg", false, [](const Report& r) { return r.ca90_deg; }},
      {"ringing_intensity_MW_per_m2", "MW/m^2", false, [](const Report& r) { return r.ringing_intensity_MW_per_m2; }},
      {"combustion_noise_db", "dB(A)", true, [](const Report& r) { return r.combustion_noise_db; }},
      {"pmep_bar", "bar", false, [](const Report& r) { return r.pmep_bar; }},
      {"n_compression", "1", false, [](const Report& r) { return r.n_compression; }},
      {"n_expansion", "1", false, [](const Report& r) { return r.n_expansion; }},
      {"ca05_deg", "deg", false, [](const Report& r) { return r.ca05_deg; }},
      {"burn_duration_deg", "deg", false, [](const Report& r) { return r.burn_duration_deg; }},
      {"pegging_offset_bar", "bar", false, [](const Report& r) { return r.pegging_offset_bar; }},
      {"mapo_bar", "bar", false, [](const Report& r) { return r.mapo_bar; }},
      // The encoder's angle of firing TDC the figures used ([combustion] tdc_deg): its std says whether it changed.
      {"tdc_deg", "deg", false, [](const Report& r) { return r.tdc_deg; }},
      {"processing_ms", "ms", false, [](const Report& r) { return static_cast<double>(r.processing_ms); }},
  };
  return f;
}

bool counts_as_valid(const Report& r) {
  // An encoder-flagged cycle's boundaries are uncertain: its duration, speed and levels are not one cycle's.
  constexpr std::int32_t kNotValid =
      std::int32_t{Report::CYCLE_SETTLING} | std::int32_t{Report::CYCLE_GAP} | std::int32_t{Report::CYCLE_ENCODER};
  return !(r.flags & kNotValid);
}

}  // namespace

void CycleStatisticsAccumulator::clear() { *this = CycleStatisticsAccumulator{}; }

void CycleStatisticsAccumulator::add(const Report& r) {
  ++cycles_;
  if (!counts_as_valid(r)) {
    ++flagged_;
    return;
  }
  ++valid_;
  seconds_ += r.duration_s;
  // Leq over the time each level covers: a cycle without one (no microphone left, a pressure fault) adds no time.
  if (std::isfinite(r.lpa_measured_db)) {
    energy_measured_s_ += dsp::mean_square_from_level(r.lpa_measured_db) * r.duration_s;
    seconds_measured_ += r.duration_s;
  }
  if (std::isfinite(r.lpa_predicted_db)) {
    energy_predicted_s_ += dsp::mean_square_from_level(r.lpa_predicted_db) * r.duration_s;
    seconds_predicted_ += r.duration_s;
  }
  auto take = [](Running& s, double v) {
    if (!std::isfinite(v)) return;
    s.min = s.n == 0 ? v : std::min(s.min, v);
    s.max = s.n == 0 ? v : std::max(s.max, v);
    ++s.n;
    s.sum += v;
    s.sum_sq += v * v;
    s.energy += std::pow(10.0, v / 10.0);
  };
  scalars_.resize(fields().size());
  for (std::size_t i = 0; i < fields().size(); ++i) take(scalars_[i], fields()[i].get(r));
  if (band_hz_.empty()) {
    band_hz_ = r.band_hz;
    bands_measured_.assign(band_hz_.size(), {});
    bands_predicted_.assign(band_hz_.size(), {});
    bands_cpl_.assign(band_hz_.size(), {});
    band_flags_seen_.assign(band_hz_.size(), 0);
    background_db_ = r.background_db;
    k2_db_ = r.k2_db;
    radius_m_ = r.radius_m;
    c1_db_ = r.c1_db;
    c2_db_ = r.c2_db;
    lw_low_hz_ = r.lw_low_hz;
    lw_high_hz_ = r.lw_high_hz;
  }
  for (std::size_t b = 0; b < band_hz_.size() && b < static_cast<std::size_t>(r.nbands); ++b) {
    band_flags_seen_[b] |= r.band_flags[b];
    take(bands_measured_[b], r.spl_a_measured_db[b]);
    take(bands_predicted_[b], r.spl_a_predicted_db[b]);
    take(bands_cpl_[b], r.cpl_db[b]);
  }
}

namespace {

double energy_mean_db(double energy, std::int64_t n) {
  return n > 0 ? 10.0 * std::log10(energy / static_cast<double>(n)) : kNaN;
}

// COV (std / mean) means something only on a scale with a true zero: not for a level in dB, nor for a crank angle,
// whose zero is TDC by convention (a CA50 at 1 deg would scatter "100 %" at the same spread as one at 20 deg at 5 %).
bool has_true_zero(const Field& f) { return !f.level && std::string_view(f.unit) != "deg"; }

ScalarStats finish(const Field& f, std::int64_t n, double sum, double sum_sq, double energy, double min, double max) {
  ScalarStats s{f.name, f.unit, f.level, n, kNaN, kNaN, kNaN, kNaN, kNaN};
  if (n == 0) return s;
  const double mean = sum / static_cast<double>(n);
  s.mean = f.level ? energy_mean_db(energy, n) : mean;
  if (n > 1) s.std = std::sqrt(std::max(0.0, (sum_sq - sum * mean) / static_cast<double>(n - 1)));
  // ... and on values of one sign: a COV of an offset scattering about 0 is a ratio of noise to nothing.
  if (has_true_zero(f) && (min > 0 || max < 0) && n > 1) s.cov = s.std / std::abs(mean);
  if (has_true_zero(f) && min > 0) s.lnv = min / mean;
  s.min = min;
  s.max = max;
  return s;
}

}  // namespace

CycleStatistics CycleStatisticsAccumulator::result() const {
  CycleStatistics s;
  s.cycles = cycles_;
  s.valid = valid_;
  s.flagged = flagged_;
  s.seconds = seconds_;
  s.leq_a_measured_db =
      seconds_measured_ > 0 && energy_measured_s_ > 0 ? dsp::level_db(energy_measured_s_ / seconds_measured_) : kNaN;
  s.leq_a_predicted_db = seconds_predicted_ > 0 && energy_predicted_s_ > 0
                             ? dsp::level_db(energy_predicted_s_ / seconds_predicted_)
                             : kNaN;
  for (std::size_t i = 0; i < fields().size(); ++i) {
    const Running r = i < scalars_.size() ? scalars_[i] : Running{};
    s.scalars.push_back(finish(fields()[i], r.n, r.sum, r.sum_sq, r.energy, r.min, r.max));
  }
  s.band_hz = band_hz_;
  for (std::size_t b = 0; b < band_hz_.size(); ++b) {
    s.spl_a_measured_db.push_back(energy_mean_db(bands_measured_[b].energy, bands_measured_[b].n));
    s.spl_a_predicted_db.push_back(energy_mean_db(bands_predicted_[b].energy, bands_predicted_[b].n));
    s.cpl_db.push_back(energy_mean_db(bands_cpl_[b].energy, bands_cpl_[b].n));
  }
  add_run_sound_power(s);
  return s;
}

// ISO 3744 over the cycles: see CycleStatistics::lwa_run_measured_db.
void CycleStatisticsAccumulator::add_run_sound_power(CycleStatistics& s) const {
  constexpr std::int8_t kNotOverall =
      Report::BAND_BELOW_FIRING | Report::BAND_PRESSURE_PASSBAND | Report::BAND_MIC_PASSBAND;
  double measured = 0, predicted = 0;
  bool any = false;
  for (std::size_t b = 0; b < band_hz_.size(); ++b) {
    const double mid = dsp::third_octave_exact_mid_hz(band_hz_[b]);
    const double background = b < background_db_.size() ? background_db_[b] : kNaN;
    dsp::BackgroundCorrection k1;  // no background: uncorrected
    if (!std::isnan(background))
      k1 = dsp::background_correction(s.spl_a_measured_db[b] - dsp::a_weighting_db(mid), background);
    std::int8_t validity = k1.validity == dsp::BandValidity::kUpperBound  ? kBandUpperBound
                           : k1.validity == dsp::BandValidity::kCorrected ? kBandCorrected
                                                                          : kBandUncorrected;
    if (band_flags_seen_[b] & kNotOverall)
      validity = kBandNotInOverall;
    else if (band_hz_[b] < lw_low_hz_ || band_hz_[b] > lw_high_hz_)
      validity = kBandOutsideLwRange;
    s.band_validity.push_back(validity);
    const bool in = validity <= kBandUpperBound && std::isfinite(k1.k1_db);
    s.k1_db.push_back(in ? k1.k1_db : kNaN);
    if (!in) continue;
    measured += std::pow(10.0, (s.spl_a_measured_db[b] - k1.k1_db) / 10.0);
    predicted += std::pow(10.0, s.spl_a_predicted_db[b] / 10.0);
    s.lwa_run_upper_bound = s.lwa_run_upper_bound || validity == kBandUpperBound;
    any = true;
  }
  const double term = dsp::hemisphere_area_term_db(radius_m_) - k2_db_ + c1_db_ + c2_db_;
  s.lwa_run_measured_db = any ? 10.0 * std::log10(measured) + term : kNaN;
  s.lwa_run_predicted_db = any ? 10.0 * std::log10(predicted) + term : kNaN;
  s.c1_db = c1_db_;
  s.c2_db = c2_db_;
  s.lw_low_hz = lw_low_hz_;
  s.lw_high_hz = lw_high_hz_;
}

CycleStatistics statistics_of(const std::vector<Report>& reports) {
  CycleStatisticsAccumulator acc;
  for (const Report& r : reports) acc.add(r);
  return acc.result();
}

noisemon::cycle_stats_t to_message(const CycleStatistics& s, std::int64_t window_cycles, std::int64_t utime) {
  noisemon::cycle_stats_t m;
  m.utime = utime;
  m.window_cycles = static_cast<std::int32_t>(window_cycles);
  m.cycles = static_cast<std::int32_t>(s.cycles);
  m.valid = static_cast<std::int32_t>(s.valid);
  m.flagged = static_cast<std::int32_t>(s.flagged);
  m.seconds = s.seconds;
  m.leq_a_measured_db = s.leq_a_measured_db;
  m.leq_a_predicted_db = s.leq_a_predicted_db;
  m.nscalars = static_cast<std::int16_t>(s.scalars.size());
  for (const ScalarStats& v : s.scalars) {
    m.name.push_back(v.name);
    m.unit.push_back(v.unit);
    m.level.push_back(v.level);
    m.n.push_back(static_cast<std::int32_t>(v.n));
    m.mean.push_back(v.mean);
    m.stddev.push_back(v.std);
    m.cov.push_back(v.cov);
    m.min.push_back(v.min);
    m.max.push_back(v.max);
  }
  m.nbands = static_cast<std::int16_t>(s.band_hz.size());
  m.band_hz = s.band_hz;
  m.spl_a_measured_db = s.spl_a_measured_db;
  m.spl_a_predicted_db = s.spl_a_predicted_db;
  m.cpl_db = s.cpl_db;
  m.lwa_run_measured_db = s.lwa_run_measured_db;
  m.lwa_run_predicted_db = s.lwa_run_predicted_db;
  m.lwa_run_upper_bound = s.lwa_run_upper_bound;
  m.c1_db = s.c1_db;
  m.c2_db = s.c2_db;
  m.lw_low_hz = s.lw_low_hz;
  m.lw_high_hz = s.lw_high_hz;
  m.k1_db = s.k1_db;
  m.band_validity = s.band_validity;
  return m;
}

CycleStatistics from_message(const noisemon::cycle_stats_t& m) {
  CycleStatistics s;
  s.cycles = m.cycles;
  s.valid = m.valid;
  s.flagged = m.flagged;
  s.seconds = m.seconds;
  s.leq_a_measured_db = m.leq_a_measured_db;
  s.leq_a_predicted_db = m.leq_a_predicted_db;
  for (int i = 0; i < m.nscalars; ++i)
    s.scalars.push_back(
        {m.name[i], m.unit[i], m.level[i] != 0, m.n[i], m.mean[i], m.stddev[i], m.cov[i], m.min[i], m.max[i]});
  s.band_hz = m.band_hz;
  s.spl_a_measured_db = m.spl_a_measured_db;
  s.spl_a_predicted_db = m.spl_a_predicted_db;
  s.cpl_db = m.cpl_db;
  s.lwa_run_measured_db = m.lwa_run_measured_db;
  s.lwa_run_predicted_db = m.lwa_run_predicted_db;
  s.lwa_run_upper_bound = m.lwa_run_upper_bound;
  s.c1_db = m.c1_db;
  s.c2_db = m.c2_db;
  s.lw_low_hz = m.lw_low_hz;
  s.lw_high_hz = m.lw_high_hz;
  s.k1_db = m.k1_db;
  s.band_validity = m.band_validity;
  return s;
}

namespace {
std::string fmt_range(float low_hz, float high_hz) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%g Hz ... %g kHz", low_hz, high_hz / 1000.0);
  return buf;
}

// "  bands corrected for the background (K1): 5000 Hz (0.75 dB)" and the bands within 6 dB of it; empty without either.
std::string band_validity_text(const CycleStatistics& s) {
  std::string corrected, bound;
  char item[48];
  for (std::size_t b = 0; b < s.band_validity.size() && b < s.band_hz.size(); ++b) {
    if (s.band_validity[b] == kBandCorrected) {
      std::snprintf(item, sizeof item, "%s%g Hz (%.2f dB)", corrected.empty() ? "" : ", ", s.band_hz[b], s.k1_db[b]);
      corrected += item;
    } else if (s.band_validity[b] == kBandUpperBound) {
      std::snprintf(item, sizeof item, "%s%g Hz", bound.empty() ? "" : ", ", s.band_hz[b]);
      bound += item;
    }
  }
  std::string out;
  if (!corrected.empty()) out += "  bands corrected for the background (K1): " + corrected + "\n";
  if (!bound.empty())
    out += "  bands 6 dB or less above the background (K1 1.3 dB, LW an upper bound): " + bound + "\n";
  return out;
}
}  // namespace

std::string statistics_text(const CycleStatistics& s) {
  char line[256];
  std::snprintf(line, sizeof line,
                "cycles %lld: %lld valid, %lld flagged (settling, gap or encoder); %.2f s; Leq(A) measured %.2f dB, "
                "predicted %.2f dB\n",
                static_cast<long long>(s.cycles), static_cast<long long>(s.valid), static_cast<long long>(s.flagged),
                s.seconds, s.leq_a_measured_db, s.leq_a_predicted_db);
  std::string out = line;
  const std::string range =
      std::isfinite(s.lw_high_hz) ? fmt_range(s.lw_low_hz, s.lw_high_hz) : std::string("all bands");
  std::snprintf(line, sizeof line,
                "LW(A) over the cycles (ISO 3744:2010, %s: energy-mean bands, K1, K2, C1 %+.2f, C2 %+.2f dB): "
                "measured %.2f dB%s, predicted %.2f dB\n",
                range.c_str(), s.c1_db, s.c2_db, s.lwa_run_measured_db,
                s.lwa_run_upper_bound ? " (an upper bound)" : "", s.lwa_run_predicted_db);
  out += line;
  out += band_validity_text(s);
  out += "  quantity                     unit         mean        std      cov        min        max      n\n";
  for (const ScalarStats& v : s.scalars) {
    std::snprintf(line, sizeof line, "  %-28s %-8s %10.4g %10.4g %8.4f %10.4g %10.4g %6lld%s\n", v.name.c_str(),
                  v.unit.c_str(), v.mean, v.std, v.cov, v.min, v.max, static_cast<long long>(v.n),
                  v.level ? "  (energy mean)" : "");
    out += line;
  }
  const auto lnv = [&](const char* name) {
    for (const ScalarStats& v : s.scalars)
      if (v.name == name) return v.lnv;
    return kNaN;
  };
  if (std::isfinite(lnv("imep_gross_bar")) || std::isfinite(lnv("imep_net_bar"))) {
    std::snprintf(line, sizeof line, "  LNV of IMEP (lowest / mean): gross %.1f %%, net %.1f %%\n",
                  100 * lnv("imep_gross_bar"), 100 * lnv("imep_net_bar"));
    out += line;
  }
  return out;
}

std::string statistics_json(const CycleStatistics& s) {
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j = {{"cycles", s.cycles},
                      {"valid", s.valid},
                      {"flagged", s.flagged},
                      {"seconds", s.seconds},
                      {"leq_a_measured_db", num(s.leq_a_measured_db)},
                      {"leq_a_predicted_db", num(s.leq_a_predicted_db)}};
  for (const ScalarStats& v : s.scalars)
    j["scalars"][v.name] = {{"unit", v.unit},      {"energy_mean", v.level}, {"n", v.n},
                            {"mean", num(v.mean)}, {"std", num(v.std)},      {"cov", num(v.cov)},
                            {"min", num(v.min)},   {"max", num(v.max)},      {"lnv", num(v.lnv)}};
  j["lwa_run_measured_db"] = num(s.lwa_run_measured_db);
  j["lwa_run_predicted_db"] = num(s.lwa_run_predicted_db);
  j["lwa_run_upper_bound"] = s.lwa_run_upper_bound;
  j["c1_db"] = num(s.c1_db);
  j["c2_db"] = num(s.c2_db);
  j["lw_band_range_hz"] = {num(s.lw_low_hz), num(s.lw_high_hz)};
  j["bands"]["hz"] = s.band_hz;
  j["bands"]["band_validity"] = s.band_validity;
  for (auto [key, values] : {std::pair{"spl_a_measured_db", &s.spl_a_measured_db},
                             {"spl_a_predicted_db", &s.spl_a_predicted_db},
                             {"cpl_db", &s.cpl_db},
                             {"k1_db", &s.k1_db}}) {
    nlohmann::json a = nlohmann::json::array();
    for (double v : *values) a.push_back(num(v));
    j["bands"][key] = a;
  }
  return j.dump(1);
}

std::string statistics_csv_header() { return "run,quantity,unit,energy_mean,n,mean,std,cov,min,max,lnv\n"; }

std::string statistics_csv_rows(const CycleStatistics& s, const std::string& run) {
  std::string out;
  char line[320];
  auto plain = [](double v) { return std::isnan(v) ? kNaN : v; };
  for (const ScalarStats& v : s.scalars) {
    std::snprintf(line, sizeof line, "%s,%s,%s,%d,%lld,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", run.c_str(), v.name.c_str(),
                  v.unit.c_str(), v.level ? 1 : 0, static_cast<long long>(v.n), plain(v.mean), plain(v.std),
                  plain(v.cov), plain(v.min), plain(v.max), plain(v.lnv));
    out += line;
  }
  for (auto [name, value] :
       {std::pair{"lwa_run_measured_db", s.lwa_run_measured_db}, {"lwa_run_predicted_db", s.lwa_run_predicted_db}}) {
    std::snprintf(line, sizeof line, "%s,%s,dB(A),1,%lld,%.6g,nan,nan,nan,nan,nan\n", run.c_str(), name,
                  static_cast<long long>(s.valid), plain(value));
    out += line;
  }
  return out;
}

}  // namespace noisemon::daemon
