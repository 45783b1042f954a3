#include "model/diagnosis/gap_watch.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace noisemon::model::diagnosis {

namespace {

OperatingSample operating_sample(const CycleGap& c) {
  return {.time_s = c.time_s,
          .speed_rpm = c.speed_rpm,
          .load_nm = c.load_nm,
          .soi_deg_btdc = c.soi_deg_btdc,
          .motored = c.motored};
}

double energy_mean_db(const std::vector<double>& levels) {
  double sum = 0.0;
  std::size_t n = 0;
  for (const double l : levels)
    if (std::isfinite(l)) sum += std::pow(10.0, l / 10.0), ++n;
  return n ? 10.0 * std::log10(sum / static_cast<double>(n)) : kNoValue;
}

// The A-weighted level gap over the bands used: 10 lg of the measured band energies' sum over the predicted ones'.
double overall_gap_db(const std::vector<double>& measured, const std::vector<double>& predicted,
                      const std::vector<char>& used) {
  double m = 0.0, p = 0.0;
  for (std::size_t b = 0; b < measured.size(); ++b)
    if (used[b] && std::isfinite(measured[b]) && std::isfinite(predicted[b])) {
      m += std::pow(10.0, 0.1 * measured[b]);
      p += std::pow(10.0, 0.1 * predicted[b]);
    }
  return p > 0.0 ? 10.0 * std::log10(m / p) : kNoValue;
}

// The h whose run length with the mean `bias` standard deviations off is `arl0`.
double cusum_threshold_with_bias(double k, double arl0, double bias) {
  double lo = 0.0, hi = 1.0;
  if (dsp::cusum_arl(k, 0.0, bias) >= arl0) return 0.0;
  while (dsp::cusum_arl(k, hi, bias) < arl0) hi *= 2.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (dsp::cusum_arl(k, mid, bias) < arl0 ? lo : hi) = mid;
  }
  return hi;
}

// Where each value of a cycle sits: the features (band gaps, microphone offsets, overall gap, window gaps), then the
// levels the attribution needs (measured, predicted, CPL per band, microphones, measured per window).
struct Layout {
  std::size_t nb, nm, nw;
  explicit Layout(const GapReference& r) : nb(r.band_hz.size()), nm(r.mics), nw(r.windows) {}
  std::size_t features() const { return nb + nm + 1 + nw; }
  std::size_t overall() const { return nb + nm; }
  std::size_t window_gap(std::size_t w) const { return nb + nm + 1 + w; }
  std::size_t measured(std::size_t b) const { return features() + b; }
  std::size_t predicted(std::size_t b) const { return features() + nb + b; }
  std::size_t cpl(std::size_t b) const { return features() + 2 * nb + b; }
  std::size_t mic(std::size_t m) const { return features() + 3 * nb + m; }
  std::size_t window(std::size_t w) const { return features() + 3 * nb + nm + w; }
  std::size_t size() const { return features() + 3 * nb + nm + nw; }
};

}  // namespace

// A feature's spread as the CUSUM standardises it: the reference's estimate raised to its upper 95 % bound (a
// spread estimated too small would fire too often), never below the floor.
double GapWatch::watched_sigma(const FeatureReference& f) const {
  const double n = static_cast<double>(std::max<std::size_t>(f.blocks, 2));
  return std::max(f.sigma * (1.0 + 1.0 / std::sqrt(2.0 * (n - 1.0))), options_.sigma_floor_db);
}

void GapWatch::Block::reset(std::size_t n) {
  sum.assign(n, 0.0);
  count.assign(n, 0);
  cycles = 0;
  seconds = 0.0;
}

void GapWatch::Block::add(const std::vector<double>& values, double cycle_s) {
  for (std::size_t i = 0; i < values.size(); ++i)
    if (std::isfinite(values[i])) sum[i] += values[i], ++count[i];
  ++cycles;
  seconds += cycle_s;
}

double GapWatch::Block::mean(std::size_t i, std::size_t min_count) const {
  return count[i] >= std::max<std::size_t>(min_count, 1) ? sum[i] / static_cast<double>(count[i]) : kNoValue;
}

GapWatch::GapWatch(const GapWatchOptions& options) : options_(options), steady_(options.steady) {
  if (options.block_cycles < 2) throw std::invalid_argument("gap watch: block_cycles must be at least 2");
  if (!(options.min_shift_db > 0.0) || !(options.false_alarm_hours > 0.0) || !(options.reference_s > 0.0))
    throw std::invalid_argument("gap watch: min_shift_db, false_alarm_hours and reference_s must be positive");
}

std::size_t GapWatch::watched_features() const {
  if (current_point_ >= points_.size()) return 0;
  const auto& w = points_[current_point_].watched;
  return static_cast<std::size_t>(std::count(w.begin(), w.end(), 1));
}

double GapWatch::reference_seconds() const {
  if (current_point_ >= points_.size() || points_[current_point_].learning) return 0.0;
  return static_cast<double>(reference_.points[current_point_].cycles) * 120.0 /
         reference_.points[current_point_].speed_rpm;
}

double GapWatch::since_reference_seconds() const {
  if (learning()) return 0.0;
  return std::max(0.0, last_s_ - watched_from_s_[current_point_]);
}

bool GapWatch::learning() const { return current_point_ >= points_.size() || points_[current_point_].learning; }

double GapWatch::current_h() const {
  if (learning()) return kNoValue;
  const auto& p = points_[current_point_];
  for (std::size_t f = 0; f < p.watched.size(); ++f)
    if (p.watched[f]) return p.cusum[f].h();
  return kNoValue;
}

std::vector<double> GapWatch::features_of(const CycleGap& c) const {
  const Layout l(reference_);
  std::vector<double> f(l.size(), kNoValue);
  for (std::size_t b = 0; b < l.nb; ++b) {
    f[b] = c.measured_db[b] - c.predicted_db[b];
    f[l.measured(b)] = c.measured_db[b];
    f[l.predicted(b)] = c.predicted_db[b];
    f[l.cpl(b)] = c.cpl_db[b];
  }
  const double array_db = energy_mean_db(c.mic_db);
  for (std::size_t m = 0; m < l.nm; ++m) {
    f[l.nb + m] = c.mic_db[m] - array_db;
    f[l.mic(m)] = c.mic_db[m];
  }
  f[l.overall()] = c.overall_measured_db - c.overall_predicted_db;
  for (std::size_t w = 0; w < l.nw; ++w) {
    f[l.window_gap(w)] = c.window_measured_db[w] - c.window_predicted_db[w];
    f[l.window(w)] = c.window_measured_db[w];
  }
  return f;
}

void GapWatch::start_layout(const CycleGap& c) {
  reference_.band_hz = c.band_hz;
  reference_.mics = c.mic_db.size();
  reference_.windows = c.window_measured_db.size();
  layout_ = true;
}

std::size_t GapWatch::find_point(const CycleGap& c) const {
  for (std::size_t p = 0; p < reference_.points.size(); ++p) {
    const auto& r = reference_.points[p];
    if (r.motored == c.motored && std::abs(r.speed_rpm - c.speed_rpm) <= options_.speed_tolerance_rpm &&
        !(std::abs(r.load_nm - c.load_nm) > options_.load_tolerance_nm) &&
        !(std::abs(r.soi_deg_btdc - c.soi_deg_btdc) > options_.soi_tolerance_deg))
      return p;
  }
  return SIZE_MAX;
}

// The operating point of a cycle: an existing one within the tolerances, or a new one centred on it.
std::size_t GapWatch::point_of(const CycleGap& c) {
  if (const std::size_t p = find_point(c); p != SIZE_MAX) return p;
  OperatingPointReference r;
  r.speed_rpm = c.speed_rpm;
  r.load_nm = c.load_nm;
  r.soi_deg_btdc = c.soi_deg_btdc;
  r.motored = c.motored;
  reference_.points.push_back(r);
  points_.emplace_back();
  watched_from_.push_back(INT64_MIN);
  watched_from_s_.push_back(0.0);
  return reference_.points.size() - 1;
}

std::string GapWatch::feature_name(std::size_t f, int side) const {
  const std::size_t nb = reference_.band_hz.size();
  std::string name;
  if (f < nb) {
    const double hz = reference_.band_hz[f];
    name = "band " + (hz < 1000.0 ? std::to_string(static_cast<int>(std::lround(hz))) + " Hz"
                                  : std::to_string(hz / 1000.0).substr(0, hz < 10000.0 ? 4 : 5) + " kHz");
  } else if (f < nb + reference_.mics) {
    name = "mic " + std::to_string(f - nb + 1);
  } else if (f == nb + reference_.mics) {
    name = "overall";
  } else {
    const auto w = static_cast<int>(f - nb - reference_.mics - 1);
    name = "window " + std::to_string(-360 + 90 * w) + ".." + std::to_string(-270 + 90 * w) + " deg";
  }
  return name + (side > 0 ? " +" : " -");
}

// Inside the watch a cycle is numbered by the watch's own count (a daemon's restart starts its reports' numbers
// again at 0); the reports' numbers are kept beside the history for the events.
void GapWatch::add(const CycleGap& report) {
  if (!layout_) start_layout(report);
  if (report.band_hz.size() != reference_.band_hz.size() || report.mic_db.size() != reference_.mics ||
      report.window_measured_db.size() != reference_.windows || report.window_predicted_db.size() != reference_.windows)
    return;                                                                  // another layout
  if (!pending_.empty() && report.time_s < pending_.back().time_s) flush();  // another run's clock: this one has ended
  if (report.speed_rpm > 0.0) steady_.add(operating_sample(report));
  pending_.push_back(report);
  while (!pending_.empty() && steady_.decided(pending_.front().time_s)) {
    take(std::move(pending_.front()));
    pending_.pop_front();
  }
}

void GapWatch::flush() {
  steady_.flush();
  for (; !pending_.empty(); pending_.pop_front()) take(std::move(pending_.front()));
}

void GapWatch::take(CycleGap c) {
  if (c.usable && c.speed_rpm > 0.0 && !steady_.steady(operating_sample(c))) {
    c.usable = false;
    ++transient_cycles_;
  }
  const std::int64_t report_cycle = c.cycle;
  c.cycle = cycles_;
  if (cycles_ == 0) {
    first_s_ = c.time_s;
    for (double& t : watched_from_s_) t = c.time_s;  // a reference given before the first cycle
  }
  last_s_ = c.time_s;
  last_cycle_ = c.cycle;
  ++cycles_;
  history_.push_back(c);
  report_cycles_.push_back(report_cycle);
  while (history_.size() > options_.history_cycles) {
    history_.pop_front();
    report_cycles_.pop_front();
  }
  if (!c.usable || !(c.speed_rpm > 0.0)) return;
  const std::size_t p = point_of(c);
  current_point_ = p;
  const std::size_t n = Layout(reference_).size();
  if (p != block_point_ || block_.sum.size() != n) {  // a block holds one operating point only
    block_.reset(n);
    block_point_ = p;
  }
  if (block_.cycles == 0) block_.first_cycle = c.cycle, block_.first_s = c.time_s;
  block_.add(features_of(c), 120.0 / c.speed_rpm);
  if (block_.cycles >= options_.block_cycles) close_block();
}

void GapWatch::close_block() {
  const std::int64_t index = blocks_++;
  block_starts_.emplace_back(block_.first_cycle, block_.first_s);
  while (block_starts_.size() > options_.history_cycles / options_.block_cycles + 1) {
    block_starts_.pop_front();
    ++block_starts_base_;
  }
  const std::size_t p = block_point_;
  if (points_[p].learning)
    learn(p, index);
  else
    watch(p, index);
  if (open_) {
    ++event_blocks_seen_;
    if (p == event_point_ && event_blocks_left_ > 0) --event_blocks_left_;
    if (event_blocks_left_ == 0 || event_blocks_seen_ >= 4 * options_.after_blocks) complete_event();
  }
  block_.reset(block_.sum.size());
}

void GapWatch::learn(std::size_t p, std::int64_t) {
  PointState& s = points_[p];
  const std::size_t features = Layout(reference_).features();
  if (s.block_means.size() != features) {
    s.block_means.assign(features, {});
    s.levels.reset(block_.sum.size());
  }
  for (std::size_t f = 0; f < features; ++f) s.block_means[f].push_back(block_.mean(f, options_.block_cycles / 2));
  for (std::size_t i = 0; i < block_.sum.size(); ++i) {
    s.levels.sum[i] += block_.sum[i];
    s.levels.count[i] += block_.count[i];
  }
  s.levels.cycles += block_.cycles;
  s.learnt_s += block_.seconds;
  if (s.learnt_s >= options_.reference_s) finish_reference(p);
}

// Mean and block-to-block spread of every feature, the mean levels, then the CUSUMs.
void GapWatch::finish_reference(std::size_t p) {
  PointState& s = points_[p];
  OperatingPointReference& r = reference_.points[p];
  const Layout l(reference_);
  const std::size_t features = l.features();
  r.features.assign(features, {});
  for (std::size_t f = 0; f < features; ++f) {
    std::vector<double> x;
    for (const double v : s.block_means[f])
      if (std::isfinite(v)) x.push_back(v);
    if (x.size() < 4 || 2 * x.size() < s.block_means[f].size()) continue;
    double mean = 0.0, ss = 0.0;
    for (const double v : x) mean += v / static_cast<double>(x.size());
    for (const double v : x) ss += (v - mean) * (v - mean);
    r.features[f] = {mean, std::sqrt(ss / static_cast<double>(x.size() - 1)), x.size()};
  }
  auto means = [&](std::size_t from, std::size_t count) {
    std::vector<double> out;
    for (std::size_t i = 0; i < count; ++i) out.push_back(s.levels.mean(from + i));
    return out;
  };
  r.measured_db = means(l.measured(0), l.nb);
  r.predicted_db = means(l.predicted(0), l.nb);
  r.cpl_db = means(l.cpl(0), l.nb);
  r.mic_db = means(l.mic(0), l.nm);
  r.window_db = means(l.window(0), l.nw);
  r.cycles = s.levels.cycles;
  s.block_means.clear();
  s.learning = false;
  watched_from_[p] = last_cycle_;
  watched_from_s_[p] = last_s_;
  arm(p);
}

// The CUSUMs of a point whose reference is complete: k from the smallest shift, h from the false-alarm budget shared
// by every watched feature's two sides.
void GapWatch::arm(std::size_t p) {
  PointState& s = points_[p];
  const OperatingPointReference& r = reference_.points[p];
  s.cusum.assign(r.features.size(), dsp::Cusum());
  s.watched.assign(r.features.size(), 0);
  for (std::size_t f = 0; f < r.features.size(); ++f) s.watched[f] = std::isfinite(r.features[f].sigma);
  const auto watched = static_cast<double>(std::count(s.watched.begin(), s.watched.end(), 1));
  const double blocks_per_hour = 3600.0 * r.speed_rpm / 120.0 / static_cast<double>(options_.block_cycles);
  const double arl = options_.false_alarm_hours * blocks_per_hour * 2.0 * std::max(1.0, watched);
  for (std::size_t f = 0; f < r.features.size(); ++f) {
    if (!s.watched[f]) continue;
    const double sigma = watched_sigma(r.features[f]);
    const double k = 0.5 * options_.min_shift_db / sigma;
    // The reference's mean is itself an estimate: h holds the rate against a mean off by two of its standard errors.
    const double bias = 1.0 / std::sqrt(static_cast<double>(r.features[f].blocks)) * r.features[f].sigma / sigma;
    s.cusum[f] = dsp::Cusum(k, cusum_threshold_with_bias(k, arl, bias));
  }
}

void GapWatch::watch(std::size_t p, std::int64_t index) {
  PointState& s = points_[p];
  const OperatingPointReference& r = reference_.points[p];
  for (std::size_t f = 0; f < r.features.size(); ++f) {
    const double x = block_.mean(f, options_.block_cycles / 2);
    if (!s.watched[f] || !std::isfinite(x)) continue;
    const int side = s.cusum[f].update((x - r.features[f].mean) / watched_sigma(r.features[f]), index);
    if (side == 0) continue;
    if (!open_)
      open_event(p, s.cusum[f].onset(), f, side);
    else if (std::find(event_.features.begin(), event_.features.end(), feature_name(f, side)) == event_.features.end())
      event_.features.push_back(feature_name(f, side));
  }
}

void GapWatch::open_event(std::size_t p, std::int64_t onset_block, std::size_t feature, int side) {
  open_ = true;
  event_feature_ = feature;
  event_ = GapEvent{};
  event_point_ = p;
  event_blocks_left_ = options_.after_blocks;
  event_blocks_seen_ = 0;
  const std::int64_t at = std::clamp<std::int64_t>(onset_block - block_starts_base_, 0,
                                                   static_cast<std::int64_t>(block_starts_.size()) - 1);
  event_.onset_cycle = block_starts_[static_cast<std::size_t>(at)].first;
  event_.onset_s = block_starts_[static_cast<std::size_t>(at)].second - first_s_;
  event_.detected_cycle = report_cycles_.back();
  event_.detected_s = history_.back().time_s - first_s_;
  event_.features.push_back(feature_name(feature, side));
}

// The CUSUM locates the change to a block and starts it where its statistic last left zero, late for a slow drift.
// On the first feature that fired, per cycle against the reference's mean since the point was watched, the least-
// squares change point of a step (a constant shift from tau on) and of a drift (a shift growing linearly from tau):
// the better of the two (the same parameter count) is the event's kind and onset.
void GapWatch::refine_onset() {
  std::vector<double> r, seconds;  // residual and time per usable cycle at the point
  std::vector<std::int64_t> cycles;
  const double mean = reference_.points[event_point_].features[event_feature_].mean;
  for (const CycleGap& c : history_) {
    if (c.cycle < watched_from_[event_point_] || !c.usable || find_point(c) != event_point_) continue;
    const double v = features_of(c)[event_feature_];
    if (!std::isfinite(v)) continue;
    r.push_back(v - mean);
    cycles.push_back(c.cycle);
    seconds.push_back(c.time_s);
  }
  const std::size_t n = r.size();
  if (n < 8) return;
  // Suffix sums from i on of r, t r, t and t^2 (t = i).
  std::vector<double> sr(n + 1, 0.0), str(n + 1, 0.0), st(n + 1, 0.0), stt(n + 1, 0.0);
  for (std::size_t i = n; i-- > 0;) {
    const double t = static_cast<double>(i);
    sr[i] = sr[i + 1] + r[i];
    str[i] = str[i + 1] + t * r[i];
    st[i] = st[i + 1] + t;
    stt[i] = stt[i + 1] + t * t;
  }
  double best_step = 0.0, best_drift = 0.0, slope = 0.0;
  std::size_t step_at = 0, drift_at = 0;
  for (std::size_t i = 1; i + 2 < n; ++i) {
    const double k = static_cast<double>(n - i), tau = static_cast<double>(i);
    const double step_gain = sr[i] * sr[i] / k;  // the squared error a step from i removes
    const double cross = str[i] - tau * sr[i], square = stt[i] - 2.0 * tau * st[i] + tau * tau * k;
    const double drift_gain = square > 0.0 ? cross * cross / square : 0.0;
    if (step_gain > best_step) best_step = step_gain, step_at = i;
    if (drift_gain > best_drift) best_drift = drift_gain, drift_at = i, slope = cross / square;
  }
  const bool drift = best_drift > best_step;
  const std::size_t at = drift ? drift_at : step_at;
  event_.kind = drift ? "drift" : "step";
  event_.onset_cycle = cycles[at];
  event_.onset_s = seconds[at] - first_s_;
  if (drift) {
    const double cycle_s = (seconds.back() - seconds[at]) / static_cast<double>(std::max<std::size_t>(n - 1 - at, 1));
    event_.drift_db_per_min = cycle_s > 0.0 ? slope * 60.0 / cycle_s : kNoValue;
  }
}

// The cycles at the event's operating point from the onset on, against its reference: attributed, emitted; the point
// then learns its reference afresh.
void GapWatch::complete_event() {
  const std::size_t p = event_point_;
  const std::int64_t cusum_onset = event_.onset_cycle;
  refine_onset();
  // A drift is attributed on the stretch the CUSUM found (its latest state), a step on everything from its onset.
  const std::int64_t after_from =
      event_.kind == "drift" ? std::max(cusum_onset, event_.onset_cycle) : event_.onset_cycle;
  const OperatingPointReference& r = reference_.points[p];
  const Layout l(reference_);
  Block after;
  after.reset(block_.sum.size());
  for (const CycleGap& c : history_)
    if (c.cycle >= after_from && c.usable && find_point(c) == p) after.add(features_of(c), 0.0);
  GapChange& g = event_.change;
  g.band_hz = reference_.band_hz;
  g.measured_before = r.measured_db;
  g.predicted_before = r.predicted_db;
  g.cpl_before = r.cpl_db;
  g.mic_before = r.mic_db;
  const double n_after = std::max<double>(1.0, static_cast<double>(after.cycles));
  auto sigma = [&](std::size_t f) {
    const FeatureReference& x = r.features[f];
    if (!std::isfinite(x.sigma)) return kNoValue;
    const double s = std::max(x.sigma, options_.sigma_floor_db), b = static_cast<double>(options_.block_cycles);
    return s * std::sqrt(b / n_after + 1.0 / static_cast<double>(std::max<std::size_t>(x.blocks, 1)));
  };
  for (std::size_t b = 0; b < l.nb; ++b) {
    g.measured_after.push_back(after.mean(l.measured(b)));
    g.predicted_after.push_back(after.mean(l.predicted(b)));
    g.cpl_after.push_back(after.mean(l.cpl(b)));
    g.band_sigma_db.push_back(sigma(b));
    g.cpl_sigma_db.push_back(sigma(b));
    g.band_used.push_back(points_[p].watched[b] && std::isfinite(g.measured_after[b]) &&
                          std::isfinite(g.predicted_after[b]));
  }
  for (std::size_t m = 0; m < l.nm; ++m) {
    g.mic_after.push_back(after.mean(l.mic(m)));
    g.mic_sigma_db.push_back(std::isfinite(sigma(l.nb + m)) ? sigma(l.nb + m) : options_.sigma_floor_db);
  }
  g.window_before = r.window_db;
  for (std::size_t w = 0; w < l.nw; ++w) {
    g.window_after.push_back(after.mean(l.window(w)));
    g.window_sigma_db.push_back(std::isfinite(sigma(l.window_gap(w))) ? sigma(l.window_gap(w))
                                                                      : options_.sigma_floor_db);
  }
  g.speed_rpm = r.speed_rpm;
  g.pressure_edge_rate_hz = options_.pressure_edge_rate_per_rev * r.speed_rpm / 60.0;
  event_.attribution = attribute_change(g, options_.attribution);
  event_.effect = event_.attribution.effect;
  event_.params = event_.attribution.params;
  event_.confidence = event_.attribution.confidence;
  event_.gap_before_db = overall_gap_db(g.measured_before, g.predicted_before, g.band_used);
  event_.gap_after_db = overall_gap_db(g.measured_after, g.predicted_after, g.band_used);
  event_.speed_rpm = r.speed_rpm;
  event_.load_nm = r.load_nm;
  event_.soi_deg_btdc = r.soi_deg_btdc;
  event_.motored = r.motored;
  add_speed_law(event_);
  open_ = false;
  points_[p] = PointState{};
  const std::int64_t back = event_.onset_cycle - history_.front().cycle;  // the watch's count to the report's number
  if (back >= 0 && back < static_cast<std::int64_t>(report_cycles_.size()))
    event_.onset_cycle = report_cycles_[static_cast<std::size_t>(back)];
  if (on_event) on_event(event_);
}

// At one operating point a structural gain that follows speed is a gain (gain_db, at speed_rpm); the same change met
// again at another speed (another point's reference, learnt before it) gives its law: the slope between the two
// gains, dB per 1000 rpm, and the speed where it is nil. The previous speed_dependence event at least
// kSpeedLawSpanRpm away is taken.
void GapWatch::add_speed_law(GapEvent& event) {
  constexpr double kSpeedLawSpanRpm = 200.0;
  if (event.effect != "speed_dependence") return;
  const auto fitted = std::find_if(event.params.begin(), event.params.end(),
                                   [](const auto& param) { return param.first == "gain_db"; });
  if (fitted == event.params.end()) return;
  const double gain = fitted->second;
  event.params.emplace_back("speed_rpm", event.speed_rpm);
  for (auto it = structural_gains_.rbegin(); it != structural_gains_.rend(); ++it) {
    const double span_rpm = event.speed_rpm - it->first;
    if (std::abs(span_rpm) < kSpeedLawSpanRpm) continue;
    const double db_per_krpm = (gain - it->second) / span_rpm * 1000.0;
    event.params.emplace_back("db_per_krpm", db_per_krpm);
    if (std::abs(db_per_krpm) > 1e-9)
      event.params.emplace_back("nil_rpm", event.speed_rpm - gain / db_per_krpm * 1000.0);
    break;
  }
  structural_gains_.emplace_back(event.speed_rpm, gain);
}

void GapWatch::finish_learning() {
  flush();
  for (std::size_t p = 0; p < points_.size(); ++p)
    if (points_[p].learning && !points_[p].block_means.empty() && points_[p].block_means.front().size() >= 4)
      finish_reference(p);
}

void GapWatch::set_reference(const GapReference& reference) {
  reference_ = reference;
  layout_ = !reference.band_hz.empty();
  points_.assign(reference_.points.size(), PointState{});
  watched_from_.assign(reference_.points.size(), INT64_MIN);
  watched_from_s_.assign(reference_.points.size(), 0.0);
  for (std::size_t p = 0; p < points_.size(); ++p) {
    points_[p].learning = false;
    arm(p);
  }
}

}  // namespace noisemon::model::diagnosis
