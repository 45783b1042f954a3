// The live gap watch on a synthetic test cell (synthetic_gap_cell.hpp): its false alarms against the rate set, a step
// found with its onset, operating-point changes not taken for changes of the gap.
#include "model/diagnosis/gap_watch.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "tests/model/synthetic_gap_cell.hpp"

namespace nm = noisemon::model;

namespace {

std::vector<nm::diagnosis::GapEvent> watch_cycles(nm::diagnosis::GapWatch& watch, gapcell::Cell& cell,
                                                  std::int64_t cycles, const gapcell::Effects& effects = {},
                                                  std::int64_t effect_from = 0) {
  std::vector<nm::diagnosis::GapEvent> events;
  watch.on_event = [&](const nm::diagnosis::GapEvent& e) { events.push_back(e); };
  for (std::int64_t i = 0; i < cycles; ++i) watch.add(cell.next(i >= effect_from ? effects : gapcell::Effects{}));
  return events;
}

}  // namespace

// With the false-alarm time set to 0.1 h and nothing changing, 2 h of cycles give about 20 alarms less the time spent
// relearning after each (20 s): the union of 62 two-sided CUSUMs at the rate Bonferroni shares out is at most the
// rate set (conservative when features correlate), and not far below it with these nearly independent features.
// The smallest shift is set near the features' block spread (k about 1), where Siegmund's approximation holds; for
// a shift many times the spread (k >> 1) the true rate is far below the one set.
TEST(GapWatch, FalseAlarmRateIsAtMostTheOneSet) {
  nm::diagnosis::GapWatchOptions o;
  o.false_alarm_hours = 0.1;
  o.min_shift_db = 0.1;
  o.reference_s = 20.0;
  gapcell::Cell cell(1);
  nm::diagnosis::GapWatch watch(o);
  const auto cycles = static_cast<std::int64_t>(2.0 * 3600.0 * 3050.0 / 120.0);
  const auto events = watch_cycles(watch, cell, cycles);
  const double watched_h = 2.0 - static_cast<double>(events.size() + 1) * o.reference_s / 3600.0;
  const double expected = watched_h / o.false_alarm_hours;
  std::printf("%zu false alarms in %.2f h watched, %.1f at the rate set\n", events.size(), watched_h, expected);
  EXPECT_LE(static_cast<double>(events.size()), 1.5 * expected)
      << events.size() << " alarms, " << expected << " expected at most";
  EXPECT_GE(static_cast<double>(events.size()), 0.25 * expected) << events.size() << " alarms";
}

// A microphone's sensitivity rising 2 dB at a known cycle: one event, found within a few blocks, its onset on the
// cycle, named mic_gain of that microphone with its size.
TEST(GapWatch, StepIsFoundItsOnsetLocatedAndNamed) {
  gapcell::Cell cell(2);
  nm::diagnosis::GapWatch watch(nm::diagnosis::GapWatchOptions{});
  gapcell::Effects e;
  e.gain_mic = 3;
  e.gain_db = 2.0;
  const std::int64_t onset = 6000;  // 236 s: after the 120 s reference
  const auto events = watch_cycles(watch, cell, 9000, e, onset);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_NEAR(static_cast<double>(events[0].onset_cycle), static_cast<double>(onset), 3.0);
  EXPECT_GE(events[0].detected_cycle, onset);
  EXPECT_LE(events[0].detected_cycle, onset + 4 * 16);
  EXPECT_EQ(events[0].effect, "mic_gain");
  EXPECT_NE(std::find(events[0].features.begin(), events[0].features.end(), "mic 4 +"), events[0].features.end());
  const auto& p = events[0].params;
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].second, 4.0);
  EXPECT_NEAR(p[1].second, 2.0, 0.25);
  EXPECT_GT(events[0].confidence, 0.9);
  // The overall gap moves by what one microphone of ten 2 dB louder adds to their energy mean (its offset and
  // directivity spread its share about a tenth).
  EXPECT_NEAR(events[0].gap_after_db - events[0].gap_before_db,
              10.0 * std::log10(1.0 + (std::pow(10.0, 0.2) - 1.0) / 10.0), 0.08);
}

// The engine ramps between two operating points (3050 rpm / 0 N m and 3450 rpm / 20 N m) over 5 s, twelve times,
// in a cell whose gap follows the load steeply (1 dB per N m, as a band dominated by the transducer's floor does):
// the first and last cycles of every ramp sit within a point's tolerances (2 N m, 60 rpm) while the gap moves by up
// to 2 dB. Watched, they fire; left out as unsteady (the default), nothing does.
std::size_t events_over_ramps(const nm::diagnosis::GapWatchOptions& o) {
  gapcell::Cell cell(8);
  nm::diagnosis::GapWatch watch(o);
  std::size_t events = 0;
  watch.on_event = [&](const nm::diagnosis::GapEvent&) { ++events; };
  auto run = [&](double load, std::int64_t cycles) {
    cell.set_speed(3050.0 + 20.0 * load);
    cell.set_gap_offset(load);
    for (std::int64_t i = 0; i < cycles; ++i) {
      nm::diagnosis::CycleGap c = cell.next();
      c.load_nm = load;
      watch.add(c);
    }
  };
  for (int stint = 0; stint < 12; ++stint) {
    const bool up = stint % 2 == 0;
    run(up ? 0.0 : 20.0, 5000);
    for (int k = 1; k <= 135; ++k) run(20.0 * (up ? k : 135 - k) / 135.0, 1);  // 5 s, a cycle at a time
  }
  watch.flush();
  return events;
}

TEST(GapWatch, CyclesOfAChangeOfOperatingPointAreNotWatched) {
  nm::diagnosis::GapWatchOptions unguarded;
  unguarded.steady.before_s = unguarded.steady.after_s = 0.0;  // a cycle judged on its own operating point alone
  EXPECT_GE(events_over_ramps(unguarded), 1u);
  EXPECT_EQ(events_over_ramps(nm::diagnosis::GapWatchOptions{}), 0u);
}

// The gate's decision: the operating points from before_s before a cycle to after_s after it within the band.
TEST(SteadyStateGate, ACycleIsSteadyWhenThePointHeldAroundIt) {
  nm::diagnosis::SteadyStateGate gate(
      nm::diagnosis::SteadyStateOptions{});  // 5 s before, 2 s after; 30 rpm, 1 N m, 0.5 deg
  const auto at = [](double t, double rpm, double load) {
    return nm::diagnosis::OperatingSample{.time_s = t, .speed_rpm = rpm, .load_nm = load};
  };
  for (int i = 0; i <= 200; ++i) {  // 10 s steady, then the load steps up by 1.5 N m at 10 s
    const double t = 0.05 * i;
    gate.add(at(t, 3050.0 + (i % 2 ? 10.0 : -10.0), t < 10.0 ? 0.0 : 1.5));
  }
  EXPECT_FALSE(gate.decided(8.5));
  EXPECT_TRUE(gate.decided(7.9));
  EXPECT_TRUE(gate.steady(at(7.9, 3050.0, 0.0)));   // the step is 2.1 s later
  EXPECT_FALSE(gate.steady(at(8.1, 3050.0, 0.0)));  // the step is within 2 s
  EXPECT_FALSE(gate.steady(at(7.9, 3100.0, 0.0)));  // its own speed outside the band of its neighbours'
  gate.flush();
  EXPECT_TRUE(gate.decided(9.9));
  EXPECT_FALSE(gate.steady(at(9.9, 3050.0, 1.5)));  // the point before it differs
  gate.add(at(1.0, 2000.0, 0.0));                   // a clock that runs back: another run
  EXPECT_TRUE(gate.steady(at(1.0, 2000.0, 0.0)));
  EXPECT_FALSE(gate.decided(1.0));
}

// Two operating points whose gaps differ by 2 dB, the engine switching between them every 3 minutes for 2 hours:
// each learns its own reference, and no switch is an event (the false-alarm time 80 h: one in 40 runs would fire).
TEST(GapWatch, OperatingPointChangesAreNotChanges) {
  nm::diagnosis::GapWatchOptions o;
  o.false_alarm_hours = 80.0;
  gapcell::Cell cell(3);
  nm::diagnosis::GapWatch watch(o);
  std::vector<nm::diagnosis::GapEvent> events;
  watch.on_event = [&](const nm::diagnosis::GapEvent& e) { events.push_back(e); };
  for (int stint = 0; stint < 40; ++stint) {
    const bool second = stint % 2 == 1;
    cell.set_speed(second ? 3450.0 : 3050.0);
    cell.set_gap_offset(second ? 2.0 : 0.0);
    const auto cycles = static_cast<std::int64_t>(180.0 * (second ? 3450.0 : 3050.0) / 120.0);
    for (std::int64_t i = 0; i < cycles; ++i) watch.add(cell.next());
  }
  EXPECT_TRUE(events.empty()) << events.size() << " events, the first " << events.front().effect;
  EXPECT_EQ(watch.reference().points.size(), 2u);
  EXPECT_FALSE(watch.learning());
}

// A reference saved from one run and given to the next: watched from its first block, no learning.
TEST(GapWatch, GivenReferenceIsWatchedFromTheStart) {
  gapcell::Cell first(4);
  nm::diagnosis::GapWatch learner(nm::diagnosis::GapWatchOptions{});
  (void)watch_cycles(learner, first, 4000);
  ASSERT_FALSE(learner.learning());
  gapcell::Cell second(5);
  nm::diagnosis::GapWatch watch(nm::diagnosis::GapWatchOptions{});
  watch.set_reference(learner.reference());
  gapcell::Effects e;
  e.gain_mic = 0;
  e.gain_db = 3.0;
  const auto events = watch_cycles(watch, second, 600, e, 200);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].effect, "mic_gain");
  EXPECT_NEAR(static_cast<double>(events[0].onset_cycle), 200.0, 3.0);
}

// The daemon restarts: its reports' cycle numbers start again at 0. The watch goes on (the same operating point, the
// same reference), and a step after the restart is found with its onset in the new numbering.
TEST(GapWatch, DaemonRestartNumberingAgainFromZeroIsNoChange) {
  gapcell::Cell before(6);
  nm::diagnosis::GapWatch watch(nm::diagnosis::GapWatchOptions{});
  std::vector<nm::diagnosis::GapEvent> events;
  watch.on_event = [&](const nm::diagnosis::GapEvent& e) { events.push_back(e); };
  for (int i = 0; i < 6000; ++i) watch.add(before.next());
  gapcell::Cell after(7);  // cycle numbers from 0 again
  gapcell::Effects e;
  e.gain_mic = 8;
  e.gain_db = 2.5;
  for (int i = 0; i < 3000; ++i) watch.add(after.next(i >= 1500 ? e : gapcell::Effects{}));
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].effect, "mic_gain");
  EXPECT_NEAR(static_cast<double>(events[0].onset_cycle), 1500.0, 3.0);
  EXPECT_GE(events[0].detected_cycle, 1500);
  EXPECT_LT(events[0].detected_cycle, 1600);
}

// A structural gain that follows speed (3 dB per 1000 rpm, nil at 2000 rpm, fixed here, not the sim's law) switches
// on while the engine runs at 2500 rpm, then the engine moves to 3500 rpm, whose reference was learnt clean: two
// speed_dependence events, 1.5 dB and 4.5 dB; the second gives the law from both.
TEST(GapWatch, StructuralGainMetAtTwoSpeedsGivesItsLaw) {
  gapcell::Cell cell(9);
  nm::diagnosis::GapWatch watch(nm::diagnosis::GapWatchOptions{});
  std::vector<nm::diagnosis::GapEvent> events;
  watch.on_event = [&](const nm::diagnosis::GapEvent& e) { events.push_back(e); };
  auto run = [&](double rpm, double seconds, bool effect) {
    cell.set_speed(rpm);
    gapcell::Effects e;
    if (effect) e.structure_db.assign(gapcell::kBandsHz.size(), 3.0 * (rpm - 2000.0) / 1000.0);
    for (auto i = static_cast<std::int64_t>(seconds * rpm / 120.0); i > 0; --i) watch.add(cell.next(e));
  };
  run(2500.0, 150.0, false);
  run(3500.0, 150.0, false);
  run(2500.0, 60.0, false);
  run(2500.0, 60.0, true);
  run(3500.0, 60.0, true);
  watch.flush();
  ASSERT_EQ(events.size(), 2u);
  auto param = [](const nm::diagnosis::GapEvent& e, const char* key) {
    for (const auto& [k, v] : e.params)
      if (k == key) return v;
    return std::nan("");
  };
  for (const auto& e : events) EXPECT_EQ(e.effect, "speed_dependence");
  std::printf("gains %.2f dB at 2500 rpm, %.2f dB at 3500 rpm: %.2f dB/krpm, nil at %.0f rpm\n",
              param(events[0], "gain_db"), param(events[1], "gain_db"), param(events[1], "db_per_krpm"),
              param(events[1], "nil_rpm"));
  EXPECT_NEAR(param(events[0], "gain_db"), 1.5, 0.1);
  EXPECT_EQ(param(events[0], "speed_rpm"), 2500.0);
  EXPECT_TRUE(std::isnan(param(events[0], "db_per_krpm")));  // one speed: no law yet
  EXPECT_NEAR(param(events[1], "gain_db"), 4.5, 0.1);
  EXPECT_NEAR(param(events[1], "db_per_krpm"), 3.0, 0.15);
  EXPECT_NEAR(param(events[1], "nil_rpm"), 2000.0, 100.0);
}
