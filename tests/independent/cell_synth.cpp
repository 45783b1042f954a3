// The independent test cell (see cell_synth.hpp): the records, the physics, the pressure and the microphones. Standard
// library and Eigen's FFT only; the writers are in cell_writers.cpp.
#include "cell_synth.hpp"

#include "cell_block.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <numbers>
#include <random>
#include <stdexcept>

// FFTW behind Eigen's FFT interface: the cell's transforms (long, 2^a 3^b 5^c points) were half of an independent
// test's time with Eigen's own kissfft.
#define EIGEN_FFTW_DEFAULT
#include <unsupported/Eigen/FFT>

namespace indep {
namespace {

using cd = std::complex<double>;
constexpr double kPref = 20e-6;  // Pa
constexpr double kBarToPa = 1e5;
constexpr double kDeviationCutoffHz = 1000;  // each cycle's deviation below it is kept whole (the floor is far below)
constexpr double kMeanCutoffHz = 4000;       // the ensemble mean below it likewise

// One transform object per thread keeps its plans for the next call of the same length. FFTW's planner is shared by
// all threads (the withheld matrix synthesises on several): made safe for that once, before the first plan.
Eigen::FFT<double>& thread_fft() {
  static const bool planner_safe = (fftw_make_planner_thread_safe(), true);
  (void)planner_safe;
  thread_local Eigen::FFT<double> fft;
  return fft;
}

std::vector<cd> fft_fwd(const std::vector<double>& x) {
  const std::vector<cd> in(x.begin(), x.end());
  std::vector<cd> out;
  thread_fft().fwd(out, in);
  return out;
}

std::vector<double> fft_inv_real(const std::vector<cd>& X) {
  Eigen::FFT<double>& fft = thread_fft();
  std::vector<cd> out;
  fft.inv(out, X);  // scaled by 1/n
  std::vector<double> y(out.size());
  for (std::size_t i = 0; i < out.size(); ++i) y[i] = out[i].real();
  return y;
}

std::vector<double> parse_numbers(const std::string& line, const std::string& path, std::size_t lineno) {
  std::vector<double> v;
  const char* p = line.c_str();
  while (true) {
    while (*p == ' ' || *p == '\t' || *p == '\r') ++p;
    if (*p == '\0') break;
    char* end = nullptr;
    const double x = std::strtod(p, &end);
    if (end == p || !std::isfinite(x))
      throw std::runtime_error(path + ": line " + std::to_string(lineno) + ": not a finite number near \"" +
                               std::string(p).substr(0, 16) + "\"");
    v.push_back(x);
    p = end;
  }
  return v;
}

void check_angles(const CycleTable& t, const std::string& path) {
  if (t.crank_deg.size() != static_cast<std::size_t>(kSamplesPerCycle))
    throw std::runtime_error(path + ": " + std::to_string(t.crank_deg.size()) +
                             " rows, expected 3600 (720 deg in 0.2 deg)");
  for (std::size_t i = 1; i < t.crank_deg.size(); ++i) {
    const double step = t.crank_deg[i] - t.crank_deg[i - 1];
    if (std::abs(step - kRecordStepDeg) > 0.01 * kRecordStepDeg)
      throw std::runtime_error(path + ": line " + std::to_string(i + 1) + ": crank step " + std::to_string(step) +
                               " deg, expected 0.2");
  }
  if (std::abs(t.crank_deg.front() + 180.0) > 1e-6)
    throw std::runtime_error(path + ": the table starts at " + std::to_string(t.crank_deg.front()) +
                             " deg, expected -180");
}

// The record's columns laid end to end as `cycles` cycles [720k - 360, 720k + 360): cycle k is column first+k's
// 360 ... 539.8 deg (rows 2700 ...) then column first+k+1's -180 ... 359.8 deg (rows 0 ... 2699).
std::vector<double> lay_out(const CycleTable& t, int first, int cycles) {
  if (first < 0 || first + cycles + 1 > static_cast<int>(t.cycles_bar.size()))
    throw std::runtime_error("cycles " + std::to_string(first) + " ... " + std::to_string(first + cycles) +
                             " asked of a record of " + std::to_string(t.cycles_bar.size()));
  constexpr int kTail = 2700;  // row of +360 deg
  std::vector<double> x;
  x.reserve(static_cast<std::size_t>(cycles) * kSamplesPerCycle);
  for (int k = 0; k < cycles; ++k) {
    const auto& a = t.cycles_bar[first + k];
    const auto& b = t.cycles_bar[first + k + 1];
    x.insert(x.end(), a.begin() + kTail, a.end());
    x.insert(x.end(), b.begin(), b.begin() + kTail);
  }
  return x;
}

std::vector<double> ensemble_mean(const std::vector<double>& x, int cycles) {
  std::vector<double> m(kSamplesPerCycle, 0.0);
  for (int k = 0; k < cycles; ++k)
    for (int i = 0; i < kSamplesPerCycle; ++i) m[i] += x[static_cast<std::size_t>(k) * kSamplesPerCycle + i] / cycles;
  return m;
}

// The amplitude gain that leaves a band's content above its floor: power P = floor * 10^(excess/10) becomes P - floor
// (spectral subtraction).
double above_floor_gain(double excess_db) { return std::sqrt(std::max(0.0, 1.0 - std::pow(10.0, -excess_db / 10.0))); }

// What the low-passed pressure keeps of a laid-out run: the condition's own ensemble mean below 4 kHz plus each
// cycle's deviation from it below 1 kHz. Everything else in the record is its floor unless it stands above it.
std::vector<double> low_passed(const std::vector<double>& x, int cycles, double speed_rpm) {
  const double rate = 30.0 * speed_rpm;  // samples per second (0.2 deg)
  const std::vector<double> mean = ensemble_mean(x, cycles);
  const std::vector<double> mean_lp = lowpass(mean, kMeanCutoffHz / rate);
  std::vector<double> dev(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) dev[i] = x[i] - mean[i % kSamplesPerCycle];
  std::vector<double> smooth = lowpass(dev, kDeviationCutoffHz / rate);
  for (std::size_t i = 0; i < x.size(); ++i) smooth[i] += mean_lp[i % kSamplesPerCycle];
  return smooth;
}

// r split into the kFloorBands bands (see the header): the parts sum to r.
std::vector<std::vector<double>> band_parts(const std::vector<double>& r, double speed_rpm) {
  std::vector<std::vector<double>> parts;
  std::vector<double> below(r.size(), 0.0);
  for (std::size_t e = 1; e <= kFloorBands; ++e) {
    const double edge_per_sample = 1000.0 * std::exp2(static_cast<double>(2 * e - 1) / 6.0) / (30.0 * speed_rpm);
    std::vector<double> next = e < kFloorBands && edge_per_sample < 0.45 ? lowpass(r, edge_per_sample, 0.9, 1.1) : r;
    std::vector<double> part(r.size());
    for (std::size_t i = 0; i < r.size(); ++i) part[i] = next[i] - below[i];
    parts.push_back(std::move(part));
    below = std::move(next);
  }
  return parts;
}

// The clean pressure of a laid-out run (see the header): the low-passed pressure plus, per band and crank angle, the
// rest of the record with its floor's power taken out (excess_db, see excess_over_floor_db).
std::vector<double> clean_of(const std::vector<double>& x, int cycles, double speed_rpm,
                             const std::vector<std::vector<double>>& excess_db) {
  std::vector<double> clean = low_passed(x, cycles, speed_rpm);
  std::vector<double> rest(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) rest[i] = x[i] - clean[i];
  const auto parts = band_parts(rest, speed_rpm);
  for (std::size_t i = 0; i < x.size(); ++i) {
    const int j = static_cast<int>(i % kSamplesPerCycle);
    for (std::size_t b = 0; b < kFloorBands; ++b) clean[i] += above_floor_gain(excess_db[b][j]) * parts[b][i];
  }
  return clean;
}

bool five_smooth(std::size_t n) {
  for (std::size_t p : {2u, 3u, 5u})
    while (n % p == 0) n /= p;
  return n == 1;
}

// The second mode's panel, sized so that the total is +db at f0 over the structure alone: |1 + c z| = g with
// z = R(f0) / H(f0) = 1 / H(f0), the positive root of c^2 |z|^2 + 2 c Re z + 1 - g^2 = 0.
double panel_scale(const Structure& st, const Effects& fx) {
  const cd z = 1.0 / eq41(fx.second_mode_hz, st);
  const double g2 = std::pow(10.0, fx.second_mode_db / 10.0), a = std::norm(z), b = z.real();
  return (-b + std::sqrt(b * b + a * (g2 - 1.0))) / a;
}

}  // namespace

// ------------------------------------------------------------------------------------------ records

CycleTable read_cycle_table(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  CycleTable t;
  std::string line;
  std::size_t lineno = 0, columns = 0;
  while (std::getline(in, line)) {
    ++lineno;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const std::vector<double> v = parse_numbers(line, path, lineno);
    if (columns == 0) {
      columns = v.size();
      if (columns < 3) throw std::runtime_error(path + ": line 1: expected an angle and at least two cycles");
      t.cycles_bar.resize(columns - 1);
    }
    if (v.size() != columns)
      throw std::runtime_error(path + ": line " + std::to_string(lineno) + ": " + std::to_string(v.size()) +
                               " columns, expected " + std::to_string(columns));
    t.crank_deg.push_back(v[0]);
    for (std::size_t c = 1; c < columns; ++c) t.cycles_bar[c - 1].push_back(v[c]);
  }
  check_angles(t, path);
  return t;
}

Sources load_sources(const std::string& dir) {
  return {read_cycle_table(dir + "/yanmar_l100v_fired_18Nm.txt"), read_cycle_table(dir + "/yanmar_l100v_motored.txt")};
}

// ------------------------------------------------------------------------------------------ physics

std::complex<double> eq41(double f_hz, const Structure& st) {
  const double wb = 2 * kPi * st.fb_hz, wn = 2 * kPi * st.fn_hz;
  const cd s(0.0, 2 * kPi * f_hz);
  return st.ka * (s + wb) / (s * s + 2 * st.zeta * wn * s + wn * wn);
}

std::complex<double> resonance(double f_hz, double f0_hz, double q) {
  const cd x(0.0, f_hz / (q * f0_hz));
  const double r = f_hz / f0_hz;
  return x / (1.0 - r * r + x);
}

double a_weighting_db(double f_hz) {
  const double f2 = f_hz * f_hz;
  const double num = 12194.0 * 12194.0 * f2 * f2;
  const double den =
      (f2 + 20.6 * 20.6) * std::sqrt((f2 + 107.7 * 107.7) * (f2 + 737.9 * 737.9)) * (f2 + 12194.0 * 12194.0);
  return 20.0 * std::log10(num / den) + 2.0;
}

const std::array<std::array<double, 3>, kMics>& mic_positions_m() {
  static const std::array<std::array<double, 3>, kMics> p{{{-1.35, 0.78, 0.79},
                                                           {0.00, 1.73, 0.26},
                                                           {0.00, 1.16, 1.31},
                                                           {1.00, -0.58, 1.31},
                                                           {0.00, 0.00, 1.75},
                                                           {1.35, 0.78, 0.79},
                                                           {1.50, -0.87, 0.26},
                                                           {0.00, -1.16, 1.31},
                                                           {-1.00, -0.58, 1.31},
                                                           {-1.50, -0.87, 0.26}}};
  return p;
}

const std::array<double, kMics>& directivity_db() {
  static const std::array<double, kMics> g{0.6, -0.4, 0.9, -0.8, 0.2, -0.3, 0.7, -0.9, 0.4, -0.1};
  return g;
}

std::vector<double> radiate(const std::vector<double>& u, std::size_t n_out, double period_s,
                            const Transfer& transfer) {
  const std::size_t n_in = u.size();
  const std::vector<cd> U = fft_fwd(u);
  std::vector<cd> Y(n_out, cd(0.0, 0.0));
  const std::size_t k_max = (std::min(n_in, n_out) - 1) / 2;  // strictly below both Nyquist limits
  const double scale = static_cast<double>(n_out) / static_cast<double>(n_in);
  Y[0] = scale * transfer(0.0).real() * U[0].real();
  for (std::size_t k = 1; k <= k_max; ++k) {
    Y[k] = scale * transfer(static_cast<double>(k) / period_s) * U[k];
    Y[n_out - k] = std::conj(Y[k]);
  }
  return fft_inv_real(Y);
}

std::vector<double> lowpass(const std::vector<double>& x, double cutoff, double edge_lo, double edge_hi) {
  std::vector<cd> X = fft_fwd(x);
  const std::size_t n = X.size();
  const double lo = edge_lo * cutoff, hi = edge_hi * cutoff;
  for (std::size_t k = 1; k < n; ++k) {
    const double f = static_cast<double>(std::min(k, n - k)) / static_cast<double>(n);
    const double g = f <= lo ? 1.0 : f >= hi ? 0.0 : 0.5 * (1.0 + std::cos(kPi * (f - lo) / (hi - lo)));
    X[k] *= g;
  }
  return fft_inv_real(X);
}

std::complex<double> structural_transfer(double f_hz, double speed_rpm, const Structure& st, const Effects& fx) {
  return eq41(f_hz, st) * speed_gain(speed_rpm, fx) + panel_transfer(f_hz, speed_rpm, st, fx);
}

double speed_gain(double speed_rpm, const Effects& fx) {
  return std::pow(speed_rpm / fx.speed_ref_rpm, fx.speed_exponent);
}

std::complex<double> panel_transfer(double f_hz, double speed_rpm, const Structure& st, const Effects& fx) {
  if (fx.second_mode_db <= 0 || f_hz <= 0) return 0.0;
  return speed_gain(speed_rpm, fx) * panel_scale(st, fx) * resonance(f_hz, fx.second_mode_hz, fx.second_mode_q);
}

std::complex<double> mic_error(double f_hz, int mic, const Effects& fx) {
  if (mic != fx.mic_gain_index || fx.mic_gain_db == 0) return 1.0;
  const double g = std::pow(10.0, fx.mic_gain_db / 20.0);
  if (fx.mic_gain_corner_hz <= 0) return g;
  const cd x(0.0, f_hz / fx.mic_gain_corner_hz);
  return 1.0 + (g - 1.0) * x / (1.0 + x);
}

namespace {
double mean_square(const std::vector<cd>& X, double fs_hz, bool a_weighted) {
  const std::size_t n = X.size();
  double ms = 0;
  for (std::size_t k = 1; k < n; ++k) {
    const double f = static_cast<double>(std::min(k, n - k)) * fs_hz / static_cast<double>(n);
    ms += std::norm(X[k]) * (a_weighted ? std::pow(10.0, a_weighting_db(f) / 10.0) : 1.0);
  }
  return ms / (static_cast<double>(n) * static_cast<double>(n));
}
}  // namespace

double level_db(const std::vector<double>& x_pa, double fs_hz, bool a_weighted) {
  return 10.0 * std::log10(mean_square(fft_fwd(x_pa), fs_hz, a_weighted) / (kPref * kPref));
}

double median_second_difference_bar(const CycleTable& t) {
  std::vector<double> d;
  for (const std::vector<double>& p : t.cycles_bar)
    for (std::size_t i = 1; i + 1 < p.size(); ++i)
      if (t.crank_deg[i] >= -120 && t.crank_deg[i] <= -60) d.push_back(std::abs(p[i + 1] - 2 * p[i] + p[i - 1]));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

double record_floor_bar(const CycleTable& t) {
  constexpr double kHalfNormalMedian = 0.6744897501960817;  // median of |N(0, 1)|
  return median_second_difference_bar(t) / (kHalfNormalMedian * std::sqrt(6.0));
}

std::vector<std::vector<double>> excess_over_floor_db(const CycleTable& t, double speed_rpm) {
  const int cycles = static_cast<int>(t.cycles_bar.size()) - 1;
  const std::vector<double> x = lay_out(t, 0, cycles);
  const std::vector<double> smooth = low_passed(x, cycles, speed_rpm);
  std::vector<double> rest(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) rest[i] = x[i] - smooth[i];
  std::vector<std::vector<double>> excess;
  for (const std::vector<double>& part : band_parts(rest, speed_rpm)) {
    std::vector<double> power(kSamplesPerCycle, 0.0);
    for (std::size_t i = 0; i < part.size(); ++i) power[i % kSamplesPerCycle] += part[i] * part[i] / cycles;
    constexpr int half = 50;  // 10 deg
    std::vector<double> local(kSamplesPerCycle, 0.0);
    for (int j = 0; j < kSamplesPerCycle; ++j)
      for (int d = -half; d <= half; ++d)
        local[j] += power[(j + d + kSamplesPerCycle) % kSamplesPerCycle] / (2 * half + 1);
    std::vector<double> sorted = local;
    const auto quiet = sorted.begin() + kSamplesPerCycle / 20;  // the floor: the record's level where it is quietest
    std::nth_element(sorted.begin(), quiet, sorted.end());
    const double floor = *quiet;
    for (double& v : local) v = floor > 0 ? 10.0 * std::log10(v / floor) : -300.0;  // an empty band: nothing above
    excess.push_back(std::move(local));
  }
  return excess;
}

// ------------------------------------------------------------------------------------------ the cell

namespace {

// A run's first record column at `seed`: moved by 11 columns per seed after the first, wrapping within the columns a
// run of last_first's length may start at.
int shifted_column(int first, int last_first, std::uint64_t seed) {
  const auto columns = static_cast<std::uint64_t>(last_first + 1);
  return static_cast<int>((static_cast<std::uint64_t>(first) + 11 * (seed - 1)) % columns);
}

}  // namespace

std::vector<Condition> default_conditions(int cycles, std::uint64_t seed) {
  struct Fired {
    double rpm, load;
    bool unknown;
  };
  constexpr Fired fired[] = {
      {1500, 0.85, false}, {1800, 1.0, true}, {2000, 0.7, false}, {2200, 1.15, false}, {2600, 1.3, false}};
  const int last_first = 59 - cycles;  // 60 columns; cycles + 1 consecutive ones per run
  const auto shift = [&](int first) { return shifted_column(first, last_first, seed); };
  std::vector<Condition> out;
  for (int i = 0; i < 5; ++i) {
    Condition c;
    char name[40];
    std::snprintf(name, sizeof name, "fired_%04.0f_l%03.0f", fired[i].rpm, 100 * fired[i].load);
    c.name = name;
    c.speed_rpm = fired[i].rpm;
    c.load_scale = fired[i].load;
    c.load_unknown = fired[i].unknown;
    c.first_cycle = shift(static_cast<int>(std::lround(i * last_first / 4.0)));
    c.cycles = cycles;
    out.push_back(c);
  }
  out.push_back({"motored_1800", 1800, 1.0, true, false, shift(0), cycles});
  out.push_back({"motored_2600", 2600, 1.0, true, false, shift(last_first), cycles});
  return out;
}

std::vector<Condition> second_cell_conditions(int cycles, std::uint64_t seed) {
  struct Fired {
    double rpm, load;
  };
  constexpr Fired fired[] = {{1400, 0.8}, {1400, 1.2}, {2000, 0.75}, {2000, 1.25}, {2400, 0.9}, {2400, 1.1}};
  const int last_first = 59 - cycles;  // 60 columns; cycles + 1 consecutive ones per run
  const auto shift = [&](int first) { return shifted_column(first, last_first, seed); };
  std::vector<Condition> out;
  for (int i = 0; i < 6; ++i) {
    Condition c;
    char name[40];
    std::snprintf(name, sizeof name, "op_%04.0f_l%03.0f", fired[i].rpm, 100 * fired[i].load);
    c.name = name;
    c.speed_rpm = fired[i].rpm;
    c.load_scale = fired[i].load;
    c.first_cycle = shift(static_cast<int>(std::lround(i * last_first / 5.0)));
    c.cycles = cycles;
    out.push_back(c);
  }
  out.push_back({"motored_2000", 2000, 1.0, true, false, shift(last_first / 2), cycles});
  return out;
}

Chain second_cell_chain(std::uint64_t seed) {
  Chain chain;
  chain.structure = kSecondCellStructure;
  chain.added_pressure_noise_bar = 0.05;
  chain.seed = seed;
  return chain;
}

Timing timing(double nominal_rpm, int cycles, double fs_hz) {
  const double target = 120.0 * cycles / nominal_rpm * fs_hz;
  const auto t = static_cast<std::size_t>(std::llround(target));
  std::size_t n = t;
  for (std::size_t d = 0; d < t; ++d) {
    if (five_smooth(t + d)) {
      n = t + d;
      break;
    }
    if (five_smooth(t - d)) {
      n = t - d;
      break;
    }
  }
  const double period = static_cast<double>(n) / fs_hz;
  return {120.0 * cycles / period, period, n};
}

CellPressure condition_pressure(const Sources& src, const Condition& c, double speed_rpm) {
  const CycleTable& table = c.motored ? src.motored : src.fired;
  const std::vector<double> x = lay_out(table, c.first_cycle, c.cycles);
  CellPressure p;
  p.clean_bar = clean_of(x, c.cycles, speed_rpm, excess_over_floor_db(table, speed_rpm));
  p.recorded_bar = x;  // load scale 1: pressure.csv is the record itself
  if (c.motored || c.load_scale == 1.0) return p;
  // "motored": the motored record's clean mean over all its cycles (no content above 4 kHz without combustion).
  const int all = static_cast<int>(src.motored.cycles_bar.size()) - 1;
  const std::vector<double> base =
      lowpass(ensemble_mean(lay_out(src.motored, 0, all), all), kMeanCutoffHz / (30.0 * speed_rpm));
  for (std::size_t i = 0; i < x.size(); ++i) {
    // recorded - clean: the record's floor as its chain wrote it (what the engine does not hear)
    const double b = base[i % kSamplesPerCycle], noise = x[i] - p.clean_bar[i];
    p.clean_bar[i] = b + c.load_scale * (p.clean_bar[i] - b);
    p.recorded_bar[i] = p.clean_bar[i] + noise;  // added back unscaled
  }
  return p;
}

// ------------------------------------------------------------------------------------------ microphones

namespace {

// Stationary Gaussian noise, one period of n samples, power spectrum shape(f) (f > 0), scaled to exactly `level_db`
// (A-weighted or not) over the period.
std::vector<double> shaped_noise(std::size_t n, double fs_hz, const std::function<double(double)>& shape, double level,
                                 bool a_weighted, std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<cd> X(n, cd(0.0, 0.0));
  for (std::size_t k = 1; k <= (n - 1) / 2; ++k) {
    const double a = normal(rng), b = normal(rng);
    X[k] = std::sqrt(shape(static_cast<double>(k) * fs_hz / static_cast<double>(n))) * cd(a, b);
    X[n - k] = std::conj(X[k]);
  }
  const double gain = std::sqrt(kPref * kPref * std::pow(10.0, level / 10.0) / mean_square(X, fs_hz, a_weighted));
  for (auto& v : X) v *= gain;
  return fft_inv_real(X);
}

std::mt19937_64 rng_for(const Chain& chain, int condition, int mic, int stream) {
  std::seed_seq seq{static_cast<std::uint32_t>(chain.seed), static_cast<std::uint32_t>(chain.seed >> 32),
                    static_cast<std::uint32_t>(condition), static_cast<std::uint32_t>(mic),
                    static_cast<std::uint32_t>(stream)};
  return std::mt19937_64(seq);
}

// Crank-angle-locked impacts: a decaying two-tone burst at fixed angles of every cycle (deg from firing TDC).
struct Impact {
  double angle_deg, weight;
};
constexpr Impact kImpacts[] = {{-150, 0.6}, {8, 1.0}, {140, 0.8}, {355, 0.7}};  // IVC, piston slap, EVO, EVC/IVO
constexpr double kImpactDecayS = 0.4e-3;

double impact_shape(double t) {
  if (t < 0) return 0.0;
  return std::exp(-t / kImpactDecayS) * (std::sin(2 * kPi * 2500 * t) + 0.7 * std::sin(2 * kPi * 5200 * t + 0.6));
}

// One impact of one cycle as it varies from cycle to cycle: its angle error and its amplitude factor.
struct Hit {
  double jitter_deg = 0.0, amplitude = 1.0;
};

// Unit-amplitude impacts of every cycle of the run as heard `delay_s` later, added to y (periodic: wraps). hits: per
// cycle and impact [k * impacts + i] (empty: every impact at its angle, at its weight).
void add_impacts(std::vector<double>& y, const Timing& t, int cycles, double fs_hz, double delay_s, double amplitude,
                 const std::vector<Hit>& hits = {}) {
  const std::size_t n = y.size();
  const double deg_per_s = 6.0 * t.speed_rpm;
  const auto span = static_cast<std::size_t>(std::ceil(16 * kImpactDecayS * fs_hz));
  constexpr std::size_t kCount = std::size(kImpacts);
  for (int k = 0; k < cycles; ++k)
    for (std::size_t i = 0; i < kCount; ++i) {
      const Impact& im = kImpacts[i];
      const Hit hit = hits.empty() ? Hit{} : hits[static_cast<std::size_t>(k) * kCount + i];
      const double t0 = (im.angle_deg + hit.jitter_deg + 360.0 + 720.0 * k) / deg_per_s + delay_s;
      const auto j0 = static_cast<std::size_t>(std::ceil(t0 * fs_hz));
      for (std::size_t j = j0; j < j0 + span; ++j)
        y[j % n] += amplitude * hit.amplitude * im.weight * impact_shape(static_cast<double>(j) / fs_hz - t0);
    }
}

// Every impact's variation over the run (empty without any): Gaussian angle errors, log-normal energies whose mean is
// the nominal energy (so the run's level is the specified one on average). The same at every microphone.
std::vector<Hit> impact_hits(const Chain& chain, int condition, int cycles, const Effects& fx) {
  if (fx.mechanical_jitter_deg <= 0 && fx.mechanical_energy_spread_db <= 0) return {};
  std::mt19937_64 rng = rng_for(chain, condition, kMics, 7);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double sigma_np = fx.mechanical_energy_spread_db * std::log(10.0) / 10.0;  // of the energy's logarithm
  std::vector<Hit> hits(static_cast<std::size_t>(cycles) * std::size(kImpacts));
  for (Hit& h : hits) {
    h.jitter_deg = fx.mechanical_jitter_deg * normal(rng);
    h.amplitude = std::exp(0.5 * (sigma_np * normal(rng) - 0.5 * sigma_np * sigma_np));
  }
  return hits;
}

// The impacts' amplitude for an array-average Leq(A) of `dba` at ref_rpm (energy per impact fixed).
double impact_amplitude(const Timing& t, int cycles, double fs_hz, double delay_s, double dba, double ref_rpm) {
  std::vector<double> unit(t.n_out, 0.0);
  add_impacts(unit, t, cycles, fs_hz, delay_s, 1.0);
  const double at_this_speed = dba + 10.0 * std::log10(t.speed_rpm / ref_rpm);
  double array_energy = 0;  // mean of the directivity gains' energy
  for (double g : directivity_db()) array_energy += std::pow(10.0, g / 10.0) / kMics;
  return std::pow(10.0, (at_this_speed - level_db(unit, fs_hz, true)) / 20.0) / std::sqrt(array_energy);
}

// A path to one microphone: `path` (Pa per Pa at f), the microphone's directivity and the delay.
Transfer to_mic(int mic, const Chain& chain, const Transfer& path) {
  const double gain = std::pow(10.0, directivity_db()[mic] / 20.0);
  const double delay = chain.radius_m / chain.sound_speed_m_per_s;
  return [=](double f) { return gain * path(f) * std::polar(1.0, -2 * kPi * f * delay); };
}

// What one microphone hears of the structure: eq. 4.1 (and the panel) in the frequency domain, or a nonlinear block's
// output made in the time domain (block non-empty), at the speed's gain, with the panel beside it.
std::vector<double> structural_sound(const std::vector<double>& u, const BlockMotion& block, int mic, const Run& r,
                                     const Chain& chain, const Effects& fx) {
  const double rpm = r.time.speed_rpm, period = r.time.period_s;
  const Structure& st = chain.structure;
  if (block.y_pa.empty())
    return radiate(u, r.time.n_out, period,
                   to_mic(mic, chain, [&](double f) { return structural_transfer(f, rpm, st, fx); }));
  const double gain = speed_gain(rpm, fx);
  std::vector<double> y =
      radiate(block.y_pa, r.time.n_out, period, to_mic(mic, chain, [=](double) { return cd(gain); }));
  if (fx.second_mode_db > 0) {
    const Transfer panel_path = to_mic(mic, chain, [&](double f) { return panel_transfer(f, rpm, st, fx); });
    const std::vector<double> panel = radiate(u, r.time.n_out, period, panel_path);
    for (std::size_t i = 0; i < y.size(); ++i) y[i] += panel[i];
  }
  return y;
}

// White Gaussian noise of rms `bar` per sample added to the recorded pressure (stream picks the realisation).
void add_pressure_noise(std::vector<double>& recorded_bar, double bar, const Chain& chain, int condition, int stream) {
  if (bar <= 0) return;
  std::mt19937_64 rng = rng_for(chain, condition, kMics, stream);
  std::normal_distribution<double> noise(0.0, bar);
  for (double& p : recorded_bar) p += noise(rng);
}

// The floors and the background at one microphone: stream 1 self-noise, 2 pink floor, 3 background.
void add_floors(std::vector<double>& y, int condition, int mic, const Chain& chain, const Effects& fx) {
  const std::size_t n = y.size();
  auto add = [&](int stream, const std::function<double(double)>& shape, double level, bool a_weighted) {
    std::mt19937_64 rng = rng_for(chain, condition, mic, stream);
    const std::vector<double> v = shaped_noise(n, chain.fs_hz, shape, level, a_weighted, rng);
    for (std::size_t i = 0; i < n; ++i) y[i] += v[i];
  };
  add(
      1, [](double) { return 1.0; }, chain.self_noise_dba, true);
  add(
      2, [](double f) { return f < 20.0 ? 0.0 : 1.0 / f; }, chain.pink_floor_db, false);
  if (std::isfinite(fx.background_dba))
    add(
        3, [](double f) { return f < 20.0 ? 0.0 : 1.0 / (1.0 + (f / 500.0) * (f / 500.0)); }, fx.background_dba, true);
}

}  // namespace

std::vector<double> engine_input_pa(const std::vector<double>& clean_bar) {
  double mean = 0;
  for (double p : clean_bar) mean += p / static_cast<double>(clean_bar.size());
  std::vector<double> u(clean_bar.size());
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = (clean_bar[i] - mean) * kBarToPa;
  return u;
}

Run synthesize(const Sources& src, const Condition& c, int condition_index, const Chain& chain, const Effects& fx) {
  Run r;
  r.condition = c;
  r.time = timing(c.speed_rpm, c.cycles, chain.fs_hz);
  r.fs_hz = chain.fs_hz;
  r.pressure = condition_pressure(src, c, r.time.speed_rpm);
  add_pressure_noise(r.pressure.recorded_bar, chain.added_pressure_noise_bar, chain, condition_index, 11);
  add_pressure_noise(r.pressure.recorded_bar, fx.transducer_noise_bar, chain, condition_index, 12);
  if (chain.states_floor)
    r.stated_floor_bar =
        std::hypot(record_floor_bar(c.motored ? src.motored : src.fired), chain.added_pressure_noise_bar);
  const std::vector<double> u = engine_input_pa(r.pressure.clean_bar);
  const BlockMotion block =
      fx.block.any() ? block_motion(u, r.time.period_s, chain.structure, fx.block) : BlockMotion{};
  const double delay = chain.radius_m / chain.sound_speed_m_per_s;
  const double impacts = std::isfinite(fx.mechanical_dba) ? impact_amplitude(r.time, c.cycles, chain.fs_hz, delay,
                                                                             fx.mechanical_dba, fx.mechanical_ref_rpm)
                                                          : 0.0;
  const std::vector<Hit> hits = impact_hits(chain, condition_index, c.cycles, fx);  // heard alike at every microphone
  for (int m = 0; m < kMics; ++m) {
    std::vector<double> y = structural_sound(u, block, m, r, chain, fx);
    if (impacts > 0)
      add_impacts(y, r.time, c.cycles, chain.fs_hz, delay, impacts * std::pow(10.0, directivity_db()[m] / 20.0), hits);
    add_floors(y, condition_index, m, chain, fx);
    if (m == fx.mic_gain_index && fx.mic_gain_db != 0)
      y = radiate(y, y.size(), r.time.period_s, [&](double f) { return mic_error(f, m, fx); });
    r.mics_pa.push_back(std::move(y));
  }
  return r;
}

}  // namespace indep
