// `noisemon dash`'s /metrics text, read back by a small parser of the Prometheus text exposition format (0.0.4)
// written from the format's rules, not from the writer: every line is a comment (# HELP / # TYPE) or a sample;
// names and label names match their grammars; each family's HELP and TYPE come once, before its samples.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include "cli/dash_json.hpp"
#include "cli/dash_metrics.hpp"
#include "cli/dash_state.hpp"

namespace {

using noisemon::cli::MetricsInput;
using noisemon::cli::prometheus_text;

struct Sample {
  std::string name;
  std::map<std::string, std::string> labels;
  double value;
};

struct Exposition {
  std::vector<Sample> samples;
  std::map<std::string, std::string> types;
  std::vector<std::string> errors;
};

// Label values: any characters with \\, \" and \n escaped.
std::map<std::string, std::string> parse_labels(const std::string& text, std::vector<std::string>& errors) {
  static const std::regex label(R"(([a-zA-Z_][a-zA-Z0-9_]*)=\"((?:[^\"\\\n]|\\[\\\"n])*)\"(,|$))");
  std::map<std::string, std::string> out;
  auto it = text.cbegin();
  std::smatch m;
  while (it != text.cend()) {
    if (!std::regex_search(it, text.cend(), m, label, std::regex_constants::match_continuous)) {
      errors.push_back("bad labels: " + text);
      break;
    }
    if (!out.emplace(m[1], m[2]).second) errors.push_back("duplicate label " + m[1].str());
    it = m[0].second;
  }
  return out;
}

Exposition parse(const std::string& text) {
  static const std::regex help(R"(# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) .*)");
  static const std::regex type(R"(# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram|summary|untyped))");
  static const std::regex sample(
      R"(([a-zA-Z_:][a-zA-Z0-9_:]*)(?:\{(.*)\})? (NaN|[+-]Inf|[-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?))");
  Exposition e;
  std::set<std::string> helped, sampled;
  std::istringstream in(text);
  std::string line;
  std::smatch m;
  if (text.empty() || text.back() != '\n') e.errors.push_back("the text must end with a line feed");
  while (std::getline(in, line)) {
    if (std::regex_match(line, m, help)) {
      if (!helped.insert(m[1]).second) e.errors.push_back("second HELP for " + m[1].str());
    } else if (std::regex_match(line, m, type)) {
      if (e.types.count(m[1]) || sampled.count(m[1])) e.errors.push_back("TYPE after samples or twice: " + m[1].str());
      e.types[m[1]] = m[2];
    } else if (std::regex_match(line, m, sample)) {
      const std::string value = m[3];
      e.samples.push_back({m[1], parse_labels(m[2], e.errors),
                           value == "NaN"    ? NAN
                           : value == "+Inf" ? INFINITY
                           : value == "-Inf" ? -INFINITY
                                             : std::stod(value)});
      sampled.insert(m[1]);
      if (!e.types.count(m[1])) e.errors.push_back("sample before its TYPE: " + line);
    } else {
      e.errors.push_back("not a comment or sample: " + line);
    }
  }
  return e;
}

noisemon::status_t make_status() {
  noisemon::status_t s{};
  s.source = "sim";
  s.uptime_s = 12.5;
  s.nthreads = 2;
  s.thread_name = {"processing", "lcm"};
  s.thread_state = {noisemon::status_t::THREAD_RUNNING, noisemon::status_t::THREAD_FAILED};
  s.thread_error = {"", "boom \"quoted\"\nsecond line"};
  s.nrings = 1;
  s.ring_name = {"pressure"};
  s.ring_fill = {0.25f};
  s.ring_overruns = {7};
  s.cycles_published = 1234;
  s.cycles_dropped = 5;
  s.latency_ms_mean = 20.5f;
  s.latency_ms_max = 34.0f;
  s.processing_ms_mean = 0.5f;
  s.processing_ms_max = 0.75f;
  s.ncounters = 2;
  s.counter_name = {"comedi.pressure.overruns", "alsa.mics.clock_ppb"};
  s.counter_value = {3, -49870};
  s.counter_is_gauge = {false, true};
  return s;
}

const Sample* find(const Exposition& e, const std::string& name, const std::string& label = "",
                   const std::string& value = "") {
  for (const Sample& s : e.samples)
    if (s.name == name && (label.empty() || (s.labels.count(label) && s.labels.at(label) == value))) return &s;
  return nullptr;
}

}  // namespace

TEST(DashMetrics, StatusAndLevelsParseAsPrometheusTextWithTheCellOnEverySample) {
  noisemon::cli::MetricsInput in;
  in.cell = "bay-2";
  in.status = make_status();
  noisemon::cycle_report_t r{};
  r.cycle = 99;
  r.lpa_measured_db = 111.25;
  r.lpa_predicted_db = NAN;
  in.cycle = r;
  const Exposition e = parse(noisemon::cli::prometheus_text(in));
  for (const std::string& error : e.errors) ADD_FAILURE() << error;
  ASSERT_FALSE(e.samples.empty());
  for (const Sample& s : e.samples) EXPECT_EQ(s.labels.count("cell") ? s.labels.at("cell") : "", "bay-2") << s.name;
  EXPECT_EQ(e.types.at("noisemon_cycles_published_total"), "counter");
  EXPECT_EQ(e.types.at("noisemon_ring_fill_ratio"), "gauge");
  EXPECT_EQ(find(e, "noisemon_cycles_published_total")->value, 1234);
  EXPECT_EQ(find(e, "noisemon_cycles_dropped_total")->value, 5);
  EXPECT_EQ(find(e, "noisemon_ring_fill_ratio", "ring", "pressure")->value, 0.25);
  EXPECT_EQ(find(e, "noisemon_ring_overruns_total", "ring", "pressure")->value, 7);
  EXPECT_EQ(find(e, "noisemon_thread_state", "thread", "processing")->value, 1);
  EXPECT_EQ(find(e, "noisemon_thread_state", "thread", "lcm")->value, 3);
  EXPECT_DOUBLE_EQ(find(e, "noisemon_latency_mean_seconds")->value, 0.0205);
  EXPECT_DOUBLE_EQ(find(e, "noisemon_processing_max_seconds")->value, 0.00075);
  EXPECT_EQ(find(e, "noisemon_driver_counter_total", "counter", "comedi.pressure.overruns")->value, 3);
  // A state that may go down is a gauge, never a "_total" counter (Prometheus would take its fall for a reset).
  EXPECT_EQ(find(e, "noisemon_driver_counter_total", "counter", "alsa.mics.clock_ppb"), nullptr);
  ASSERT_NE(find(e, "noisemon_driver_gauge", "gauge", "alsa.mics.clock_ppb"), nullptr);
  EXPECT_EQ(find(e, "noisemon_driver_gauge", "gauge", "alsa.mics.clock_ppb")->value, -49870);
  EXPECT_EQ(e.types.at("noisemon_driver_gauge"), "gauge");
  EXPECT_EQ(find(e, "noisemon_lpa_measured_db")->value, 111.25);
  EXPECT_TRUE(std::isnan(find(e, "noisemon_lpa_predicted_db")->value));
  EXPECT_EQ(find(e, "noisemon_last_cycle")->value, 99);
  for (const auto& [name, type] : e.types)
    if (type == "counter") EXPECT_TRUE(name.ends_with("_total")) << name;
}

// The gap watch's figures: events by effect, the last cycle's gap per band group (measured 3 dB above predicted in
// the 500 Hz and 1 kHz bands, 1 dB below in 2 and 4 kHz: the groups 500 Hz ... 2 kHz and from 2 kHz on read +3 and
// -1), the time since the reference.
TEST(DashMetrics, GapWatchEventsBandGroupsAndReferenceAge) {
  noisemon::cli::MetricsInput in;
  in.cell = "c";
  noisemon::cycle_report_t r{};
  r.band_hz = {500.0f, 1000.0f, 2000.0f, 4000.0f, 20000.0f};
  r.spl_a_measured_db = {83.0f, 93.0f, 69.0f, 79.0f, 10.0f};
  r.spl_a_predicted_db = {80.0f, 90.0f, 70.0f, 80.0f, 50.0f};
  r.band_flags = {0, 0, 0, 0, noisemon::cycle_report_t::BAND_NYQUIST_CUT};  // says nothing: left out
  r.nbands = 5;
  in.cycle = r;
  in.gap_events_by_effect = {{"mic_gain", 2}, {"second_mode", 1}};
  noisemon::gap_status_t g{};
  g.since_reference_s = 420.5;
  in.gap_status = g;
  const Exposition e = parse(noisemon::cli::prometheus_text(in));
  for (const std::string& error : e.errors) ADD_FAILURE() << error;
  EXPECT_EQ(e.types.at("noisemon_gap_events_total"), "counter");
  EXPECT_EQ(find(e, "noisemon_gap_events_total", "effect", "mic_gain")->value, 2);
  EXPECT_EQ(find(e, "noisemon_gap_events_total", "effect", "second_mode")->value, 1);
  EXPECT_NEAR(find(e, "noisemon_gap_band_group_db", "group", "500hz_2khz")->value, 3.0, 1e-5);
  EXPECT_NEAR(find(e, "noisemon_gap_band_group_db", "group", "above_2khz")->value, -1.0, 1e-5);
  EXPECT_TRUE(std::isnan(find(e, "noisemon_gap_band_group_db", "group", "below_500hz")->value));
  EXPECT_EQ(find(e, "noisemon_gap_seconds_since_reference")->value, 420.5);
  EXPECT_EQ(find(e, "noisemon_gap_learning")->value, 0);
  // The heat map's column of this cycle: the gaps, null where the band says nothing.
  const nlohmann::json point = noisemon::cli::trend_point_json(r, 0, false);
  EXPECT_EQ(point["gap"], nlohmann::json::parse("[3.0, 3.0, -1.0, -1.0, null]"));
}

TEST(DashMetrics, LabelValuesAreEscaped) {
  EXPECT_EQ(noisemon::cli::prometheus_label_value("a\"b\\c\nd"), "a\\\"b\\\\c\\nd");
  noisemon::cli::MetricsInput in;
  in.status = make_status();
  in.status->ring_name = {"odd \"ring\"\n"};
  const Exposition e = parse(noisemon::cli::prometheus_text(in));
  for (const std::string& error : e.errors) ADD_FAILURE() << error;
  EXPECT_NE(find(e, "noisemon_ring_fill_ratio", "ring", "odd \\\"ring\\\"\\n"), nullptr);
}

TEST(DashMetrics, BeforeAnyMessageOnlyTheDashsOwnCounterIsExposed) {
  const Exposition e = parse(noisemon::cli::prometheus_text(noisemon::cli::MetricsInput{}));
  for (const std::string& error : e.errors) ADD_FAILURE() << error;
  ASSERT_EQ(e.samples.size(), 1u);
  EXPECT_EQ(e.samples[0].name, "noisemon_dash_cycles_received_total");
}

TEST(DashState, EventsCarryTheTrendPointsAClientHasNotHadAndMarkRestartsAndDrops) {
  noisemon::cli::DashState state("", 3);
  noisemon::cycle_report_t r{};
  for (const std::int64_t cycle : {0, 1, 3, 4, 0}) {  // 2 dropped, then the daemon restarts
    r.cycle = cycle;
    state.on_cycle(r);
  }
  std::uint64_t sent = 0;
  const auto all = nlohmann::json::parse(state.event_json(0, sent));
  EXPECT_EQ(sent, 5u);
  ASSERT_EQ(all["trend"].size(), 3u);  // the history keeps 3
  EXPECT_EQ(all["trend"][0]["dropped"], 1);
  EXPECT_EQ(all["trend"][2]["restarted"], true);
  EXPECT_EQ(all["full"], true);
  const auto newer = nlohmann::json::parse(state.event_json(4, sent));
  ASSERT_EQ(newer["trend"].size(), 1u);
  EXPECT_EQ(newer["full"], false);
  EXPECT_EQ(state.wait_newer(5, std::chrono::milliseconds(1)), 5u);
}

// A check table (published before the engine starts, when no cycle comes) wakes the page's stream, reaches it with
// every row, and /metrics counts its failed rows.
TEST(DashState, ACheckTableWakesTheStreamAndIsInTheEventAndTheMetrics) {
  noisemon::cli::DashState state("c", 10);
  EXPECT_EQ(state.checks(), 0u);
  std::uint64_t sent = 0;
  EXPECT_TRUE(nlohmann::json::parse(state.event_json(0, sent))["check"].is_null());
  noisemon::check_t c{};
  c.utime = 1'700'000'000'000'000;
  c.source = "alsa";
  c.seconds = 3.0;
  c.item = {"microphone 1", "microphone 2", "CAN"};
  c.value = {"94.0 dB, floor 30.1 dB", "12.0 dB, floor 11.9 dB", "0 operating points, last 0 rpm"};
  c.verdict = {"ok", "dead: 82 dB below the others (unplugged, no power, or muted)", "no frames decoded"};
  c.failed = {false, true, true};
  c.nrows = 3;
  c.problems = 2;
  c.summary = "2 problems: fix them before the test";
  std::thread publisher([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    state.on_check(c);
  });
  // No cycle arrives: only the check ends the wait, long before its 60 s.
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(state.wait_newer(0, std::chrono::seconds(60), 0), 0u);
  publisher.join();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(30));
  EXPECT_EQ(state.checks(), 1u);

  const auto event = nlohmann::json::parse(state.event_json(0, sent));
  ASSERT_EQ(event["check"]["rows"].size(), 3u);
  EXPECT_EQ(event["check"]["rows"][1]["item"], "microphone 2");
  EXPECT_EQ(event["check"]["rows"][1]["failed"], true);
  EXPECT_EQ(event["check"]["rows"][1]["verdict"], c.verdict[1]);
  EXPECT_EQ(event["check"]["summary"], c.summary);
  EXPECT_EQ(event["check"]["problems"], 2);

  const Exposition e = parse(state.metrics_text());
  for (const std::string& error : e.errors) ADD_FAILURE() << error;
  EXPECT_EQ(find(e, "noisemon_check_problems")->value, 2);
  EXPECT_EQ(find(e, "noisemon_check_failed", "item", "microphone 1")->value, 0);
  EXPECT_EQ(find(e, "noisemon_check_failed", "item", "microphone 2")->value, 1);
  EXPECT_NEAR(find(e, "noisemon_check_time_seconds")->value, 1.7e9, 1e-3);
}
