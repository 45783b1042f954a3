// `noisemon dash` as a person uses it: noisemond on the simulated engine and the dash in a private network
// namespace, Debian's headless Chromium on the page. The numbers on the page must equal those of the LCM cycle
// reports of the same cycles (this test subscribes too), the page must keep updating when the daemon and when
// the dash restart, and /metrics must parse and equal the status messages. A second test runs two cells on one
// multicast group; a third has the live gap watch find an effect switched on mid-run and checks its panel.
#include <gtest/gtest.h>
#include <httplib.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <regex>
#include <sstream>
#include <thread>

#include "tests/e2e/chromium_cdp.hpp"
#include "tests/e2e/dash_bus.hpp"
#include "tests/e2e/private_network.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using nlohmann::json;
using noisemon::test::allowance;
using noisemon::test::kLcmUrl;
using noisemon::test::slurp;
using noisemon::test::spawn;
using noisemon::test::wait_for;
const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new noisemon::test::PrivateNetwork);

// Skips without Chromium; fails instead under CI (tests/support/required.hpp), where scripts/install-deps.sh installs
// it.
#define REQUIRE_CHROMIUM()                                                                                    \
  do {                                                                                                        \
    if (access(noisemon::test::kChromium, X_OK) != 0) {                                                       \
      const std::string why = std::string(noisemon::test::kChromium) + " missing (apt-get install chromium)"; \
      if (::noisemon::test::under_ci()) FAIL() << why;                                                        \
      GTEST_SKIP() << why;                                                                                    \
    }                                                                                                         \
  } while (0)

std::string temp(const std::string& name) { return noisemon::test::unique_temp_dir() + "/" + name; }

// Polls `done` every 100 ms until it holds or `seconds` pass.
bool eventually(double seconds, const std::function<bool()>& done) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return done();
}

std::string http_get(int port, const std::string& path) {
  httplib::Client client("127.0.0.1", port);
  client.set_connection_timeout(2);
  const auto res = client.Get(path.c_str());
  return res && res->status == 200 ? res->body : std::string();
}

// A process of the test, killed when the test ends early (a failed ASSERT), so none outlives it.
class Process {
 public:
  explicit Process(pid_t pid) : pid_(pid) {}
  Process(Process&& other) noexcept : pid_(other.pid_) { other.pid_ = -1; }
  Process& operator=(Process&& other) noexcept {
    std::swap(pid_, other.pid_);
    return *this;
  }
  ~Process() {
    if (pid_ > 0) wait_for(pid_, std::chrono::seconds(0));
  }
  // SIGINT, as Ctrl-C; the exit status (-1: it had to be killed after the allowance for a second of work).
  int stop() {
    kill(pid_, SIGINT);
    const int status = wait_for(pid_, allowance(std::chrono::seconds(1)));
    pid_ = -1;
    return status;
  }
  int wait(int seconds) {
    const int status = wait_for(pid_, std::chrono::seconds(seconds));
    pid_ = -1;
    return status;
  }

 private:
  pid_t pid_;
};

Process start_dash(int port, const std::vector<std::string>& extra, const std::string& name) {
  std::vector<std::string> args{NOISEMON_PATH, "dash",     "--lcm",
                                kLcmUrl,       "--listen", "127.0.0.1:" + std::to_string(port)};
  args.insert(args.end(), extra.begin(), extra.end());
  Process p(spawn(args, temp(name + ".out"), temp(name + ".err")));
  eventually(5, [&] { return !http_get(port, "/api/state").empty(); });
  return p;
}

Process start_daemon(const std::vector<std::string>& extra, const std::string& name) {
  std::vector<std::string> args{NOISEMOND_PATH, "--lcm", kLcmUrl};
  args.insert(args.end(), extra.begin(), extra.end());
  return Process(spawn(args, temp(name + ".out"), temp(name + ".err")));
}

// Everything the page shows as text that the test compares, read in one go (the page cannot change meanwhile).
const char* const kReadPage = R"JS((() => {
  const t = (id) => { const e = document.getElementById(id); return e ? e.textContent : ''; };
  if (!document.getElementById('cycle')) return { utime: '', received: 0 };  // still loading
  const mics = [];
  for (let i = 1; document.getElementById('mic-' + i); ++i) mics.push(t('mic-' + i));
  return { utime: document.getElementById('cycle').dataset.utime || '', cycle: t('cycle'), conn: t('conn'),
    lpa_m: t('lpa-meas'), lpa_p: t('lpa-pred'), lwa_m: t('lwa-meas'), lwa_p: t('lwa-pred'), speed: t('speed'),
    soi: t('soi'), flags: t('flags'), published: t('published'), received: +t('received'), events: +t('events'),
    restarts: +t('restarts'), mics, band_flags: t('band-flags'), reference: typeof charts !== 'undefined' && charts.attenuation ? charts.attenuation.data[3] : [] };
})())JS";

std::int64_t page_utime(const json& page) {
  const std::string u = page.value("utime", "");
  return u.empty() ? 0 : std::stoll(u);
}

// The page's numbers against the report of the same cycle as this test received it.
void expect_page_matches_bus(const json& page, noisemon::test::BusRecorder& bus) {
  std::optional<noisemon::cycle_report_t> r;
  eventually(2, [&] { return (r = bus.cycle_at(page_utime(page))).has_value(); });
  ASSERT_TRUE(r) << "the page shows a cycle this test never heard: " << page.dump();
  EXPECT_EQ(page["cycle"], std::to_string(r->cycle));
  const auto near = [](const json& text, double value, double digits) {
    EXPECT_NEAR(std::stod(text.get<std::string>()), value, 0.5 * std::pow(10.0, -digits) + 1e-9) << text;
  };
  near(page["lpa_m"], r->lpa_measured_db, 2);
  near(page["lpa_p"], r->lpa_predicted_db, 2);
  near(page["lwa_m"], r->lwa_measured_db, 2);
  near(page["lwa_p"], r->lwa_predicted_db, 2);
  near(page["speed"], r->speed_rpm, 1);
  near(page["soi"], r->soi_deg_btdc, 1);
  ASSERT_EQ(page["mics"].size(), static_cast<std::size_t>(r->nmics));
  for (int m = 0; m < r->nmics; ++m) near(page["mics"][m], r->mic_lpa_db[m], 2);
  EXPECT_EQ(page["flags"] == "ok", r->flags == 0) << page["flags"] << " for flags " << r->flags;
  const std::string band_flags = page["band_flags"];
  const std::pair<int, const char*> names[] = {
      {1, "nyquist-cut"}, {8, "below-firing"}, {16, "beyond-pressure"}, {32, "beyond-mic"}};
  int any = 0;
  for (int b = 0; b < r->nbands; ++b) any |= r->band_flags[b];
  for (const auto& [bit, name] : names)
    EXPECT_EQ(band_flags.find(name) != std::string::npos, (any & bit) != 0) << band_flags;
  EXPECT_EQ(band_flags == "none", any == 0) << band_flags;
}

// The attenuation plot's reference series: the thesis's linear curve the dash sent, at every band of the report.
void expect_reference_drawn(const json& page, int port) {
  const json state = json::parse(http_get(port, "/api/state"));
  const json& ref = state["reference"];
  ASSERT_EQ(page["reference"].size(), ref["att_db"].size()) << page["reference"].dump();
  for (std::size_t b = 0; b < ref["att_db"].size(); ++b)
    EXPECT_NEAR(page["reference"][b].get<double>(), ref["att_db"][b].get<double>(), 1e-9) << ref["band_hz"][b];
}

// name{labels} value, per the text format; a line that is neither this nor a comment fails the test.
std::map<std::string, double> parse_metrics(const std::string& text) {
  static const std::regex sample(
      R"(([a-zA-Z_:][a-zA-Z0-9_:]*(?:\{[^}]*\})?) (NaN|[+-]Inf|[-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?))");
  static const std::regex comment(R"(# (HELP|TYPE) [a-zA-Z_:][a-zA-Z0-9_:]* .*)");
  std::map<std::string, double> out;
  std::istringstream in(text);
  std::string line;
  std::smatch m;
  while (std::getline(in, line)) {
    if (std::regex_match(line, m, sample))
      out[m[1]] = m[2] == "NaN" ? NAN : std::stod(m[2]);
    else
      EXPECT_TRUE(std::regex_match(line, comment)) << line;
  }
  return out;
}

// /metrics against the status message it was made from (the one with the same cycles_published).
void expect_metrics_match_bus(int port, noisemon::test::BusRecorder& bus) {
  const auto metrics = parse_metrics(http_get(port, "/metrics"));
  const std::string cell = "{cell=\"\"}";
  ASSERT_TRUE(metrics.count("noisemon_cycles_published_total" + cell));
  std::optional<noisemon::status_t> s;
  eventually(2, [&] {
    for (const auto& candidate : bus.statuses())
      if (candidate.cycles_published == metrics.at("noisemon_cycles_published_total" + cell)) s = candidate;
    return s.has_value();
  });
  ASSERT_TRUE(s) << "no status message with cycles_published " << metrics.at("noisemon_cycles_published_total" + cell);
  EXPECT_EQ(metrics.at("noisemon_cycles_dropped_total" + cell), s->cycles_dropped);
  EXPECT_DOUBLE_EQ(metrics.at("noisemon_latency_mean_seconds" + cell), s->latency_ms_mean * 1e-3);
  EXPECT_DOUBLE_EQ(metrics.at("noisemon_processing_max_seconds" + cell), s->processing_ms_max * 1e-3);
  for (int i = 0; i < s->nrings; ++i) {
    const std::string labels = "{cell=\"\",ring=\"" + s->ring_name[i] + "\"}";
    EXPECT_EQ(metrics.at("noisemon_ring_fill_ratio" + labels), s->ring_fill[i]) << labels;
    EXPECT_EQ(metrics.at("noisemon_ring_overruns_total" + labels), s->ring_overruns[i]) << labels;
  }
  for (int i = 0; i < s->nthreads; ++i)
    EXPECT_EQ(metrics.at("noisemon_thread_state{cell=\"\",thread=\"" + s->thread_name[i] + "\"}"), s->thread_state[i]);
  const auto last =
      bus.newest_with_index("NOISEMON_CYCLE", static_cast<std::int64_t>(metrics.at("noisemon_last_cycle" + cell)));
  ASSERT_TRUE(last);
  EXPECT_DOUBLE_EQ(metrics.at("noisemon_lpa_measured_db" + cell), last->lpa_measured_db);
  EXPECT_DOUBLE_EQ(metrics.at("noisemon_lpa_predicted_db" + cell), last->lpa_predicted_db);
}

}  // namespace

TEST(Dash, PageShowsTheBusNumbersAndKeepsUpdatingAcrossRestartsOfTheDaemonAndTheDash) {
  NOISEMON_REQUIRE_NAMESPACE();
  REQUIRE_CHROMIUM();
  constexpr int port = 18080;
  noisemon::test::BusRecorder bus(kLcmUrl, {"NOISEMON_CYCLE"}, "NOISEMON_STATUS");
  ASSERT_TRUE(bus.good());
  Process dash = start_dash(port, {}, "dash");
  Process daemon = start_daemon({}, "daemon");
  noisemon::test::Chromium browser("http://127.0.0.1:" + std::to_string(port) + "/", temp("chromium-profile"),
                                   temp("chromium.log"));
  json page;
  ASSERT_TRUE(eventually(15, [&] { return (page = browser.evaluate(kReadPage)).value("received", 0) >= 5; }))
      << page.dump();
  EXPECT_EQ(page["conn"], "live");

  // Several updates in a row, each equal to its cycle's report.
  std::set<std::int64_t> shown;
  for (int i = 0; i < 6; ++i) {
    page = browser.evaluate(kReadPage);
    expect_page_matches_bus(page, bus);
    shown.insert(page_utime(page));
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  EXPECT_GE(shown.size(), 4u) << "the page did not update";
  expect_reference_drawn(page, port);
  ASSERT_TRUE(eventually(3, [&] { return !bus.statuses().empty(); }));
  expect_metrics_match_bus(port, bus);
  page = browser.evaluate(kReadPage);
  bool published_matches = false;
  for (const auto& s : bus.statuses()) published_matches |= page["published"] == std::to_string(s.cycles_published);
  EXPECT_TRUE(published_matches) << "health shows " << page["published"];

  // The daemon restarts: its cycle indices start again, the page goes on with the new run.
  EXPECT_EQ(daemon.stop(), 0);
  const auto restart_utime =
      std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count();
  daemon = start_daemon({}, "daemon2");
  ASSERT_TRUE(eventually(15, [&] {
    page = browser.evaluate(kReadPage);
    return page_utime(page) > restart_utime && page["restarts"] >= 1;
  })) << page.dump();
  expect_page_matches_bus(page, bus);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // a few cycles of the new run in the trend
  browser.screenshot(DASH_SCREENSHOT);
  std::printf("screenshot: %s\n", DASH_SCREENSHOT);

  // The dash restarts: the page's EventSource reconnects by itself and shows new cycles.
  EXPECT_EQ(dash.stop(), 0);
  const std::int64_t before = page_utime(browser.evaluate(kReadPage));
  dash = start_dash(port, {}, "dash2");
  ASSERT_TRUE(eventually(15, [&] {
    page = browser.evaluate(kReadPage);
    return page["conn"] == "live" && page_utime(page) > before;
  })) << page.dump();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  page = browser.evaluate(kReadPage);
  expect_page_matches_bus(page, bus);
  EXPECT_EQ(daemon.stop(), 0);
  EXPECT_EQ(dash.stop(), 0);
}

TEST(Dash, TwoCellsOnOneGroupAreToldApart) {
  NOISEMON_REQUIRE_NAMESPACE();
  constexpr int port = 18081;
  noisemon::test::BusRecorder bus(kLcmUrl, {"NOISEMON_CYCLE", "NOISEMON_CYCLE_A", "NOISEMON_CYCLE_B"},
                                  "NOISEMON_STATUS_A");
  const std::string config_a = temp("a.toml"), config_b = temp("b.toml"), csv_b = temp("b.csv");
  std::ofstream(config_a) << "[lcm]\ncell = \"A\"\npublish_raw = false\n";
  std::ofstream(config_b) << "[lcm]\ncell = \"B\"\npublish_raw = false\n[sim]\nspeed_rpm = 2000.0\n";
  Process dash = start_dash(port, {"--cell", "A"}, "dash");
  Process watch(spawn(
      {NOISEMON_PATH, "watch", "--lcm", kLcmUrl, "--cell", "B", "--count", "5", "--timeout", "20", "--csv", csv_b},
      temp("watch.out"), temp("watch.err")));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  Process a = start_daemon({"--config", config_a, "--cycles", "60"}, "daemon-a");
  Process b = start_daemon({"--config", config_b, "--cycles", "40"}, "daemon-b");
  EXPECT_EQ(a.wait(30), 0);
  EXPECT_EQ(b.wait(30), 0);
  EXPECT_EQ(watch.wait(10), 0);

  const auto state = json::parse(http_get(port, "/api/state"));
  EXPECT_EQ(state["cell"], "A");
  const auto cycles_a = bus.cycles("NOISEMON_CYCLE_A"), cycles_b = bus.cycles("NOISEMON_CYCLE_B");
  EXPECT_GE(cycles_a.size(), 50u);
  EXPECT_GE(cycles_b.size(), 30u);
  EXPECT_TRUE(bus.cycles("NOISEMON_CYCLE").empty()) << "a cell's daemon published on the plain channel";
  ASSERT_EQ(state["trend"].size(), cycles_a.size());
  for (const auto& point : state["trend"]) {  // every point the dash shows is one of cell A's reports
    const auto utime = std::llround(point["t"].get<double>() * 1e6);
    const auto it = cycles_a.lower_bound(utime - 2);
    ASSERT_TRUE(it != cycles_a.end() && std::llabs(it->first - utime) <= 2) << point.dump();
    EXPECT_EQ(point["cycle"], it->second.cycle);
  }
  std::ifstream in(csv_b);
  std::string line;
  int rows = -1;  // the header
  while (std::getline(in, line)) ++rows;
  EXPECT_EQ(rows, 5);
  for (const auto& [utime, r] : cycles_b) EXPECT_NEAR(r.speed_rpm, 2000.0, 100.0);
  EXPECT_EQ(dash.stop(), 0);
}

// A reference for `noisemon gapwatch`: the healthy virtual engine (noisemond unpaced, 500 cycles, 20 engine seconds)
// as lcm-logger recorded it. A cycle lost on the way only shortens it.
std::string record_healthy_reference() {
  const std::string config = temp("healthy.toml"), log = temp("healthy.lcmlog");
  std::ofstream(config) << "[sim]\npaced = false\n[lcm]\npublish_raw = false\n";
  Process logger(spawn({"/usr/bin/lcm-logger", "-q", "--lcm-url", kLcmUrl, log}, "/dev/null"));
  std::this_thread::sleep_for(allowance(std::chrono::milliseconds(75)));  // subscribed
  Process daemon = start_daemon({"--config", config, "--cycles", "500"}, "healthy");
  EXPECT_EQ(daemon.wait(static_cast<int>(noisemon::test::allowance_s(10.0))), 0);
  std::this_thread::sleep_for(allowance(std::chrono::milliseconds(150)));  // the last reports recorded
  logger.stop();
  return log;
}

// The gap watch's panel: `noisemon gapwatch` live with a reference of the healthy engine, noisemond on the paced
// virtual engine with microphone 7's gain up 4 dB from 5 s on, writing its events as JSON lines too. The page's event
// table must show the event the JSON file holds (effect, microphone, onset), a click must open its evidence, the heat
// map must be drawn, and /metrics must count the event by effect. (With the reference learnt live instead, a start
// on a loaded machine that drops the first cycles moved the reference over the onset, and nothing changed after it.)
TEST(Dash, GapPanelShowsTheLiveGapWatchsEventAndItsEvidence) {
  NOISEMON_REQUIRE_NAMESPACE();
  REQUIRE_CHROMIUM();
  constexpr int port = 18082;
  const std::string reference = record_healthy_reference();
  const std::string config = temp("turning-bad.toml"), events = temp("events.jsonl");
  std::ofstream(config) << "[lcm]\npublish_raw = false\n[[sim.effects]]\neffect = \"mic_gain=4,mic=7\"\nonset_s = 5\n";
  Process dash = start_dash(port, {}, "dash");
  Process watch(
      spawn({NOISEMON_PATH, "gapwatch", "--lcm", kLcmUrl, "--reference", reference, "--json", events, "--no-progress"},
            temp("gapwatch.out"), temp("gapwatch.err")));
  Process daemon = start_daemon({"--config", config}, "daemon");
  noisemon::test::Chromium browser("http://127.0.0.1:" + std::to_string(port) + "/", temp("chromium-profile"),
                                   temp("chromium.log"));
  const char* const read_events = R"JS((() => {
    const rows = [...document.querySelectorAll('#gap-events tr[data-i]')].map((r) => r.textContent);
    const c = document.getElementById('gap-heatmap');
    if (!c) return { rows: [] };  // still loading
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let coloured = 0;
    for (let i = 0; i < d.length; i += 4) coloured += (d[i] !== 255 || d[i + 1] !== 255 || d[i + 2] !== 255) ? 1 : 0;
    return { rows, status: document.getElementById('gap-status').textContent, columns: c.width, coloured };
  })())JS";
  json page;
  // The event comes once the 5 s before the onset and the detection and attribution have passed on the engine's clock
  // (about 12 s), on a loaded machine later.
  if (!eventually(noisemon::test::allowance_s(20.0),
                  [&] { return !(page = browser.evaluate(read_events))["rows"].empty(); })) {
    watch.stop();  // its summary: the cycles it watched, those in changes of operating point
    FAIL() << "no event on the page: " << page.dump() << "\n"
           << slurp(temp("gapwatch.err")) << slurp(temp("daemon.err"));
  }
  std::ifstream in(events);
  std::string line;
  ASSERT_TRUE(std::getline(in, line)) << "gapwatch wrote no event to " << events;
  const json first = json::parse(line);
  EXPECT_EQ(first["effect"], "mic_gain");
  EXPECT_EQ(first["params"]["mic"], 7);
  const std::string row = page["rows"].back();  // the oldest event is the last row
  EXPECT_NE(row.find("mic_gain"), std::string::npos) << row;
  EXPECT_NE(row.find("mic=7"), std::string::npos) << row;
  char onset[32];
  std::snprintf(onset, sizeof onset, "%.1f s", first["onset_s"].get<double>());
  EXPECT_NE(row.find(onset), std::string::npos) << row << " against " << line;
  EXPECT_GT(page["columns"], 100);
  EXPECT_GT(page["coloured"], 0);
  EXPECT_EQ(page["status"].get<std::string>().find("no state"), std::string::npos) << page["status"];

  const json evidence = browser.evaluate(R"JS((() => {
    const rows = document.querySelectorAll('#gap-events tr[data-i]');
    rows[rows.length - 1].click();
    return document.getElementById('gap-evidence').textContent;
  })())JS");
  EXPECT_NE(evidence.get<std::string>().find("mic_gain"), std::string::npos) << evidence;
  EXPECT_NE(evidence.get<std::string>().find("mic7"), std::string::npos) << evidence;
  browser.screenshot(DASH_GAP_SCREENSHOT);
  std::printf("screenshot: %s\n", DASH_GAP_SCREENSHOT);

  const auto metrics = parse_metrics(http_get(port, "/metrics"));
  const std::string counted = "noisemon_gap_events_total{cell=\"\",effect=\"mic_gain\"}";
  ASSERT_TRUE(metrics.count(counted)) << http_get(port, "/metrics");
  EXPECT_GE(metrics.at(counted), 1.0);
  EXPECT_EQ(daemon.stop(), 0);
  EXPECT_EQ(watch.stop(), 0);
  EXPECT_EQ(dash.stop(), 0);
}

// The pre-test check's panel: `noisemon check --publish` before the engine starts (no daemon, so no cycle ever
// comes), microphone 4 unplugged. The page must show the table the check printed, row by row with its verdicts, the
// failed row marked, and /metrics must say which row failed.
TEST(Dash, PreTestCheckPanelShowsThePublishedTableWithNoEngineRunning) {
  NOISEMON_REQUIRE_NAMESPACE();
  REQUIRE_CHROMIUM();
  constexpr int port = 18083;
  const std::string config = temp("check.toml");
  std::ofstream(config)
      << "[lcm]\nurl = \"" << kLcmUrl << "\"\n"
      << "[[sim.faults]]\nkind = \"unplugged\"\nchannel = \"mic4\"\nat_s = 0.0\nduration_s = 1000.0\n";
  Process dash = start_dash(port, {}, "dash");
  noisemon::test::Chromium browser("http://127.0.0.1:" + std::to_string(port) + "/", temp("chromium-profile"),
                                   temp("chromium.log"));
  Process check(spawn({NOISEMON_PATH, "check", "--publish", "--config", config, "--seconds", "1"}, temp("check.out"),
                      temp("check.err")));
  ASSERT_EQ(check.wait(static_cast<int>(noisemon::test::allowance_s(60.0))), 1)
      << slurp(temp("check.out")) << slurp(temp("check.err"));
  const std::string printed = slurp(temp("check.out"));
  const char* const read_check = R"JS((() => {
    const status = document.getElementById('check-status');
    if (!status) return { rows: [] };  // still loading
    const rows = [...document.querySelectorAll('#check-rows tr')].slice(1).map((r) => [...r.children].map((c) => c.textContent));
    return { rows, status: status.textContent };
  })())JS";
  json page;
  ASSERT_TRUE(eventually(noisemon::test::allowance_s(10.0),
                         [&] { return !(page = browser.evaluate(read_check))["rows"].empty(); }))
      << page.dump() << slurp(temp("dash.err"));
  int failed_rows = 0;
  for (const auto& row : page["rows"]) {  // item, value, verdict: each as the terminal printed that row
    const std::string item = row[0], value = row[1], verdict = row[2];
    std::istringstream lines(printed);
    std::string line, match;
    while (std::getline(lines, line))
      if (line.rfind(item + " ", 0) == 0) match = line;
    EXPECT_NE(match.find(value), std::string::npos) << item << ": " << match;
    EXPECT_NE(match.find(verdict), std::string::npos) << item << ": " << match;
    failed_rows += verdict.rfind("FAIL", 0) == 0 ? 1 : 0;
    EXPECT_EQ(verdict.rfind("FAIL", 0) == 0, item == "microphone 4") << item << ": " << verdict;
  }
  EXPECT_EQ(failed_rows, 1);
  EXPECT_NE(page["status"].get<std::string>().find("1 problems: fix them before the test"), std::string::npos)
      << page["status"];
  const auto metrics = parse_metrics(http_get(port, "/metrics"));
  EXPECT_EQ(metrics.at("noisemon_check_problems{cell=\"\"}"), 1.0);
  EXPECT_EQ(metrics.at("noisemon_check_failed{cell=\"\",item=\"microphone 4\"}"), 1.0);
  EXPECT_EQ(metrics.at("noisemon_check_failed{cell=\"\",item=\"microphone 3\"}"), 0.0);
  EXPECT_EQ(dash.stop(), 0);
}

// The recording's buttons: a daemon that records only by command, the page's Start with a test point typed in, then
// Mark and Stop. Each answer the daemon gave shows under the buttons, the file it names is the one the recorder wrote
// (its test point in the name, the three acknowledgements in it), and a name that is no file name is refused by the
// page's server without reaching the daemon.
TEST(Dash, RecordingButtonsStartMarkAndStopTheDaemonsRecording) {
  NOISEMON_REQUIRE_NAMESPACE();
  REQUIRE_CHROMIUM();
  constexpr int port = 18084;
  const std::string records = temp("records");
  std::filesystem::remove_all(records);
  const std::string config = temp("record.toml");
  std::ofstream(config) << noisemon::test::sim_pacing_toml() << "[record]\nenabled = true\nautostart = false\ndir = \""
                        << records << "\"\n";
  Process daemon = start_daemon({"--config", config}, "daemon");
  Process dash = start_dash(port, {}, "dash");
  noisemon::test::Chromium browser("http://127.0.0.1:" + std::to_string(port) + "/", temp("chromium-profile"),
                                   temp("chromium.log"));
  const auto press = [&](const std::string& script) {
    const std::string js =
        "(() => { const $ = (id) => document.getElementById(id); if (!$('record-start') || !$('record-start').onclick) "
        "return '';"
        " $('record-answer').textContent = ''; " +
        script + "; return 'pressed'; })()";
    EXPECT_TRUE(eventually(noisemon::test::allowance_s(10.0), [&] { return browser.evaluate(js) == "pressed"; }));
    json answer;
    const char* const read = "document.getElementById('record-answer').textContent";
    EXPECT_TRUE(eventually(noisemon::test::allowance_s(15.0),
                           [&] {
                             answer = browser.evaluate(read);
                             return answer.is_string() && !answer.get<std::string>().empty() &&
                                    answer.get<std::string>().find("waiting") == std::string::npos;
                           }))
        << answer.dump() << slurp(temp("daemon.err"));
    return answer.is_string() ? answer.get<std::string>() : std::string();
  };
  const std::string started = press("$('record-test-point').value = 'dash-tp'; $('record-start').click()");
  EXPECT_EQ(started.rfind("done: recording test point dash-tp", 0), 0u) << started;
  const std::string refused = press("$('record-test-point').value = '../escape'; $('record-start').click()");
  EXPECT_NE(refused.find("test point '../escape'"), std::string::npos) << refused;
  const std::string marked = press("$('record-note').value = 'door opened'; $('record-mark').click()");
  EXPECT_EQ(marked.rfind("done: marked in ", 0), 0u) << marked;
  const std::string stopped = press("$('record-stop').click()");
  EXPECT_EQ(stopped.rfind("done: recording stopped", 0), 0u) << stopped;
  EXPECT_EQ(daemon.stop(), 0);
  EXPECT_EQ(dash.stop(), 0);

  std::vector<std::filesystem::path> files;
  for (const auto& f : std::filesystem::directory_iterator(records)) files.push_back(f.path());
  ASSERT_EQ(files.size(), 1u);
  EXPECT_TRUE(files[0].filename().string().starts_with("dash-tp_")) << files[0];
  EXPECT_NE(started.find(files[0].string()), std::string::npos) << started;
  int acks = 0;
  lcm::LogFile log(files[0].string(), "r");
  ASSERT_TRUE(log.good());
  while (const lcm::LogEvent* e = log.readNextEvent()) acks += e->channel == "NOISEMON_CMD_ACK" ? 1 : 0;
  EXPECT_EQ(acks, 3);
}
