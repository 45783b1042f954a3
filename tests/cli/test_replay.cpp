// noisemon replay on hand-made logs: what it refuses, what it skips and counts, that it reports, and that a
// second replay of the same log reports the same.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <memory>
#include <numbers>
#include <set>
#include <sstream>
#include <vector>

#include "cli/hdf5_publisher.hpp"
#include "cli/replay_command.hpp"
#include "cli/watch.hpp"
#include "daemon/cycle_processor.hpp"
#include "daemon/replay.hpp"
#include "daemon/report_messages.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "tests/cli/h5py_reader.hpp"
#include "tests/cli/run_command.hpp"
#include "tests/daemon/csv_column.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/unique_temp.hpp"

using namespace noisemon;

namespace {

template <class Message>
void write(lcm::LogFile& log, const std::string& channel, const Message& m, std::int64_t utime) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm::LogEvent e{0, utime, channel, static_cast<std::int32_t>(buf.size()), buf.data()};
  log.writeEvent(&e);
}

std::string error_of(const daemon::ReplayOptions& o) {
  try {
    daemon::run_replay(o);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

drivers::StreamInfo info() {
  drivers::StreamInfo i;
  i.epoch_utime = 1'000'000;
  i.mic_count = 1;
  i.mic_positions_m = {{0, 0, 1.75}};
  i.radius_m = 1.75;
  i.acoustic_delay_s = 0.0;
  return i;
}

}  // namespace

TEST(Replay, RawBlockBeforeTheSessionIsAnErrorNamingFileAndEvent) {
  const std::string path = noisemon::test::unique_temp_dir() + "/nosession.lcmlog";
  {
    lcm::LogFile log(path, "w");
    drivers::SampleBlock b;
    b.first_index = 0;
    b.frames = 10;
    b.channels = 2;
    write(log, "NOISEMON_RAW", daemon::to_message(b, 0, 0), 1);
  }
  daemon::ReplayOptions o;
  o.log_path = path;
  o.progress = false;
  const std::string err = error_of(o);
  EXPECT_NE(err.find(path), std::string::npos) << err;
  EXPECT_NE(err.find("event 0"), std::string::npos) << err;
  EXPECT_NE(err.find("NOISEMON_SESSION"), std::string::npos) << err;
}

TEST(Replay, MissingFileIsAnErrorNamingIt) {
  daemon::ReplayOptions o;
  o.log_path = "/nonexistent/x.lcmlog";
  EXPECT_NE(error_of(o).find("/nonexistent/x.lcmlog: cannot open"), std::string::npos);
}

namespace {

// One microphone hearing the pressure's 1 kHz tone through nothing: 40 cycles of 1000 frames, with one damaged
// and one foreign event after the session.
constexpr int kCycle = 1000, kTotal = 40 * kCycle;

// The 200-frame pressure (a tone of 1e3 Pa on 1e5 Pa, the crank angle of kCycle-frame cycles) and microphone
// (1e-3 of the tone times mic_gain(k)) blocks from frame `first`.
template <class MicGain>
void tone_blocks(int first, double tone_hz, MicGain mic_gain, drivers::SampleBlock& p, drivers::SampleBlock& m) {
  p.first_index = m.first_index = first;
  p.frames = m.frames = 200;
  p.channels = 2;
  m.channels = 1;
  for (int f = 0; f < 200; ++f) {
    const int k = first + f;
    const double x = 1e3 * std::sin(2 * std::numbers::pi * tone_hz * k / 40000.0);
    p.data[2 * f] = 1e5 + x;
    p.data[2 * f + 1] = -360.0 + 720.0 * (k % kCycle) / kCycle;
    m.data[f] = 1e-3 * x * mic_gain(k);
  }
}

// op: an operating point written after the session (none when not given).
void write_mixed_log(const std::string& path, const drivers::OperatingPoint* op = nullptr) {
  const int total = kTotal;
  {
    lcm::LogFile log(path, "w");
    write(log, "NOISEMON_SESSION", daemon::to_message(info(), "test", 0), 0);
    if (op) write(log, "NOISEMON_OP", daemon::to_message(*op), 0);
    std::vector<char> junk(300, 'x');
    lcm::LogEvent bad{0, 1, "NOISEMON_RAW", static_cast<std::int32_t>(junk.size()), junk.data()};
    log.writeEvent(&bad);
    lcm::LogEvent other{0, 1, "SOMEONE_ELSE", static_cast<std::int32_t>(junk.size()), junk.data()};
    log.writeEvent(&other);
    for (int first = 0; first < total; first += 200) {
      drivers::SampleBlock p, m;
      tone_blocks(
          first, 1000.0, [](int) { return 1.0; }, p, m);
      write(log, "NOISEMON_RAW", daemon::to_message(p, 0, 1'000'000), 2);
      write(log, "NOISEMON_RAW", daemon::to_message(m, 1, 1'000'000), 2);
    }
  }
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST(Replay, DamagedAndForeignEventsAreSkippedAndCountedAndCyclesStillCome) {
  const std::string path = noisemon::test::unique_temp_dir() + "/mixed.lcmlog";
  const int total = kTotal;
  write_mixed_log(path);
  daemon::ReplayOptions o;
  o.log_path = path;
  o.progress = false;
  const daemon::ReplaySummary s = daemon::run_replay(o);
  EXPECT_EQ(s.skipped_damaged, 1);
  EXPECT_EQ(s.skipped_unknown, 1);
  EXPECT_EQ(s.raw_blocks, 2 * total / 200);
  // Boundaries at frames 1000, 2000, ... 39000: 38 closed cycles; frames before the first warm the filters up
  // and the cycle from 39000 never closes.
  EXPECT_EQ(s.reports, 38);
  EXPECT_EQ(s.cycles_dropped, 0);
}

TEST(Replay, SameLogTwiceGivesIdenticalReports) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string path = dir + "/twice.lcmlog";
  write_mixed_log(path);
  std::vector<std::vector<noisemon::cycle_report_t>> reports(2);
  std::vector<std::vector<std::int64_t>> stamps(2);
  std::vector<std::string> csv(2);
  for (int run = 0; run < 2; ++run) {
    daemon::ReplayOptions o;
    o.log_path = path;
    o.progress = false;
    o.out_log = dir + "/reports" + std::to_string(run) + ".lcmlog";
    o.csv_path = dir + "/reports" + std::to_string(run) + ".csv";
    daemon::run_replay(o);
    csv[run] = read_bytes(o.csv_path);
    lcm::LogFile f(o.out_log, "r");
    while (const lcm::LogEvent* e = f.readNextEvent()) {
      noisemon::cycle_report_t m;
      ASSERT_EQ(m.decode(e->data, 0, e->datalen), e->datalen);
      m.processing_ms = 0;  // the CPU time the cycle took: a measurement of this run, not of the engine
      reports[run].push_back(m);
      stamps[run].push_back(e->timestamp);
    }
  }
  ASSERT_EQ(reports[0].size(), 38u);
  EXPECT_EQ(csv[0], csv[1]);
  EXPECT_EQ(std::count(csv[0].begin(), csv[0].end(), '\n'), 1 + 38);  // header and one row per cycle
  EXPECT_EQ(stamps[0], stamps[1]);
  ASSERT_EQ(reports[1].size(), reports[0].size());
  for (std::size_t i = 0; i < reports[0].size(); ++i) {
    // Byte for byte once encoded: every level, flag and operating-point field (NaN included).
    std::vector<char> a(static_cast<std::size_t>(reports[0][i].getEncodedSize())), b(a.size());
    reports[0][i].encode(a.data(), 0, static_cast<int>(a.size()));
    reports[1][i].encode(b.data(), 0, static_cast<int>(b.size()));
    EXPECT_EQ(a, b) << "cycle " << i;
  }
}

namespace {

// The CSV's field `column` (0-based) of every data row.
std::vector<std::string> csv_column(const std::string& csv, std::size_t column) {
  std::istringstream in(csv);
  return test::csv_column(in, column);
}

}  // namespace

TEST(Replay, UnknownLoadAndSoiAreNaNInTheReportsNanInTheCsvAndNaOnTheWatchLines) {
  // A motored run whose SOI does not apply and whose load was not recorded (null in its run.json).
  const std::string dir = noisemon::test::unique_temp_dir();
  drivers::OperatingPoint op;
  op.utime = 0;
  op.speed_rpm = 4800;
  op.load_nm = std::numeric_limits<double>::quiet_NaN();
  op.soi_deg_btdc = -std::numeric_limits<double>::quiet_NaN();  // sign bit set: still printed "nan"
  op.rail_pressure_bar = std::numeric_limits<double>::quiet_NaN();
  op.motored = true;
  write_mixed_log(dir + "/unknowns.lcmlog", &op);
  daemon::ReplayOptions o;
  o.log_path = dir + "/unknowns.lcmlog";
  o.progress = false;
  o.out_log = dir + "/unknowns_reports.lcmlog";
  o.csv_path = dir + "/unknowns.csv";
  ASSERT_EQ(daemon::run_replay(o).reports, 38);
  int reports = 0;
  {
    lcm::LogFile f(o.out_log, "r");
    while (const lcm::LogEvent* e = f.readNextEvent()) {
      noisemon::cycle_report_t m;
      ASSERT_EQ(m.decode(e->data, 0, e->datalen), e->datalen);
      EXPECT_TRUE(std::isnan(m.load_nm));
      EXPECT_TRUE(std::isnan(m.soi_deg_btdc));
      EXPECT_TRUE(m.motored);
      EXPECT_NEAR(m.speed_rpm, 4800.0, 1e-9);  // measured from the cycle: 720 deg in 1000 frames at 40 kHz
      ++reports;
    }
  }
  EXPECT_EQ(reports, 38);
  const std::string csv = read_bytes(o.csv_path);
  for (std::size_t column : {3, 4}) {  // load_nm, soi_deg_btdc
    const std::vector<std::string> fields = csv_column(csv, column);
    ASSERT_EQ(fields.size(), 38u);
    for (const std::string& f : fields) EXPECT_EQ(f, "nan") << "column " << column;
  }

  // noisemon watch reading the reports (LCM's file provider plays the replay's output log as the network).
  cli::WatchOptions w;
  w.lcm_url = "file://" + o.out_log + "?speed=0";
  w.channel = o.config.lcm.report_channel;
  w.count = 38;
  w.timeout_s = noisemon::test::allowance_s(2.5);  // the longest silence: opening the log
  w.csv_path = dir + "/watch.csv";
  testing::internal::CaptureStdout();
  const int status = cli::run_watch(w);
  const std::string printed = testing::internal::GetCapturedStdout();
  ASSERT_EQ(status, 0) << printed;
  std::istringstream lines(printed);
  std::string line;
  int cycle_lines = 0;
  while (std::getline(lines, line)) {
    if (line.find("settling") == std::string::npos && line.find("ok") == std::string::npos) continue;  // headers
    ++cycle_lines;
    EXPECT_EQ(line.find("nan"), std::string::npos) << line;
    // cycle, speed, then the SOI column: n/a.
    std::istringstream fields(line);
    std::string cycle, speed, soi;
    fields >> cycle >> speed >> soi;
    EXPECT_EQ(speed, "4800.0") << line;
    EXPECT_EQ(soi, "n/a") << line;
  }
  EXPECT_EQ(cycle_lines, 38) << printed;
  const std::string watch_csv = read_bytes(w.csv_path);
  EXPECT_EQ(csv_column(watch_csv, 4), csv_column(csv, 4));  // the same "nan" as replay's CSV
  EXPECT_EQ(csv_column(watch_csv, 3), csv_column(csv, 3));
}

namespace {

// Two runs in one log, operating points that change between blocks (and repeats that do not), as noisemond and
// `noisemon import` write them.
void write_two_runs_with_changing_operating_points(const std::string& path) {
  lcm::LogFile log(path, "w");
  for (int run = 0; run < 2; ++run) {
    drivers::StreamInfo i = info();
    i.epoch_utime += run * 100'000'000;
    write(log, "NOISEMON_SESSION", daemon::to_message(i, "test", i.epoch_utime, run == 0 ? "a" : "b"), i.epoch_utime);
    for (int first = 0, n = 0; first < kTotal; first += 200, ++n) {
      if (n % 9 == 0) {
        drivers::OperatingPoint op;
        op.utime = i.epoch_utime + first * 25;
        op.speed_rpm = 2400;
        op.load_nm = 10.0 * ((n / 9) % 4) + run;  // changes every ninth block pair
        op.soi_deg_btdc = 8;
        write(log, "NOISEMON_OP", daemon::to_message(op), op.utime);
        if (n % 2 == 0) write(log, "NOISEMON_OP", daemon::to_message(op), op.utime + 1);  // a repeat
      }
      drivers::SampleBlock p, m;
      tone_blocks(
          first, 1000.0 + 300 * run, [](int k) { return 1 + 0.1 * (k / 5000); }, p, m);
      write(log, "NOISEMON_RAW", daemon::to_message(p, 0, i.epoch_utime), i.epoch_utime + first * 25);
      write(log, "NOISEMON_RAW", daemon::to_message(m, 1, i.epoch_utime), i.epoch_utime + first * 25);
    }
  }
}

struct Stamped {
  std::int64_t utime;
  std::vector<char> bytes;  // encoded, processing_ms zeroed
  bool operator==(const Stamped&) const = default;
};

Stamped stamped(noisemon::cycle_report_t m, std::int64_t utime) {
  m.processing_ms = 0;  // the CPU time the cycle took: a measurement of this run, not of the engine
  std::vector<char> b(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return {utime, b};
}

// The second path: LCM's own log reader and message decoders, and a cycle processor per session driven by hand in
// the log's order (each block added and processed before the next event): what replay did before it ran the pipeline.
std::vector<Stamped> processed_in_log_order(const std::string& path, const daemon::Config& config) {
  std::vector<Stamped> out;
  std::unique_ptr<daemon::CycleProcessor> processor;
  lcm::LogFile log(path, "r");
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    if (e->channel == "NOISEMON_SESSION") {
      noisemon::session_t s;
      EXPECT_EQ(s.decode(e->data, 0, e->datalen), e->datalen);
      daemon::ProcessorConfig pc;
      pc.model = config.model;
      pc.acoustic_delay_s = config.acoustic_delay_s;
      pc.engine = config.engine;
      const auto keep = [&](const daemon::CycleReport& r) {
        out.push_back(stamped(daemon::to_message(r), r.window_end_utime));
      };
      processor = std::make_unique<daemon::CycleProcessor>(pc, drivers::formats::from_message(s), keep);
    } else if (e->channel == "NOISEMON_OP") {
      noisemon::operating_point_t m;
      EXPECT_EQ(m.decode(e->data, 0, e->datalen), e->datalen);
      processor->set_operating_point(drivers::formats::from_message(m));
    } else if (e->channel == "NOISEMON_RAW") {
      noisemon::raw_block_t m;
      EXPECT_EQ(m.decode(e->data, 0, e->datalen), e->datalen);
      if (m.stream == noisemon::raw_block_t::STREAM_PRESSURE)
        processor->add_pressure(drivers::formats::from_message(m));
      else
        processor->add_mics(drivers::formats::from_message(m));
      processor->process();
    }
  }
  return out;
}

}  // namespace

TEST(Replay, ReportsAreTheProcessorsDrivenInLogOrderOperatingPointChangesIncluded) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string path = dir + "/two_runs.lcmlog";
  write_two_runs_with_changing_operating_points(path);
  daemon::ReplayOptions o;
  o.log_path = path;
  o.progress = false;
  o.out_log = dir + "/two_runs_reports.lcmlog";
  const daemon::ReplaySummary s = daemon::run_replay(o);
  EXPECT_EQ(s.sessions, 2);
  EXPECT_EQ(s.reports, 2 * 38);
  std::vector<Stamped> replayed;
  lcm::LogFile f(o.out_log, "r");
  while (const lcm::LogEvent* e = f.readNextEvent()) {
    noisemon::cycle_report_t m;
    ASSERT_EQ(m.decode(e->data, 0, e->datalen), e->datalen);
    EXPECT_EQ(e->channel, "NOISEMON_CYCLE");
    replayed.push_back(stamped(m, e->timestamp));
  }
  const std::vector<Stamped> reference = processed_in_log_order(path, o.config);
  ASSERT_EQ(replayed.size(), reference.size());
  for (std::size_t i = 0; i < reference.size(); ++i) EXPECT_TRUE(replayed[i] == reference[i]) << "report " << i;
  // The operating points did change the reports: several loads among them.
  std::set<double> loads;
  for (const Stamped& r : reference) {
    noisemon::cycle_report_t m;
    m.decode(r.bytes.data(), 0, static_cast<int>(r.bytes.size()));
    loads.insert(m.load_nm);
  }
  EXPECT_GE(loads.size(), 6u);
}

// `noisemon replay --hdf5`: the HDF5 file gets the same cycles as the CSV, each run's condition in /runs and every
// cycle's run index, read back by h5py.
TEST(Replay, Hdf5OutputHoldsEveryCycleWithItsRunAsTheCsvDoes) {
  NOISEMON_REQUIRE_H5PY();
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string path = dir + "/two_runs.lcmlog";
  write_two_runs_with_changing_operating_points(path);
  daemon::ReplayOptions o;
  o.log_path = path;
  o.progress = false;
  o.csv_path = dir + "/two_runs.csv";
  o.publishers.push_back(std::make_shared<cli::Hdf5Publisher>(dir + "/two_runs.h5"));
  const daemon::ReplaySummary s = daemon::run_replay(o);
  o.publishers.clear();  // closes the file
  const nlohmann::json h5 = noisemon::test::read_with_h5py(dir + "/two_runs.h5", dir);
  EXPECT_EQ(h5["conditions"], nlohmann::json({"a", "b"}));
  ASSERT_EQ(h5["cycle"].size(), static_cast<std::size_t>(s.reports));
  std::ifstream csv_file(o.csv_path);
  const std::string csv((std::istreambuf_iterator<char>(csv_file)), std::istreambuf_iterator<char>());
  const auto column = [&csv](const std::string& name) {
    std::istringstream header(csv.substr(0, csv.find('\n')));
    std::size_t index = 0;
    for (std::string field; std::getline(header, field, ','); ++index)
      if (field == name) return csv_column(csv, index);
    ADD_FAILURE() << "no column " << name;
    return std::vector<std::string>{};
  };
  const std::vector<std::string> cycles = column("cycle"), conditions = column("condition");
  ASSERT_EQ(cycles.size(), h5["cycle"].size());
  for (std::size_t i = 0; i < cycles.size(); ++i) {
    EXPECT_EQ(std::stoll(cycles[i]), h5["cycle"][i].get<std::int64_t>()) << "row " << i;
    EXPECT_EQ(conditions[i], h5["run"][i].get<int>() == 0 ? "a" : "b") << "row " << i;
  }
}

// `noisemon replay -j 2` over two logs: each log's CSV is byte for byte the CSV of that log replayed alone, and
// each log is reported once as it finishes.
TEST(Replay, SeveralLogsWithTwoJobsGiveTheCsvOfEachReplayedAlone) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::vector<std::string> logs{dir + "/mixed.lcmlog", dir + "/two_runs.lcmlog"};
  write_mixed_log(logs[0]);
  write_two_runs_with_changing_operating_points(logs[1]);
  std::vector<std::string> alone;
  for (const std::string& log : logs) {
    daemon::ReplayOptions o;
    o.log_path = log;
    o.progress = false;
    o.csv_path = log + ".alone.csv";
    daemon::run_replay(o);
    alone.push_back(read_bytes(o.csv_path));
  }
  std::filesystem::create_directory(dir + "/csv");
  cli::MultiReplayOptions m;
  m.logs = logs;
  m.csv_dir = dir + "/csv";
  m.jobs = 2;
  std::vector<std::size_t> done;
  const auto results = cli::run_replays(m, [&](const cli::LogReplayResult& r, std::size_t n, std::size_t total) {
    EXPECT_EQ(total, 2u);
    EXPECT_TRUE(r.error.empty()) << r.log << ": " << r.error;
    done.push_back(n);
  });
  EXPECT_EQ(done, (std::vector<std::size_t>{1, 2}));
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[0].summary.reports, 38);
  EXPECT_EQ(results[1].summary.reports, 2 * 38);
  EXPECT_EQ(read_bytes(dir + "/csv/mixed.csv"), alone[0]);
  EXPECT_EQ(read_bytes(dir + "/csv/two_runs.csv"), alone[1]);
  EXPECT_EQ(std::count(alone[1].begin(), alone[1].end(), '\n'), 1 + 2 * 38);
}

TEST(Replay, SeveralLogsOneFailingDoesNotStopTheOthers) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::vector<std::string> logs{dir + "/bad.lcmlog", dir + "/good.lcmlog"};
  std::ofstream(logs[0]) << "not an LCM log";
  write_mixed_log(logs[1]);
  cli::MultiReplayOptions m;
  m.logs = logs;
  m.jobs = 2;
  const auto results = cli::run_replays(m);
  ASSERT_EQ(results.size(), 2u);
  EXPECT_NE(results[0].error.find(logs[0]), std::string::npos) << results[0].error;
  EXPECT_TRUE(results[1].error.empty()) << results[1].error;
  EXPECT_EQ(results[1].summary.reports, 38);
}

namespace {

std::string multi_replay_error(const cli::MultiReplayOptions& m) {
  try {
    cli::check_multi_replay(m);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Replay, SeveralLogsRefuseAmbiguousOutputs) {
  const std::string dir = noisemon::test::unique_temp_dir();
  std::filesystem::create_directory(dir + "/other");
  const std::string a = dir + "/a.lcmlog", c = dir + "/c.lcmlog", other_a = dir + "/other/a.lcmlog";
  for (const std::string& log : {a, c, other_a}) write_mixed_log(log);
  EXPECT_EQ(cli::replay_output_name(a), "a");
  EXPECT_EQ(cli::replay_output_name(dir + "/lcmlog-2026-11-25.00"), "lcmlog-2026-11-25.00");

  cli::MultiReplayOptions m;
  m.logs = {a, c};
  m.csv_dir = dir + "/cycles.csv";  // a file name, not a directory
  std::string err = multi_replay_error(m);
  EXPECT_NE(err.find("--csv " + m.csv_dir + ": with 2 logs, --csv names an existing directory"), std::string::npos)
      << err;
  m.csv_dir = a;  // an existing file
  EXPECT_NE(multi_replay_error(m).find("is not one"), std::string::npos);
  m.csv_dir = "";
  m.out_dir = dir;  // DIR/a.lcmlog is the input a.lcmlog
  err = multi_replay_error(m);
  EXPECT_NE(err.find("--out " + dir + " would replace the input log"), std::string::npos) << err;
  m.out_dir = "";
  m.hdf5_dir = dir;
  m.logs = {a, other_a};  // both would write DIR/a.h5
  err = multi_replay_error(m);
  EXPECT_NE(err.find("same name 'a'"), std::string::npos) << err;
  EXPECT_NE(err.find(other_a), std::string::npos) << err;
  m.hdf5_dir = "";
  EXPECT_EQ(multi_replay_error(m), "");  // no outputs: nothing can collide
  m.logs = {a, c};
  m.csv_dir = m.out_dir = dir + "/other";
  EXPECT_EQ(multi_replay_error(m), "");
}

namespace {

using Output = test::CommandOutput;

Output run_replay_tool(const std::string& args) { return test::run_command(std::string(NOISEMON_TOOL) + " " + args); }

}  // namespace

// The command line: one line per finished log, the outputs per log, a file name refused for several logs, and one
// log as before (a file).
TEST(Replay, CommandLineWithSeveralLogsAndJobs) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string a = dir + "/a.lcmlog", c = dir + "/c.lcmlog";
  write_mixed_log(a);
  write_mixed_log(c);
  std::filesystem::create_directory(dir + "/out");
  Output o = run_replay_tool("replay " + a + " " + c + " -j 2 --csv " + dir + "/out --out " + dir + "/out");
  EXPECT_EQ(o.status, 0) << o.text;
  EXPECT_NE(o.text.find("[1/2] "), std::string::npos) << o.text;
  EXPECT_NE(o.text.find("[2/2] "), std::string::npos) << o.text;
  EXPECT_NE(o.text.find("2 logs (-j 2)"), std::string::npos) << o.text;
  EXPECT_EQ(read_bytes(dir + "/out/a.csv"), read_bytes(dir + "/out/c.csv"));  // the same log twice
  EXPECT_TRUE(std::filesystem::exists(dir + "/out/a.lcmlog"));
  o = run_replay_tool("replay " + a + " " + c + " --csv " + dir + "/x.csv");
  EXPECT_EQ(o.status, 1) << o.text;
  EXPECT_NE(o.text.find("--csv names an existing directory"), std::string::npos) << o.text;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.csv"));
  o = run_replay_tool("replay " + a + " --csv " + dir + "/one.csv --no-progress");
  EXPECT_EQ(o.status, 0) << o.text;
  EXPECT_NE(o.text.find("noisemon replay: 1 session(s), "), std::string::npos) << o.text;
  EXPECT_EQ(read_bytes(dir + "/one.csv"), read_bytes(dir + "/out/a.csv"));
}
