// report.html of `noisemon diagnose`: built from hand-made report.json documents with known numbers. The page is
// self-contained and escaped, has every section and plot, places values where the documented axis mapping puts
// them, and renders (without throwing) from reports with missing keys, nulls and values of the wrong type.
#include <gtest/gtest.h>

#include <cmath>
#include <regex>
#include <string>
#include <tuple>
#include <vector>

#include "cli/report/report_html.hpp"

using nlohmann::json;
using noisemon::cli::report::report_html;

namespace {

const std::string kEvil = "<script>alert(1)</script>";

// A band-mode report: 10 bands 31.5 Hz .. 16 kHz, two held-out conditions (the second named kEvil).
json band_report() {
  const std::vector<double> hz{31.5, 63, 125, 250, 500, 1000, 2000, 4000, 8000, 16000};
  json j;
  j["tool"] = "noisemon diagnose";
  j["mode"] = "band";
  j["units"] = "dB";
  j["command"] = "noisemon diagnose runs/x -o out";
  j["data"] = {"runs/x"};
  j["metric"] = "thesis metric";
  j["baseline"] = {{"model", "linear"}, {"train_rms_db", 1.2}, {"heldout_rms_db", 1.5}, {"parameters", 4}};
  j["candidates"] =
      json::array({{{"effect", "second_mode"},
                    {"effects", {"second_mode"}},
                    {"heldout_rms_db", 0.3},
                    {"heldout_thesis_rms_db", 0.25},
                    {"gap_closed_fraction", 0.8},
                    {"significant", true},
                    {"win_fraction", 1.0},
                    {"parameters", 7}},
                   {{"effect", "mic_gain"},
                    {"effects", {"mic_gain"}},
                    {"heldout_rms_db", 1.49},
                    {"gap_closed_fraction", 0.01},
                    {"significant", false},
                    {"win_fraction", 0.5},
                    {"thesis_metric_worse", true},
                    {"closes_db", {{"thesis_bands", -0.25}, {"mic_calibration", 0.5}, {"crank_windows", 0.0}}},
                    {"parameters", 14}}});
  j["combinations"] = json::array({{{"effect", "second_mode+mic_gain"},
                                    {"effects", {"second_mode", "mic_gain"}},
                                    {"heldout_rms_db", 0.29},
                                    {"gap_closed_fraction", 0.81},
                                    {"significant", false}}});
  json w;
  w["bands_hz"] = hz;
  w["heldout_conditions"] = {"cond_a", kEvil};
  w["conditions"] = json::array({{{"name", "cond_a"}, {"role", "train+heldout"}, {"speed_rpm", 3000.0}, {"cycles", 8}},
                                 {{"name", kEvil}, {"role", "train+heldout"}, {"speed_rpm", 3400.0}, {"cycles", 8}}});
  w["floor_limited"] = json::array({std::vector<bool>(10, false), std::vector<bool>(10, false)});
  json gap = json::array();
  for (int r = 0; r < 2; ++r) {
    json row = json::array();
    for (int b = 0; b < 10; ++b) row.push_back(b == 0 ? json(nullptr) : json(b == 6 ? 3.0 : -0.5));
    gap.push_back(row);
  }
  w["gap_db"] = gap;
  json meas = json::array(), base = json::array(), best = json::array();
  for (int r = 0; r < 2; ++r) {
    std::vector<double> m, bl, bs;
    for (int b = 0; b < 10; ++b) {
      m.push_back(100.0 - 4.0 * b);  // 100 .. 64: the y axis is [60, 100] (step 10)
      bl.push_back(99.0 - 4.0 * b);
      bs.push_back(100.0 - 4.0 * b);
    }
    m[5] = 80.0;  // 1 kHz
    meas.push_back(m), base.push_back(bl), best.push_back(bs);
  }
  w["att_meas_db"] = meas;
  w["att_baseline_db"] = base;
  w["att_best_db"] = best;
  w["best_model"] = "second_mode";
  w["mics"] = {"mic1", "mic2"};
  w["mic_offset_db"] = {0.4, -0.4};
  w["mic_gap_rms_db"] = {1.0, 1.1};
  w["mic_residual_baseline_db"] = json::array({{0.2, -0.2}, {0.4, -0.4}});
  w["mic_residual_best_db"] = json::array({{0.0, 0.1}, {0.0, 0.1}});
  w["amplitude"] = {{"cpl_overall_db", {210.0, 212.0}}, {"mean_gap_db", {0.1, 0.2}}, {"slope_db_per_db", 0.05}};
  w["crank_windows"] = {{"start_deg", {-360, -180, 0, 180}}, {"gap_db", {0.1, -0.2, 0.3, nullptr}}};
  w["coherence"] = {{"coherent_fraction", {0.9, 0.95, nullptr, 0.99, 1, 1, 1, 1, 0.8, 0.7}}};
  w["noise_floor"] = {{"combustion_independent_db", {60, 70, 80, 80, 70, 60, 50, 40, 30, 20}},
                      {"background_db", std::vector<json>(10, nullptr)}};
  w["band_notes"] = {"line_free", "", "", "", "", "", "", "", "", ""};
  w["floors"] = {{"pressure_judged_by", {"stated", "estimated"}},
                 {"pressure_stated_bar", {0.02, nullptr}},
                 {"pressure_estimated_bar", {0.0213, 0.187}},
                 {"floor_limited_bands", {2, 7}},
                 {"floor_limited_windows", {40, 120}},
                 {"mic_floor_db", {30, 28, 26, 24, 22, 20, 18, 16, 14, 12}},
                 {"mic_floor_source", "quiet crank windows"},
                 {"summary", {"cond (2 runs): 2-7 of 10 bands floor-limited from 4000 Hz up"}}};
  j["where"] = w;
  std::vector<json> before{nullptr, 0.5, 0.5, 0.5, 1.0, 1.0, 4.0, 1.0, 0.5, 0.5};  // y axis [0, 4] (step 1)
  std::vector<json> after{nullptr, 0.1, 0.1, 0.1, 0.1, 0.1, 0.2, 0.1, 0.1, 0.1};
  j["verdict"] = {{"effect", "second_mode"},      {"also", json::array()},
                  {"heldout_rms_before_db", 1.5}, {"heldout_rms_after_db", 0.3},
                  {"gap_closed_fraction", 0.8},   {"band_before_db", before},
                  {"band_after_db", after},       {"explanation", "second_mode closes 80 % of the held-out gap"}};
  return j;
}

// A waveform-mode report: bands 1, 10, 100 Hz; errors from 1e-4 to 1e-1.
json waveform_report() {
  json j;
  j["mode"] = "waveform";
  j["units"] = "volts";
  j["baseline"] = {{"model", "data"}, {"train_rms_db", 0.01}, {"heldout_rms_db", 0.02}, {"params", {{"k1", 1.0}}}};
  j["candidates"] = json::array({{{"effect", "cubic_stiffness"},
                                  {"heldout_rms_db", 0.001},
                                  {"gap_closed_fraction", 0.95},
                                  {"significant", true},
                                  {"p_value", 0.0005},
                                  {"second_round", false},
                                  {"params", {{"k1", 1.0}, {"k3", 2.0}}}},
                                 {{"effect", "cubic_damping"},
                                  {"heldout_rms_db", 0.0009},
                                  {"gap_closed_fraction", 0.1},
                                  {"significant", true},
                                  {"p_value", 0.0005},
                                  {"second_round", true},
                                  {"params", {{"b3", 1.0}}}}});
  j["not_applicable"] = json::array({{{"effect", "mic_gain"}, {"reason", "one output channel"}}});
  json w;
  w["bands_hz"] = {1.0, 10.0, 100.0};
  w["output_rms"] = {0.1, 0.05, 0.01};
  w["error_rms_before"] = {0.01, 0.02, 0.001};
  w["error_rms_after"] = {0.0001, 0.0005, 0.0002};
  w["amplitude"] = json::array({{{"level_lo", 0.0},
                                 {"level_hi", 0.05},
                                 {"samples", 100},
                                 {"error_rms_before", 0.01},
                                 {"error_rms_after", 0.001}},
                                {{"level_lo", 0.05},
                                 {"level_hi", 0.1},
                                 {"samples", 100},
                                 {"error_rms_before", 0.02},
                                 {"error_rms_after", 0.001}}});
  w["explainable_gap"] = {{"baseline_fraction", 0.8},  {"baseline_p_value", 0.001}, {"baseline_significant", true},
                          {"remaining_fraction", 0.2}, {"remaining_p_value", 0.3},  {"remaining_significant", false}};
  j["where"] = w;
  j["verdict"] = {{"effect", "cubic_stiffness"},
                  {"also", {"cubic_damping"}},
                  {"heldout_rms_before_db", 0.02},
                  {"heldout_rms_after_db", 0.001},
                  {"gap_closed_fraction", 0.95}};
  j["test_sets"] =
      json::array({{{"name", "multisine"}, {"range", {100, 2000}}, {"baseline_rms", 0.02}, {"best_rms", 0.001}}});
  return j;
}

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

std::string svg_by_id(const std::string& html, const std::string& id) {
  const std::size_t a = html.find("<svg id=\"" + id + "\"");
  if (a == std::string::npos) return "";
  const std::size_t b = html.find("</svg>", a);
  return b == std::string::npos ? "" : html.substr(a, b + 6 - a);
}

double attr(const std::string& element, const std::string& name) {
  std::smatch m;
  if (!std::regex_search(element, m, std::regex(" " + name + "=\"([-0-9.]+)\""))) return NAN;
  return std::stod(m[1]);
}

struct Frame {
  double x, y, w, h;
};
Frame frame_of(const std::string& svg) {
  std::smatch m;
  if (!std::regex_search(svg, m, std::regex("<rect class=\"frame\"[^>]*>"))) return {NAN, NAN, NAN, NAN};
  const std::string e = m[0];
  return {attr(e, "x"), attr(e, "y"), attr(e, "width"), attr(e, "height")};
}

// The opening tag of the element (circle or rect) whose <title> is exactly `title`.
std::string element_with_title(const std::string& svg, const std::string& title) {
  const std::size_t t = svg.find("<title>" + title + "</title>");
  if (t == std::string::npos) return "";
  const std::size_t a = svg.rfind('<', t - 1);
  return svg.substr(a, t - a);
}

// The documented axis mapping: x = x0 + pw * (t(v) - t(lo)) / (t(hi) - t(lo)), y likewise from the bottom.
double map_x(const Frame& f, double v, double lo, double hi, bool log) {
  auto t = [&](double u) { return log ? std::log10(u) : u; };
  return f.x + f.w * (t(v) - t(lo)) / (t(hi) - t(lo));
}
double map_y(const Frame& f, double v, double lo, double hi, bool log) {
  auto t = [&](double u) { return log ? std::log10(u) : u; };
  return f.y + f.h * (1.0 - (t(v) - t(lo)) / (t(hi) - t(lo)));
}
const double kEdge = std::pow(2.0, 1.0 / 6.0);  // 1/3-octave band centre to edge

}  // namespace

TEST(ReportHtml, BandPageIsSelfContainedWellFormedAndEscaped) {
  const std::string html = noisemon::cli::report::report_html(band_report());
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(html.find("</html>"), std::string::npos);
  EXPECT_EQ(count(html, "<svg"), count(html, "</svg>"));
  EXPECT_GE(count(html, "<svg"), 8u);
  EXPECT_EQ(count(html, "<section"), count(html, "</section>"));
  EXPECT_EQ(count(html, "<table"), count(html, "</table>"));
  EXPECT_EQ(html.find("http"), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("<img"), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;alert(1)&lt;/script&gt;"), std::string::npos);
  EXPECT_EQ(html.find("Missing from this report"), std::string::npos);
}

TEST(ReportHtml, BandPageHasEverySectionAndPlot) {
  const std::string html = noisemon::cli::report::report_html(band_report());
  for (const char* id : {"gap-map", "att-0", "att-1", "band-gap", "mic-offsets", "mic-residuals", "gap-vs-level",
                         "crank-windows", "coherence", "noise-floor"})
    EXPECT_FALSE(svg_by_id(html, id).empty()) << id;
  for (const char* id : {"id=\"candidates\"", "id=\"conditions\""}) EXPECT_NE(html.find(id), std::string::npos) << id;
  // The header: verdict, gap before -> after with units, closed fraction, explanation, baseline.
  EXPECT_NE(html.find("<div class=\"verdict v-named\">second_mode</div>"), std::string::npos);
  EXPECT_NE(html.find("<b>1.50</b> &rarr; <b>0.30</b> dB"), std::string::npos);
  EXPECT_NE(html.find("80.0 %"), std::string::npos);
  EXPECT_NE(html.find("second_mode closes 80 % of the held-out gap"), std::string::npos);
  EXPECT_NE(html.find("Baseline model <b>linear</b>"), std::string::npos);
  // The verdict's row is highlighted; the combination is marked.
  const std::size_t vrow = html.find("<tr class=\"vrow\">");
  ASSERT_NE(vrow, std::string::npos);
  EXPECT_EQ(html.find("<td>second_mode", vrow), vrow + 17);
  EXPECT_NE(html.find("second_mode + mic_gain<span class=\"tag\">combination</span>"), std::string::npos);
  // The null gap cell is hatched and the hatch is explained.
  EXPECT_NE(html.find("cond_a, 31.5 Hz: not scored"), std::string::npos);
  EXPECT_NE(html.find("not scored (null)"), std::string::npos);
}

TEST(ReportHtml, BandPageShowsTheFloorsAndWhatEachCandidateCloses) {
  const std::string html = noisemon::cli::report::report_html(band_report());
  ASSERT_NE(html.find("id=\"floors\""), std::string::npos);
  EXPECT_NE(html.find("<li>cond (2 runs): 2-7 of 10 bands floor-limited from 4000 Hz up</li>"), std::string::npos);
  // Per condition: which floor judged it, stated and estimated floors, the cells at a floor.
  EXPECT_NE(html.find("<td>cond_a</td><td>stated</td><td>0.02</td><td>0.0213</td><td>2</td><td>40</td>"),
            std::string::npos);
  EXPECT_NE(html.find("<td>estimated</td><td>\xE2\x80\x94</td><td>0.187</td><td>7</td><td>120</td>"),
            std::string::npos);
  EXPECT_NE(html.find("Microphone floor from the quiet crank windows"), std::string::npos);
  // A candidate that makes the thesis metric worse is marked; the parts of the gap it closes are shown.
  EXPECT_NE(html.find("mic_gain<span class=\"tag\">thesis metric worse</span>"), std::string::npos);
  EXPECT_NE(html.find("<td>-0.25 / 0.50 / 0.00</td>"), std::string::npos);
  EXPECT_FALSE(svg_by_id(html, "noise-floor").empty());
  EXPECT_NE(svg_by_id(html, "noise-floor").find("microphone floor"), std::string::npos);
}

TEST(ReportHtml, BandValuesSitWhereTheAxisMappingPutsThem) {
  const std::string html = noisemon::cli::report::report_html(band_report());
  const double lo = 31.5 / kEdge, hi = 16000 * kEdge;  // the band axis: the band edges

  // Attenuation (condition 0): measured 80 dB at 1 kHz; the y axis spans [60, 100].
  const std::string att = svg_by_id(html, "att-0");
  const Frame fa = frame_of(att);
  const std::string dot = element_with_title(att, "1000 Hz, measured: 80.00 dB");
  ASSERT_FALSE(dot.empty());
  EXPECT_NEAR(attr(dot, "cx"), map_x(fa, 1000, lo, hi, true), 0.02);
  EXPECT_NEAR(attr(dot, "cy"), map_y(fa, 80, 60, 100, false), 0.02);

  // Per-band gap: the 2 kHz "before" bar (4 dB, the axis top) is the left half of 80 % of its band's width.
  const std::string bg = svg_by_id(html, "band-gap");
  const Frame fb = frame_of(bg);
  const std::string bar = element_with_title(bg, "2000 Hz, before: 4.00 dB");
  ASSERT_FALSE(bar.empty());
  const double bw = 0.4 * (map_x(fb, 2000 * kEdge, lo, hi, true) - map_x(fb, 2000 / kEdge, lo, hi, true));
  EXPECT_NEAR(attr(bar, "x"), map_x(fb, 2000, lo, hi, true) - bw, 0.02);
  EXPECT_NEAR(attr(bar, "y"), map_y(fb, 4.0, 0, 4, false), 0.02);
  EXPECT_NEAR(attr(bar, "y") + attr(bar, "height"), map_y(fb, 0.0, 0, 4, false), 0.02);

  // Gap map: cell (row 1, band 6 = 2 kHz) holds +3 dB: x = x0 + 6 * pw / 10, y = y0 + 1 * 20, red (positive).
  const std::string gm = svg_by_id(html, "gap-map");
  const Frame fg = frame_of(gm);
  EXPECT_NEAR(fg.h, 2 * 20.0, 1e-9);
  const std::string cell = element_with_title(gm, "&lt;script&gt;alert(1)&lt;/script&gt;, 2000 Hz: 3.00 dB");
  ASSERT_FALSE(cell.empty());
  EXPECT_NEAR(attr(cell, "x"), fg.x + 6 * fg.w / 10, 0.02);
  EXPECT_NEAR(attr(cell, "y"), fg.y + 20, 0.02);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(cell, m, std::regex("fill=\"#([0-9a-f]{2})([0-9a-f]{2})([0-9a-f]{2})\"")));
  EXPECT_GT(std::stoi(m[1], nullptr, 16), std::stoi(m[3], nullptr, 16));
  // A -0.5 dB cell is blue.
  const std::string cold = element_with_title(gm, "cond_a, 63 Hz: -0.50 dB");
  ASSERT_TRUE(std::regex_search(cold, m, std::regex("fill=\"#([0-9a-f]{2})([0-9a-f]{2})([0-9a-f]{2})\"")));
  EXPECT_LT(std::stoi(m[1], nullptr, 16), std::stoi(m[3], nullptr, 16));

  // Mean microphone residual: mic1 baseline (0.2 + 0.4) / 2 = 0.3 dB.
  EXPECT_FALSE(element_with_title(svg_by_id(html, "mic-residuals"), "mic1, baseline: 0.30 dB").empty());
}

TEST(ReportHtml, WaveformPageHasItsFiguresAndPlacesValues) {
  const std::string html = noisemon::cli::report::report_html(waveform_report());
  EXPECT_EQ(count(html, "<svg"), count(html, "</svg>"));
  EXPECT_EQ(html.find("http"), std::string::npos);
  for (const char* id : {"band-error", "amplitude-error"}) EXPECT_FALSE(svg_by_id(html, id).empty()) << id;
  for (const char* id : {"id=\"test-sets\"", "id=\"explainable-gap\"", "id=\"candidates\"", "one output channel",
                         "2nd round", "multisine"})
    EXPECT_NE(html.find(id), std::string::npos) << id;
  EXPECT_NE(html.find("<b>0.02</b> &rarr; <b>0.001</b> volts"), std::string::npos);

  // Band error: x log over the band edges [1 / 2^(1/6), 100 * 2^(1/6)]; y log over [1e-4, 1e-1] padded by 5 % of
  // its 3 decades on each side.
  const std::string svg = svg_by_id(html, "band-error");
  const Frame f = frame_of(svg);
  const double pad = std::pow(10.0, 0.05 * 3);
  for (const auto& [hz, title, v] : {std::tuple{10.0, "10 Hz, error before: 0.02 volts", 0.02},
                                     std::tuple{100.0, "100 Hz, error after: 0.0002 volts", 0.0002}}) {
    const std::string dot = element_with_title(svg, title);
    ASSERT_FALSE(dot.empty()) << title;
    EXPECT_NEAR(attr(dot, "cx"), map_x(f, hz, 1 / kEdge, 100 * kEdge, true), 0.02) << title;
    EXPECT_NEAR(attr(dot, "cy"), map_y(f, v, 1e-4 / pad, 0.1 * pad, true), 0.02) << title;
  }
}

TEST(ReportHtml, EmptyOrOddReportsStillRenderAPageSayingWhatIsMissing) {
  for (const json& j : {json(), json::object(), json::array(), json("text"), json(3.5),
                        json{{"verdict", {{"effect", nullptr}}}}, json{{"mode", "band"}, {"where", nullptr}},
                        json{{"mode", "waveform"}, {"where", json::array()}, {"test_sets", "x"}}}) {
    std::string html;
    ASSERT_NO_THROW(html = noisemon::cli::report::report_html(j)) << j.dump();
    EXPECT_NE(html.find("</html>"), std::string::npos);
    EXPECT_NE(html.find("Missing from this report"), std::string::npos) << j.dump();
    EXPECT_EQ(count(html, "<svg"), count(html, "</svg>"));
  }
  EXPECT_NE(noisemon::cli::report::report_html(json::object()).find("the report is an empty object"),
            std::string::npos);
  EXPECT_NE(noisemon::cli::report::report_html(json{{"mode", "band"}, {"verdict", {{"effect", "none"}}}})
                .find("Not in this report: where"),
            std::string::npos);
}

// Every value of both reports replaced by null, by a string, by an empty array, or removed: the page still renders.
TEST(ReportHtml, AnyKeyMissingNullOrOfTheWrongTypeRenders) {
  for (const json& report : {band_report(), waveform_report()}) {
    const json flat = report.flatten();
    std::vector<json::json_pointer> pointers;
    for (const auto& [key, value] : flat.items()) {
      // The leaf and each of its parents.
      for (json::json_pointer p(key); !p.empty(); p = p.parent_pointer())
        if (std::find(pointers.begin(), pointers.end(), p) == pointers.end()) pointers.push_back(p);
    }
    for (const auto& p : pointers)
      for (int variant = 0; variant < 4; ++variant) {
        json j = report;
        if (variant == 0) j[p] = nullptr;
        if (variant == 1) j[p] = "<b>x</b>";
        if (variant == 2) j[p] = json::array();
        if (variant == 3) {
          json& parent = j[p.parent_pointer()];
          if (parent.is_object())
            parent.erase(p.back());
          else if (parent.is_array())
            parent.erase(static_cast<std::size_t>(std::stoul(p.back())));
        }
        std::string html;
        ASSERT_NO_THROW(html = noisemon::cli::report::report_html(j)) << p.to_string() << " variant " << variant;
        ASSERT_EQ(count(html, "<svg"), count(html, "</svg>")) << p.to_string();
        ASSERT_EQ(html.find("<b>x</b>"), std::string::npos) << p.to_string();
      }
  }
}
