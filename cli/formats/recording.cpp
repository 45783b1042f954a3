#include "cli/formats/recording.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <stdexcept>

#include "cli/formats/angle_edges.hpp"
#include "cli/formats/recording_grid.hpp"
#include "drivers/formats/run_both.hpp"
#include "drivers/formats/stream_messages.hpp"
#include "dsp/resample.hpp"

namespace noisemon::cli::formats {
namespace {

using grid::kFs;
using grid::speed_from_crank;
using grid::utime_of_index;

constexpr double kSpeedOfSoundMS = 343.0;  // air at 20 degC: the default acoustic delay radius / c
// Frames dropped at the start of a resampled stream: the resamplers' start-up (held first pressure sample,
// zeros before the first microphone frame) reaches about 1.5 ms into their output.
constexpr std::int64_t kResamplerEdgeFrames = 128;
constexpr double kMaxRecordingSeconds = 24 * 3600;  // one import: a day of 40 kHz frames is already 3.5e9

double wrap_crank(double theta) { return theta - 720.0 * std::floor((theta + 360.0) / 720.0); }

// time_s exactly on the 40 kHz grid at consecutive indices (what to_run_dir writes): returns the first index.
bool on_pipeline_grid(const std::vector<double>& t, std::int64_t& first) {
  first = std::llround(t.front() * kFs);
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double k = t[i] * kFs;
    if (std::abs(k - static_cast<double>(first + static_cast<std::int64_t>(i))) > 1e-6) return false;
  }
  return true;
}

struct Stream {
  std::int64_t first = 0;  // grid index of values[0]
  std::vector<double> values;
  std::size_t channels = 1;
  std::int64_t end() const { return first + static_cast<std::int64_t>(values.size() / channels); }
};

// The encoder samples evenly spaced in angle, on the resampler's clock: views of the run's own columns, or filled
// copies when samples are missing (crank steps of 1.5 .. kMaxCrankGapSteps encoder steps: linear interpolation in
// time, crank angle and pressure) or the times must be shifted.
struct EncoderSamples {
  std::vector<double> t_own, th_own, p_own;
  std::span<const double> t, th, p;
  std::int64_t shift = 0;  // grid index of the resampler's t = 0
};

void fill_missing_samples(const drivers::formats::RunDir& run, double step, EncoderSamples& s) {
  const std::size_t n = run.time_s.size();
  s.t_own.reserve(n);
  s.th_own.reserve(n);
  s.p_own.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) {
      const double d = run.crank_deg[i] - run.crank_deg[i - 1];
      const long missing = d > 1.5 * step ? std::lround(d / step) - 1 : 0;
      for (long j = 1; j <= missing; ++j) {
        const double f = static_cast<double>(j) / static_cast<double>(missing + 1);
        s.t_own.push_back(run.time_s[i - 1] + f * (run.time_s[i] - run.time_s[i - 1]));
        s.th_own.push_back(run.crank_deg[i - 1] + f * d);
        s.p_own.push_back(run.pressure_pa[i - 1] + f * (run.pressure_pa[i] - run.pressure_pa[i - 1]));
      }
    }
    s.t_own.push_back(run.time_s[i]);
    s.th_own.push_back(run.crank_deg[i]);
    s.p_own.push_back(run.pressure_pa[i]);
  }
  s.t = s.t_own;
  s.th = s.th_own;
  s.p = s.p_own;
}

void encoder_samples(const drivers::formats::RunDir& run, double step, EncoderSamples& s) {
  s.t = run.time_s;
  s.th = run.crank_deg;
  s.p = run.pressure_pa;
  for (std::size_t i = 1; i < run.crank_deg.size(); ++i)
    if (run.crank_deg[i] - run.crank_deg[i - 1] > 1.5 * step) {
      fill_missing_samples(run, step, s);
      break;
    }
  // The resampler's clock starts at a grid instant at or before the first sample (it needs t >= 0).
  s.shift = s.t.front() < 0 ? static_cast<std::int64_t>(std::floor(s.t.front() * kFs)) : 0;
  if (s.shift != 0) {
    if (s.t_own.empty()) s.t_own.assign(s.t.begin(), s.t.end());
    for (double& v : s.t_own) v -= static_cast<double>(s.shift) / kFs;
    s.t = s.t_own;
  }
}

// The run's highest edge rate (its shortest step) with a 10 % margin: the resampler's fine grid is sized to it
// (half the cost of the any-encoder grid for a 0.1 deg encoder below 4200 rpm).
double highest_edge_rate_hz(std::span<const double> t) {
  double shortest = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < t.size(); ++i) shortest = std::min(shortest, t[i] - t[i - 1]);
  return shortest > 0.0 && std::isfinite(shortest) ? 1.1 / shortest : dsp::NonuniformResampler::kAnyEncoderEdgeRateHz;
}

// The pressure through the NonuniformResampler (its start-up dropped); pressure.first on the resampler's clock.
void resample_pressure_values(const EncoderSamples& s, Stream& pressure) {
  const auto& t = s.t;
  dsp::NonuniformResampler rs(kFs, 1, highest_edge_rate_hz(t));
  std::vector<double> out;
  bool started = false;
  std::size_t drop = 0;  // start-up frames still to drop
  pressure.values.reserve(static_cast<std::size_t>(std::ceil((t.back() - t.front()) * kFs)) + 64);
  constexpr std::size_t kChunk = 4096;
  for (std::size_t done = 0; done < t.size();) {
    const std::size_t take = std::min(kChunk, t.size() - done);
    const double from = done == 0 ? t.front() : t[done - 1];
    const auto room = static_cast<std::size_t>(std::ceil((t[done + take - 1] - from) * kFs)) + 8192 + 64;
    if (out.size() < room) out.resize(room);
    const std::size_t got = rs.process(&t[done], &s.p[done], take, out.data(), room);
    if (got > 0 && !started) {
      pressure.first = rs.next_output_index() - static_cast<std::int64_t>(got);
      started = true;
      drop = static_cast<std::size_t>(kResamplerEdgeFrames);
    }
    const std::size_t skip = std::min(drop, got);
    drop -= skip;
    pressure.first += static_cast<std::int64_t>(skip);
    pressure.values.insert(pressure.values.end(), out.begin() + static_cast<std::ptrdiff_t>(skip),
                           out.begin() + static_cast<std::ptrdiff_t>(got));
    done += take;
  }
}

// The encoder samples as the crank-angle stream's edges (instants on the recording's 40 kHz clock).
std::vector<double> angle_edges_of(const EncoderSamples& s) {
  std::vector<double> edges(kEdgeValues * s.t.size());
  for (std::size_t i = 0; i < s.t.size(); ++i) {
    edges[i * kEdgeValues + kEdgeInstant] = s.t[i] * kFs + static_cast<double>(s.shift);
    edges[i * kEdgeValues + kEdgeCrank] = wrap_crank(s.th[i]);
    edges[i * kEdgeValues + kEdgePressure] = s.p[i];
  }
  return edges;
}

// Encoder samples -> 40 kHz pressure and crank (the unwrapped angle interpolated linearly in time, then wrapped);
// the samples themselves into `edges` when their step is an encoder's. Returns the encoder step, degrees.
double resample_pressure(const drivers::formats::RunDir& run, Stream& pressure, Stream& crank,
                         std::vector<double>& edges) {
  const double step = drivers::formats::crank_step_deg(run.crank_deg);
  EncoderSamples s;
  encoder_samples(run, step, s);
  if (drivers::angle_step_deg(360.0 / step) > 0) edges = angle_edges_of(s);
  resample_pressure_values(s, pressure);
  const auto& t = s.t;
  crank.first = pressure.first;
  crank.values.resize(pressure.values.size());
  std::size_t seg = 0;
  for (std::size_t f = 0; f < crank.values.size(); ++f) {
    const double tau = static_cast<double>(pressure.first + static_cast<std::int64_t>(f)) / kFs;
    while (seg + 2 < t.size() && t[seg + 1] <= tau) ++seg;
    const double a = (tau - t[seg]) / (t[seg + 1] - t[seg]);
    crank.values[f] = wrap_crank(s.th[seg] + a * (s.th[seg + 1] - s.th[seg]));
  }
  pressure.first += s.shift;
  crank.first += s.shift;
  return step;
}

void resample_mics(const drivers::formats::RunDir& run, Stream& mics) {
  const std::size_t ch = run.mic_count;
  const std::size_t frames = run.mic_pa.size() / ch;
  mics.channels = ch;
  mics.first = 0;  // mics.wav's t = 0 is the grid's index 0
  if (run.mic_rate_hz == kFs) {
    mics.values.assign(run.mic_pa.begin(), run.mic_pa.end());
    return;
  }
  dsp::RationalResampler rs(run.mic_rate_hz, kFs, ch, dsp::SamplePrecision::kSingle);  // float WAV samples
  constexpr std::size_t kChunk = 8192;
  std::vector<double> in(kChunk * ch), out(rs.max_output_frames(kChunk) * ch);
  mics.values.reserve(static_cast<std::size_t>(static_cast<double>(frames) * kFs / run.mic_rate_hz + 64) * ch);
  auto drop = static_cast<std::size_t>(kResamplerEdgeFrames);  // the resampler's start-up, dropped
  for (std::size_t done = 0; done < frames;) {
    const std::size_t take = std::min(kChunk, frames - done);
    std::copy(run.mic_pa.begin() + static_cast<std::ptrdiff_t>(done * ch),
              run.mic_pa.begin() + static_cast<std::ptrdiff_t>((done + take) * ch), in.begin());
    const std::size_t room = rs.max_output_frames(take);
    if (out.size() < room * ch) out.resize(room * ch);
    const std::size_t got = rs.process(in.data(), take, out.data(), room);
    const std::size_t skip = std::min(drop, got);
    drop -= skip;
    mics.first += static_cast<std::int64_t>(skip);
    mics.values.insert(mics.values.end(), out.begin() + static_cast<std::ptrdiff_t>(skip * ch),
                       out.begin() + static_cast<std::ptrdiff_t>(got * ch));
    done += take;
  }
}

// Frames [from, from + frames) of a stream, moved out of it.
std::vector<double> take_frames(Stream& s, std::int64_t from, std::size_t frames) {
  std::vector<double> v = std::move(s.values);
  const auto skip = static_cast<std::ptrdiff_t>(static_cast<std::size_t>(from - s.first) * s.channels);
  if (skip > 0) v.erase(v.begin(), v.begin() + skip);
  v.resize(frames * s.channels);
  return v;
}

}  // namespace

namespace {

void check_run(const drivers::formats::RunDir& run) {
  const std::size_t n = run.time_s.size();
  if (n < 2 || run.crank_deg.size() != n || run.pressure_pa.size() != n)
    throw drivers::formats::RunDirError("run '" + run.condition.name +
                                        "': time, crank and pressure columns must have the same length >= 2");
  if (run.mic_count > drivers::SampleBlock::kMaxChannels ||
      (run.mic_count > 0 && (run.mic_positions_m.size() != run.mic_count || run.mic_pa.size() % run.mic_count != 0)))
    throw drivers::formats::RunDirError("run '" + run.condition.name +
                                        "': microphone data does not match its positions");
  // Before any frame count is computed from times: absurd times would overflow it (and memory).
  const double span_s = run.time_s.back() - run.time_s.front();
  if (!(std::abs(run.time_s.front()) <= kMaxRecordingSeconds && span_s <= kMaxRecordingSeconds))
    throw drivers::formats::RunDirError("run '" + run.condition.name + "': time_s " +
                                        std::to_string(run.time_s.front()) + " .. " +
                                        std::to_string(run.time_s.back()) + " s, expected a run within " +
                                        std::to_string(static_cast<int>(kMaxRecordingSeconds)) + " s of time 0");
}

template <class T>
void free_vector(std::vector<T>& v) {
  std::vector<T>().swap(v);
}

// The pressure and crank streams; frees the run's columns when `release` is the run.
void pressure_streams(const drivers::formats::RunDir& run, drivers::formats::RunDir* release, Recording& rec,
                      Stream& pressure, Stream& crank) {
  std::int64_t first = 0;
  if (on_pipeline_grid(run.time_s, first)) {
    rec.info.pressure_edges_per_rev = run.pressure_edges_per_rev.value_or(0.0);
    pressure.first = crank.first = first;
    crank.values.resize(run.time_s.size());
    for (std::size_t i = 0; i < crank.values.size(); ++i) crank.values[i] = wrap_crank(run.crank_deg[i]);
    // Not `release ? std::move(a) : b`: a conditional of an rvalue and a const lvalue is a const copy (no move).
    if (release) {
      pressure.values = std::move(release->pressure_pa);
    } else {
      pressure.values = run.pressure_pa;
    }
  } else {
    // What the encoder's edges carry (run.json says it only for samples already on the 40 kHz grid).
    const double step = resample_pressure(run, pressure, crank, rec.angle_edges);
    rec.info.pressure_edges_per_rev = 360.0 / step;
    if (!rec.angle_edges.empty())
      rec.info.pressure_angle_step_deg = drivers::angle_step_deg(rec.info.pressure_edges_per_rev);
  }
  if (release) {
    free_vector(release->time_s);
    free_vector(release->crank_deg);
    free_vector(release->pressure_pa);
  }
}

// Run directory -> recording; `release`: the run itself when its sample columns may be freed once resampled.
Recording convert(const drivers::formats::RunDir& run, drivers::formats::RunDir* release, std::int64_t epoch_utime) {
  check_run(run);
  Recording rec;
  rec.condition = run.condition.name;
  rec.info.epoch_utime = epoch_utime;
  rec.info.mic_count = run.mic_count;
  rec.info.mic_positions_m = run.mic_positions_m;
  rec.info.radius_m = run.radius_m;
  rec.info.acoustic_delay_s = run.acoustic_delay_s >= 0 ? run.acoustic_delay_s
                              : run.mic_count > 0       ? run.radius_m / kSpeedOfSoundMS
                                                        : 0.0;
  drivers::OperatingPoint op =
      operating_point_of(run, 0);  // before the columns it may measure the speed from are freed

  // The two resamplers on two threads; errors as when the pressure is resampled first.
  Stream pressure, crank, mics;
  drivers::formats::run_both([&] { pressure_streams(run, release, rec, pressure, crank); },
                             [&] {
                               if (run.mic_count == 0) return;
                               resample_mics(run, mics);
                               if (release) free_vector(release->mic_pa);
                             });
  std::int64_t from = pressure.first, to = pressure.end();
  if (run.mic_count > 0) {
    rec.info.mic_passband_hz =
        run.mic_passband_hz.value_or(run.mic_rate_hz != kFs ? dsp::converter_passband_hz(run.mic_rate_hz) : 0.0);
    from = std::max(from, mics.first);
    to = std::min(to, mics.end());
  }
  if (to <= from)
    throw drivers::formats::RunDirError("run '" + run.condition.name + "': " +
                                        (run.mic_count > 0
                                             ? std::string("the pressure and the microphones do not overlap in time")
                                             : std::string("too short to resample")));
  const auto frames = static_cast<std::size_t>(to - from);
  rec.first_index = from;
  rec.pressure_pa = take_frames(pressure, from, frames);
  rec.crank_deg = take_frames(crank, from, frames);
  if (run.mic_count > 0) rec.mics_pa = take_frames(mics, from, frames);
  if (!rec.angle_edges.empty()) rec.angle_edges = edges_within(rec.angle_edges, from, to);
  op.utime = utime_of_index(epoch_utime, from);
  rec.operating_points.push_back(op);
  return rec;
}

}  // namespace

Recording to_recording(const drivers::formats::RunDir& run, std::int64_t epoch_utime) {
  return convert(run, nullptr, epoch_utime);
}

Recording to_recording(drivers::formats::RunDir&& run, std::int64_t epoch_utime) {
  return convert(run, &run, epoch_utime);
}

drivers::OperatingPoint operating_point_of(const drivers::formats::RunDir& run, std::int64_t utime) {
  const drivers::formats::RunCondition& c = run.condition;
  drivers::OperatingPoint op;
  op.utime = utime;
  op.speed_rpm = std::isnan(c.speed_rpm) ? drivers::formats::encoder_speed_rpm(run) : c.speed_rpm;
  op.load_nm = c.load_nm;  // NaN when unknown: travels as NaN
  op.soi_deg_btdc = c.soi_deg_btdc;
  op.rail_pressure_bar = c.rail_pressure_bar.value_or(std::numeric_limits<double>::quiet_NaN());
  op.motored = c.motored_known && c.motored;  // the message's boolean: false when unknown
  return op;
}

drivers::formats::RunDir to_run_dir(const Recording& rec) {
  const std::size_t n = rec.frames();
  if (rec.crank_deg.size() != n || rec.mics_pa.size() != n * rec.info.mic_count)
    throw std::invalid_argument("to_run_dir: recording '" + rec.condition + "' has streams of different lengths");
  drivers::formats::RunDir run;
  run.condition.name = rec.condition;
  if (!rec.operating_points.empty()) {
    const drivers::OperatingPoint& op = rec.operating_points.front();
    run.condition.speed_rpm = op.speed_rpm;
    run.condition.load_nm = op.load_nm;
    run.condition.soi_deg_btdc = op.soi_deg_btdc;
    if (std::isfinite(op.rail_pressure_bar)) run.condition.rail_pressure_bar = op.rail_pressure_bar;
    run.condition.motored = op.motored;
  }
  if (!(run.condition.speed_rpm > 0)) run.condition.speed_rpm = speed_from_crank(rec.crank_deg);
  run.time_s.resize(n);
  run.crank_deg.resize(n);
  run.pressure_pa = rec.pressure_pa;
  double offset = 0;
  for (std::size_t i = 0; i < n; ++i) {
    run.time_s[i] = static_cast<double>(i) / kFs;
    if (i > 0 && rec.crank_deg[i] < rec.crank_deg[i - 1] - 360.0) offset += 720.0;  // a wrap: next cycle
    run.crank_deg[i] = rec.crank_deg[i] + offset;
  }
  run.mic_count = rec.info.mic_count;
  if (run.mic_count > 0) {
    run.mic_rate_hz = kFs;
    run.mic_pa.assign(rec.mics_pa.begin(), rec.mics_pa.end());
    run.mic_positions_m = rec.info.mic_positions_m;
    run.mic_positions_m.resize(run.mic_count);
  }
  run.radius_m = rec.info.radius_m;
  run.acoustic_delay_s = rec.info.acoustic_delay_s;
  if (rec.info.pressure_edges_per_rev > 0) run.pressure_edges_per_rev = rec.info.pressure_edges_per_rev;
  if (run.mic_count > 0 && rec.info.mic_passband_hz > 0) run.mic_passband_hz = rec.info.mic_passband_hz;
  return run;
}

}  // namespace noisemon::cli::formats
