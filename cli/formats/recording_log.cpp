// Recordings in raw LCM log files: read (the sessions of a log, assembled from its blocks, damaged events skipped
// and counted) and written (RecordingLogWriter).
#include "cli/formats/recording.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <span>
#include <stdexcept>

#include "cli/formats/angle_edges.hpp"
#include "cli/formats/recording_grid.hpp"
#include "drivers/formats/lcm_log_reader.hpp"
#include "drivers/formats/run_both.hpp"
#include "drivers/formats/stream_messages.hpp"

namespace noisemon::cli::formats {
namespace {

using grid::speed_from_crank;
using grid::utime_of_index;

constexpr std::size_t kBlockFrames = drivers::SampleBlock::kMaxFrames;
constexpr std::int64_t kRepeatFrames = 40000;  // session and operating point again every second
constexpr std::size_t kMaxDamageNotes = 10;

template <class Message>
void write_event(lcm::LogFile& log, const std::filesystem::path& path, const std::string& channel, const Message& m,
                 std::int64_t utime, std::vector<char>& buf) {
  buf.resize(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm::LogEvent e{0, utime, channel, static_cast<std::int32_t>(buf.size()), buf.data()};
  if (log.writeEvent(&e) != 0) throw std::runtime_error(path.string() + ": cannot write log event (disk full?)");
}

// ---------------------------------------------------------------------------------------------- reading

struct RawBlock {
  std::int64_t first;
  std::uint32_t frames;
  std::vector<double> data;
};

struct SessionData {
  drivers::StreamInfo info;
  std::string condition;
  std::string source;
  std::vector<RawBlock> pressure, mics, angle;
  std::vector<drivers::OperatingPoint> ops;
};

struct Interval {
  std::int64_t from, to;
};

std::vector<Interval> coverage(std::vector<RawBlock>& blocks) {
  std::stable_sort(blocks.begin(), blocks.end(),
                   [](const RawBlock& a, const RawBlock& b) { return a.first < b.first; });
  std::vector<Interval> out;
  for (const RawBlock& b : blocks) {
    const std::int64_t to = b.first + b.frames;
    if (!out.empty() && b.first <= out.back().to)
      out.back().to = std::max(out.back().to, to);
    else
      out.push_back({b.first, to});
  }
  return out;
}

std::vector<Interval> intersect(const std::vector<Interval>& a, const std::vector<Interval>& b) {
  std::vector<Interval> out;
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    const std::int64_t from = std::max(a[i].from, b[j].from), to = std::min(a[i].to, b[j].to);
    if (from < to) out.push_back({from, to});
    (a[i].to < b[j].to) ? ++i : ++j;
  }
  return out;
}

// Copies the frames of `blocks` (sorted) that fall in [from, to) into out (channels per frame).
void gather(const std::vector<RawBlock>& blocks, std::size_t channels, std::int64_t from, std::int64_t to,
            std::vector<double>& out) {
  out.assign(static_cast<std::size_t>(to - from) * channels, 0.0);
  auto it = std::lower_bound(blocks.begin(), blocks.end(), from - static_cast<std::int64_t>(kBlockFrames),
                             [](const RawBlock& b, std::int64_t v) { return b.first < v; });
  for (; it != blocks.end() && it->first < to; ++it) {
    const std::int64_t a = std::max(from, it->first), z = std::min(to, it->first + it->frames);
    for (std::int64_t k = a; k < z; ++k)
      std::copy_n(&it->data[static_cast<std::size_t>(k - it->first) * channels], channels,
                  &out[static_cast<std::size_t>(k - from) * channels]);
  }
}

// The crank-angle blocks in the order of their first frames (a block's edges in order; blocks of one first frame
// in the log's order).
std::vector<EdgeBlock> edge_blocks(std::vector<RawBlock>& blocks) {
  std::stable_sort(blocks.begin(), blocks.end(),
                   [](const RawBlock& a, const RawBlock& b) { return a.first < b.first; });
  std::vector<EdgeBlock> out;
  for (const RawBlock& b : blocks) out.push_back({b.first, b.data});
  return out;
}

// Two values the same, unknown (NaN) included.
bool same_value(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

// Repeats of the same point (noisemond sends it at 10 Hz) carry nothing new.
std::vector<drivers::OperatingPoint> distinct_points(const std::vector<drivers::OperatingPoint>& points) {
  std::vector<drivers::OperatingPoint> distinct;
  for (const drivers::OperatingPoint& op : points) {
    if (!distinct.empty()) {
      const drivers::OperatingPoint& l = distinct.back();
      if (same_value(l.speed_rpm, op.speed_rpm) && same_value(l.load_nm, op.load_nm) &&
          same_value(l.soi_deg_btdc, op.soi_deg_btdc) && same_value(l.rail_pressure_bar, op.rail_pressure_bar) &&
          l.motored == op.motored)
        continue;
    }
    distinct.push_back(op);
  }
  return distinct;
}

class LogAssembler {
 public:
  LogAssembler(std::string name, const LogChannels& channels, LogReadStats& stats)
      : name_(std::move(name)),
        ch_(channels),
        stats_(stats),
        decoder_({channels, drivers::formats::SessionChanges::kFollow, drivers::formats::BlockCheck::kFinite}) {}

  void event(const drivers::formats::LcmLogEvent& e) {
    ++stats_.events;
    const drivers::formats::RawEvent& ev = decoder_.decode(e.channel, e.data, static_cast<std::size_t>(e.datalen));
    switch (ev.kind) {
      case drivers::formats::RawEventKind::kSession:
        if (!ev.session_started) return;  // the same session, repeated
        sessions_.push_back({decoder_.info(), decoder_.condition(), decoder_.source(), {}, {}, {}, {}});
        ++stats_.sessions;
        return;
      case drivers::formats::RawEventKind::kBlock:
        if (ev.block.frames > 0) add_block(ev);
        return;
      case drivers::formats::RawEventKind::kOperatingPoint:
        sessions_.back().ops.push_back(ev.operating_point);
        return;
      case drivers::formats::RawEventKind::kDamaged:
        return damage(e, ev.reason);
      case drivers::formats::RawEventKind::kBadBlock:
      case drivers::formats::RawEventKind::kOtherSessionBlock:
        return damage(e, "raw " + ev.reason);
      case drivers::formats::RawEventKind::kBeforeSession:
        // An operating point before any session has nothing to attach it to; a raw block there is damage.
        if (ev.channel == drivers::formats::RawChannel::kRaw)
          damage(e, "raw block before any " + ch_.session + " message");
        return;
      case drivers::formats::RawEventKind::kOtherChannel:
        ++stats_.other_channels;
        return;
    }
  }

  void framing(const drivers::formats::LcmLogReader& r) {
    if (r.damaged() == 0) return;
    stats_.damaged += r.damaged();
    note(std::to_string(r.damaged()) + " damaged stretch(es) of the file (" + std::to_string(r.damaged_bytes()) +
         " bytes), the first at byte " + std::to_string(r.first_damage_offset()) +
         (r.truncated() ? "; the log ends inside an event (cut short)" : ""));
  }

  std::vector<Recording> finish() {
    if (sessions_.empty()) throw std::runtime_error(name_ + ": no " + ch_.session + " message: not a noisemon raw log");
    std::vector<Recording> out;
    for (SessionData& s : sessions_) {
      std::vector<Interval> spans = coverage(s.pressure);
      if (s.info.mic_count > 0) spans = intersect(spans, coverage(s.mics));
      if (spans.size() > 1) stats_.pieces_split += static_cast<std::int64_t>(spans.size()) - 1;
      for (const Interval& span : spans) {
        Recording rec;
        rec.condition = s.condition;
        rec.source = s.source;
        rec.info = s.info;
        rec.first_index = span.from;
        std::vector<double> p;
        gather(s.pressure, drivers::kPressureStreamChannels, span.from, span.to, p);
        const std::size_t frames = static_cast<std::size_t>(span.to - span.from);
        rec.pressure_pa.resize(frames);
        rec.crank_deg.resize(frames);
        for (std::size_t f = 0; f < frames; ++f) {
          rec.pressure_pa[f] = p[f * drivers::kPressureStreamChannels + drivers::kPressureChannel];
          rec.crank_deg[f] = p[f * drivers::kPressureStreamChannels + drivers::kCrankChannel];
        }
        if (s.info.mic_count > 0) gather(s.mics, s.info.mic_count, span.from, span.to, rec.mics_pa);
        gather_edges(edge_blocks(s.angle), span.from, span.to, rec.angle_edges);
        // The operating point in force at the start, and every change during the stretch.
        const std::int64_t u0 = utime_of_index(s.info.epoch_utime, span.from);
        const std::int64_t u1 = utime_of_index(s.info.epoch_utime, span.to);
        const drivers::OperatingPoint* before = nullptr;
        for (const drivers::OperatingPoint& op : s.ops) {
          if (op.utime <= u0)
            before = &op;
          else if (op.utime < u1)
            rec.operating_points.push_back(op);
        }
        if (before) rec.operating_points.insert(rec.operating_points.begin(), *before);
        if (rec.operating_points.empty() && !s.ops.empty()) rec.operating_points.push_back(s.ops.front());
        if (rec.operating_points.empty()) {
          // No operating point in the log: the speed is measured, the rest is unknown (never made up).
          constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
          drivers::OperatingPoint op;
          op.utime = u0;
          op.speed_rpm = speed_from_crank(rec.crank_deg);
          op.load_nm = op.soi_deg_btdc = op.rail_pressure_bar = kUnknown;
          rec.operating_points.push_back(op);
        }
        rec.operating_points = distinct_points(rec.operating_points);
        out.push_back(std::move(rec));
      }
      s = SessionData{};  // free the blocks as we go
    }
    if (out.empty()) throw std::runtime_error(name_ + ": the log's sessions hold no complete raw data");
    return out;
  }

 private:
  void add_block(const drivers::formats::RawEvent& ev) {
    const drivers::SampleBlock& b = ev.block;
    RawBlock rb{b.first_index, b.frames, std::vector<double>(b.data, b.data + std::size_t{b.frames} * b.channels)};
    SessionData& s = sessions_.back();
    if (ev.stream == noisemon::raw_block_t::STREAM_PRESSURE_ANGLE)
      s.angle.push_back(std::move(rb));
    else
      (ev.stream == noisemon::raw_block_t::STREAM_PRESSURE ? s.pressure : s.mics).push_back(std::move(rb));
  }
  void damage(const drivers::formats::LcmLogEvent& e, const std::string& what) {
    ++stats_.damaged;
    note("event " + std::to_string(e.eventnum) + " at byte " + std::to_string(e.offset) + " on " +
         std::string(e.channel) + ": " + what);
  }
  void note(std::string s) {
    if (stats_.damage.size() < kMaxDamageNotes) stats_.damage.push_back(std::move(s));
  }

  std::string name_;
  const LogChannels& ch_;
  LogReadStats& stats_;
  drivers::formats::RawStreamDecoder decoder_;
  std::vector<SessionData> sessions_;
};

std::vector<Recording> read_log(drivers::formats::LcmLogReader& reader, const std::string& name,
                                const LogChannels& channels, std::int64_t* skipped, LogReadStats* stats,
                                const ProgressFn& progress) {
  LogReadStats local;
  LogReadStats& st = stats ? *stats : local;
  st = LogReadStats{};
  LogAssembler assembler(name, channels, st);
  drivers::formats::LcmLogEvent e;
  std::int64_t n = 0;
  while (reader.next(e)) {
    assembler.event(e);
    if (progress && (++n & 1023) == 0 && reader.size() > 0)
      progress(static_cast<double>(reader.position()) / static_cast<double>(reader.size()));
  }
  assembler.framing(reader);
  if (skipped) *skipped = st.damaged;
  std::vector<Recording> out = assembler.finish();
  if (progress) progress(1.0);
  return out;
}

}  // namespace

struct RecordingLogWriter::Impl {
  Impl(const std::filesystem::path& p, const LogChannels& c)
      : path(p), channels(c), file_buffer(std::size_t{1} << 20), log(p.string(), "w") {
    if (!log.good()) throw std::runtime_error(path.string() + ": cannot write log file");
    // Large writes: the raw blocks' events go to the file a megabyte at a time, not a few kilobytes.
    std::setvbuf(log.getFilePtr(), file_buffer.data(), _IOFBF, file_buffer.size());
  }
  std::filesystem::path path;
  LogChannels channels;
  std::vector<char> file_buffer;  // the log's stdio buffer: declared before `log`, so it outlives log's last flush
  lcm::LogFile log;
  std::vector<std::int64_t> epochs;
  std::vector<char> buf;
  // The raw block messages of the two streams, refilled for each block (their samples keep their storage).
  noisemon::raw_block_t pressure_block, mic_block, angle_block;
};

RecordingLogWriter::RecordingLogWriter(const std::filesystem::path& log, const LogChannels& channels)
    : impl_(std::make_unique<Impl>(log, channels)) {}
RecordingLogWriter::~RecordingLogWriter() = default;

void RecordingLogWriter::write(const Recording& rec, const ProgressFn& progress) {
  Impl& w = *impl_;
  if (rec.crank_deg.size() != rec.frames() || rec.mics_pa.size() != rec.frames() * rec.info.mic_count ||
      rec.info.mic_count > drivers::SampleBlock::kMaxChannels || rec.info.mic_positions_m.size() < rec.info.mic_count)
    throw std::invalid_argument(w.path.string() + ": recording '" + rec.condition +
                                "' has streams of different lengths");
  if (rec.angle_edges.size() % kEdgeValues != 0 ||
      (!rec.angle_edges.empty() && !(rec.info.pressure_angle_step_deg > 0)))
    throw std::invalid_argument(w.path.string() + ": recording '" + rec.condition +
                                "' has crank-angle edges without a crank-angle step (or a partial edge)");
  if (std::find(w.epochs.begin(), w.epochs.end(), rec.info.epoch_utime) != w.epochs.end())
    throw std::invalid_argument(w.path.string() + ": recording '" + rec.condition +
                                "' has the epoch of an earlier one; each run needs its own");
  w.epochs.push_back(rec.info.epoch_utime);
  const std::int64_t epoch = rec.info.epoch_utime;
  const std::uint32_t mics = rec.info.mic_count;
  std::size_t next_op = 0, next_edge = 0;
  const drivers::OperatingPoint* current = nullptr;
  for (std::size_t f = 0; f < rec.frames(); f += kBlockFrames) {
    const std::int64_t k = rec.first_index + static_cast<std::int64_t>(f);
    const std::int64_t utime = utime_of_index(epoch, k);
    const bool repeat = f % kRepeatFrames < kBlockFrames;  // first block of each second
    if (repeat)
      write_event(w.log, w.path, w.channels.session,
                  drivers::formats::to_message(rec.info, rec.source, utime, rec.condition), utime, w.buf);
    // Each operating point when its time comes; the first one at the start in any case.
    bool op_written = false;
    while (next_op < rec.operating_points.size() &&
           (rec.operating_points[next_op].utime <= utime || (f == 0 && next_op == 0))) {
      current = &rec.operating_points[next_op++];
      write_event(w.log, w.path, w.channels.operating_point, drivers::formats::to_message(*current), utime, w.buf);
      op_written = true;
    }
    if (repeat && !op_written && current)
      write_event(w.log, w.path, w.channels.operating_point, drivers::formats::to_message(*current), utime, w.buf);
    const std::size_t frames = std::min(kBlockFrames, rec.frames() - f);
    noisemon::raw_block_t& p = w.pressure_block;
    drivers::formats::set_raw_block(p, k, frames, drivers::kPressureStreamChannels,
                                    noisemon::raw_block_t::STREAM_PRESSURE, epoch);
    for (std::size_t i = 0; i < frames; ++i) {
      p.data[i * drivers::kPressureStreamChannels + drivers::kPressureChannel] = rec.pressure_pa[f + i];
      p.data[i * drivers::kPressureStreamChannels + drivers::kCrankChannel] = rec.crank_deg[f + i];
    }
    write_event(w.log, w.path, w.channels.raw, p, utime, w.buf);
    if (mics > 0) {
      drivers::formats::set_raw_block(w.mic_block, k, frames, mics, noisemon::raw_block_t::STREAM_MICS, epoch);
      std::copy_n(&rec.mics_pa[f * mics], frames * mics, w.mic_block.data.begin());
      write_event(w.log, w.path, w.channels.raw, w.mic_block, utime, w.buf);
    }
    // The edges before the next block's first frame (all that are left after the last block).
    const double until = f + frames < rec.frames() ? static_cast<double>(k) + static_cast<double>(frames)
                                                   : std::numeric_limits<double>::infinity();
    while (next_edge_block(rec.angle_edges, next_edge, until, rec.info.pressure_angle_step_deg, epoch, w.angle_block))
      write_event(w.log, w.path, w.channels.raw, w.angle_block, w.angle_block.utime, w.buf);
    if (progress && (f / kBlockFrames) % 256 == 0) progress(static_cast<double>(f) / static_cast<double>(rec.frames()));
  }
  std::fflush(w.log.getFilePtr());
  if (progress) progress(1.0);
}

void write_recordings_log(const std::filesystem::path& path, const std::vector<Recording>& recordings,
                          const LogChannels& channels, const ProgressFn& progress) {
  std::size_t total = 0, done = 0;
  for (const Recording& r : recordings) total += r.frames();
  RecordingLogWriter writer(path, channels);
  for (const Recording& r : recordings) {
    ProgressFn part;
    if (progress && total > 0)
      part = [&](double f) {
        progress((static_cast<double>(done) + f * static_cast<double>(r.frames())) / static_cast<double>(total));
      };
    writer.write(r, part);
    done += r.frames();
  }
  if (progress) progress(1.0);
}

std::vector<Recording> read_recordings_log(const std::filesystem::path& log, const LogChannels& channels,
                                           std::int64_t* skipped, LogReadStats* stats, const ProgressFn& progress) {
  drivers::formats::LcmLogReader reader(log);
  return read_log(reader, log.string(), channels, skipped, stats, progress);
}

std::vector<Recording> read_recordings_log(const std::uint8_t* data, std::size_t size, const std::string& name,
                                           const LogChannels& channels, std::int64_t* skipped, LogReadStats* stats) {
  drivers::formats::LcmLogReader reader(data, size);
  return read_log(reader, name, channels, skipped, stats, {});
}

}  // namespace noisemon::cli::formats
