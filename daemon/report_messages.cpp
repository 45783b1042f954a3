#include "daemon/report_messages.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace noisemon::daemon {

noisemon::cycle_report_t to_message(const CycleReport& r) {
  noisemon::cycle_report_t m;
  m.utime = r.utime;
  m.cycle = r.cycle;
  m.duration_s = r.duration_s;
  m.speed_rpm = r.op.speed_rpm;
  m.load_nm = r.op.load_nm;
  m.soi_deg_btdc = r.op.soi_deg_btdc;
  m.rail_pressure_bar = r.op.rail_pressure_bar;
  m.motored = r.op.motored;
  m.lpa_measured_db = r.lpa_measured_db;
  m.lpa_predicted_db = r.lpa_predicted_db;
  m.lwa_measured_db = r.lwa_measured_db;
  m.lwa_predicted_db = r.lwa_predicted_db;
  m.radius_m = r.radius_m;
  m.k2_db = r.k2_db;
  m.c1_db = r.c1_db;
  m.c2_db = r.c2_db;
  m.lw_low_hz = r.lw_low_hz;
  m.lw_high_hz = r.lw_high_hz;
  m.nbands = static_cast<std::int16_t>(r.nbands);
  m.band_hz.assign(r.band_hz, r.band_hz + r.nbands);
  m.spl_a_measured_db.assign(r.spl_a_measured_db, r.spl_a_measured_db + r.nbands);
  m.spl_a_predicted_db.assign(r.spl_a_predicted_db, r.spl_a_predicted_db + r.nbands);
  m.cpl_db.assign(r.cpl_db, r.cpl_db + r.nbands);
  m.att_measured_db.assign(r.att_measured_db, r.att_measured_db + r.nbands);
  m.att_predicted_db.assign(r.att_predicted_db, r.att_predicted_db + r.nbands);
  m.band_flags.assign(r.band_flags, r.band_flags + r.nbands);
  m.k1_db.assign(r.k1_db, r.k1_db + r.nbands);
  m.background_db.assign(r.background_db, r.background_db + r.nbands);
  m.nmics = static_cast<std::int16_t>(r.nmics);
  m.mic_lpa_db.assign(r.mic_lpa_db, r.mic_lpa_db + r.nmics);
  m.mic_flags.assign(r.mic_flags, r.mic_flags + r.nmics);
  m.nwindows = static_cast<std::int8_t>(kCrankWindows);
  m.window_lpa_measured_db.assign(r.window_lpa_measured_db, r.window_lpa_measured_db + kCrankWindows);
  m.window_lpa_predicted_db.assign(r.window_lpa_predicted_db, r.window_lpa_predicted_db + kCrankWindows);
  m.flags = r.flags;
  m.processing_ms = r.processing_ms;
  const model::CombustionMetrics& c = r.combustion;
  m.peak_pressure_bar = c.peak_pressure_pa * 1e-5;
  m.peak_pressure_deg = c.peak_angle_deg;
  m.max_rise_bar_per_deg = c.max_rise_pa_per_deg * 1e-5;
  m.max_rise_deg = c.max_rise_angle_deg;
  m.imep_gross_bar = c.imep_gross_pa * 1e-5;
  m.imep_net_bar = c.imep_net_pa * 1e-5;
  m.heat_release_j = c.heat_release_j;
  m.ca10_deg = c.ca10_deg;
  m.ca50_deg = c.ca50_deg;
  m.ca90_deg = c.ca90_deg;
  m.ringing_intensity_MW_per_m2 = c.ringing_intensity_w_per_m2 * 1e-6;
  m.pegging_offset_bar = c.pegging_offset_pa * 1e-5;
  m.mapo_bar = c.mapo_pa * 1e-5;
  m.tdc_deg = r.tdc_deg;
  m.pmep_bar = c.pmep_pa * 1e-5;
  m.n_compression = c.n_compression;
  m.n_expansion = c.n_expansion;
  m.ca05_deg = c.ca05_deg;
  m.burn_duration_deg = c.burn_duration_deg;
  m.max_rise_motored_bar_per_deg = c.max_rise_motored_pa_per_deg * 1e-5;
  m.combustion_noise_db = r.combustion_noise_db;
  return m;
}

std::string cycle_csv_header() {
  return "cycle,utime,speed_rpm,load_nm,soi_deg_btdc,motored,lpa_measured_db,lpa_predicted_db,lwa_measured_db,"
         "lwa_predicted_db,k2_db,flags,peak_pressure_bar,peak_pressure_deg,max_rise_bar_per_deg,max_rise_deg,imep_"
         "gross_bar,"
         "imep_net_bar,heat_release_j,ca10_deg,ca50_deg,ca90_deg,ringing_intensity_MW_per_m2,combustion_noise_db,"
         "pmep_bar,n_compression,n_expansion,ca05_deg,burn_duration_deg,max_rise_motored_bar_per_deg,pegging_offset_"
         "bar,"
         "mapo_bar,condition\n";
}

namespace {
// Any NaN as the one positive quiet NaN, so the CSV says "nan" (a NaN with its sign bit set would print "-nan").
double plain(double v) { return std::isnan(v) ? std::numeric_limits<double>::quiet_NaN() : v; }
}  // namespace

std::string cycle_csv_row(const noisemon::cycle_report_t& r, const std::string& condition) {
  char buf[1024];
  std::snprintf(buf, sizeof buf,
                "%lld,%lld,%.3f,%.3f,%.3f,%d,%.4f,%.4f,%.4f,%.4f,%.2f,%d,%.3f,%.2f,%.4f,%.2f,%.4f,%.4f,%.2f,%.2f,%.2f,%"
                ".2f,%.4f,%.3f,%.4f,%.4f,%.4f,%.2f,%.2f,%.4f,%.4f,%.4f,",
                static_cast<long long>(r.cycle), static_cast<long long>(r.utime), plain(r.speed_rpm), plain(r.load_nm),
                plain(r.soi_deg_btdc), r.motored ? 1 : 0, plain(r.lpa_measured_db), plain(r.lpa_predicted_db),
                plain(r.lwa_measured_db), plain(r.lwa_predicted_db), plain(r.k2_db), r.flags,
                plain(r.peak_pressure_bar), plain(r.peak_pressure_deg), plain(r.max_rise_bar_per_deg),
                plain(r.max_rise_deg), plain(r.imep_gross_bar), plain(r.imep_net_bar), plain(r.heat_release_j),
                plain(r.ca10_deg), plain(r.ca50_deg), plain(r.ca90_deg), plain(r.ringing_intensity_MW_per_m2),
                plain(r.combustion_noise_db), plain(r.pmep_bar), plain(r.n_compression), plain(r.n_expansion),
                plain(r.ca05_deg), plain(r.burn_duration_deg), plain(r.max_rise_motored_bar_per_deg),
                plain(r.pegging_offset_bar), plain(r.mapo_bar));
  std::string row = buf;
  // RFC 4180 quoting when the name needs it.
  if (condition.find_first_of(",\"\r\n") == std::string::npos) {
    row += condition;
  } else {
    row += '"';
    for (char c : condition) row += c == '"' ? std::string("\"\"") : std::string(1, c);
    row += '"';
  }
  row += '\n';
  return row;
}

std::string cycle_flags_text(std::int32_t flags) {
  if (flags == 0) return "ok";
  std::string s;
  auto add = [&](std::int32_t bit, const char* name) {
    if (!(flags & bit)) return;
    if (!s.empty()) s += ',';
    s += name;
  };
  add(noisemon::cycle_report_t::CYCLE_SETTLING, "settling");
  add(noisemon::cycle_report_t::CYCLE_GAP, "gap");
  add(noisemon::cycle_report_t::CYCLE_NO_OPERATING_POINT, "no-op");
  add(noisemon::cycle_report_t::CYCLE_LENGTH_ODD, "odd-length");
  add(noisemon::cycle_report_t::CYCLE_NO_MICS, "no-mics");
  add(noisemon::cycle_report_t::CYCLE_ENCODER, "encoder");
  add(noisemon::cycle_report_t::CYCLE_OVERLOAD, "overload");
  add(noisemon::cycle_report_t::CYCLE_MIC_EXCLUDED, "mic-excluded");
  add(noisemon::cycle_report_t::CYCLE_PRESSURE_FAULT, "pressure-fault");
  add(noisemon::cycle_report_t::CYCLE_LW_UPPER_BOUND, "lw-bound");
  add(noisemon::cycle_report_t::CYCLE_ANGLE_GAP, "angle-gap");
  return s;
}

std::string cycle_line_header() {
  return "   cycle   speed     SOI   Lp(A) meas   pred    LW(A) meas   pred    pred-meas  flags\n"
         "           rpm   degBTDC      dB(A)  dB(A)         dB(A)  dB(A)           dB";
}

namespace {
// A number right-aligned in `width` columns with `decimals`; "n/a" when unknown (NaN: a level not measured, a
// condition value a recording did not state).
std::string value_text(double v, int width, int decimals = 2) {
  char buf[32];
  if (std::isnan(v))
    std::snprintf(buf, sizeof buf, "%*s", width, "n/a");
  else
    std::snprintf(buf, sizeof buf, "%*.*f", width, decimals, v);
  return buf;
}
}  // namespace

std::string cycle_line(const noisemon::cycle_report_t& r) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%8lld %s %s %s %s %s %s %s  %s", static_cast<long long>(r.cycle),
                value_text(r.speed_rpm, 7, 1).c_str(), value_text(r.soi_deg_btdc, 7, 1).c_str(),
                value_text(r.lpa_measured_db, 12).c_str(), value_text(r.lpa_predicted_db, 6).c_str(),
                value_text(r.lwa_measured_db, 13).c_str(), value_text(r.lwa_predicted_db, 6).c_str(),
                value_text(r.lpa_predicted_db - r.lpa_measured_db, 12).c_str(), cycle_flags_text(r.flags).c_str());
  return buf;
}

}  // namespace noisemon::daemon
