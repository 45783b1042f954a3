// The real-time path neither allocates nor locks after start: the driver threads' work (the virtual engine's
// generators, the encoder decoder) and the processing thread's (CycleProcessor) run here, after a warm-up, with
// every allocation (global operator new, malloc through it) and every mutex lock of this process counted.
// The LCM publishing thread is not on the path: it encodes messages (which allocates) behind a ring.
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <pthread.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <mutex>
#include <new>
#include <vector>

#include "daemon/cycle_processor.hpp"
#include "drivers/sim/sim_generators.hpp"
#include "drivers/source.hpp"
#include "tests/support/allocation_counter.hpp"

namespace {
std::atomic<bool> counting{false};
std::atomic<long> locks{0};  // while counting (allocations: tests/support/allocation_counter.hpp)
}  // namespace

// Every std::mutex (and any other pthread mutex) lock of the program, interposed on the C library's.
extern "C" int pthread_mutex_lock(pthread_mutex_t* m) {
  using Lock = int (*)(pthread_mutex_t*);
  static const auto real = reinterpret_cast<Lock>(dlsym(RTLD_NEXT, "pthread_mutex_lock"));
  if (counting.load(std::memory_order_relaxed)) locks.fetch_add(1, std::memory_order_relaxed);
  return real(m);
}

namespace {

namespace nd = noisemon::drivers;

struct Counted {
  long allocations, locks;
};

template <class Work>
Counted count(Work&& work) {
  noisemon::test::reset_allocation_counts();
  locks = 0;
  counting = true;
  work();
  const long allocations = noisemon::test::allocations_since_reset();
  counting = false;
  return {allocations, locks.load()};
}

TEST(RealTimePath, TheCountersSeeAllocationsAndLocks) {
  // The instrument first: it must see what it is meant to catch.
  const Counted c = count([] {
    std::vector<double> v(100);
    std::mutex m;
    std::lock_guard<std::mutex> lock(m);
    v[1] = 1;
  });
  EXPECT_GE(c.allocations, 1);
  EXPECT_GE(c.locks, 1);
}

TEST(RealTimePath, DriverGeneratorsAndTheEncoderDecoderNeitherAllocateNorLockOnceRunning) {
  nd::sim::SimConfig config;
  nd::sim::PressureGenerator pressure(config, 0.0);
  nd::sim::MicGenerator mics(config, 0.0);
  nd::BlockRing pressure_ring(4096), mic_ring(4096), angle_ring(8192);
  pressure.set_angle_ring(&angle_ring);  // the crank-angle stream too, as the daemon runs it
  double t = 0.0;
  for (; t < 0.5; t += 0.005) {  // warm-up: lock, the first held revolutions, scratch sized
    pressure.advance(t, pressure_ring);
    mics.advance(t, mic_ring);
  }
  nd::SampleBlock sink;
  while (pressure_ring.read(&sink, 1)) {
  }
  while (mic_ring.read(&sink, 1)) {
  }
  while (angle_ring.read(&sink, 1)) {
  }
  const Counted c = count([&] {
    for (; t < 1.5; t += 0.005) {
      pressure.advance(t, pressure_ring);
      mics.advance(t, mic_ring);
      while (pressure_ring.read(&sink, 1)) {
      }
      while (mic_ring.read(&sink, 1)) {
      }
      while (angle_ring.read(&sink, 1)) {
      }
    }
  });
  EXPECT_EQ(c.allocations, 0);
  EXPECT_EQ(c.locks, 0);
}

double pulse(double crank) { return 1e5 + 60e5 * std::exp(-crank * crank / 400.0); }

// Blocks of a steady engine at 3000 rpm (a cycle is 1600 frames): a pressure pulse at firing TDC, crank angle,
// ten microphones hearing a tone; and the crank-angle stream of a 0.1 deg encoder (4.5 edges a frame).
struct Streams {
  std::int64_t next = 0, next_edge = 0;
  // The edges before frame `until`, in blocks of at most 256, into the processor.
  void edges(std::int64_t until, noisemon::daemon::CycleProcessor& processor, nd::SampleBlock& a) {
    a.channels = nd::kAngleStreamChannels;
    for (;;) {
      a.frames = 0;
      for (; a.frames < 256; ++a.frames, ++next_edge) {
        const double instant = static_cast<double>(next_edge) * 0.1 * 1600.0 / 720.0;
        if (instant >= static_cast<double>(until)) break;
        if (a.frames == 0) a.first_index = static_cast<std::int64_t>(std::floor(instant));
        const double crank = std::fmod(static_cast<double>(next_edge) * 0.1, 720.0) - 360.0;
        a.data[a.frames * 2 + nd::kAngleCrankChannel] = crank;
        a.data[a.frames * 2 + nd::kAnglePressureChannel] = pulse(crank);
      }
      if (a.frames == 0) return;
      processor.add_pressure_angle(a);
    }
  }
  void fill(nd::SampleBlock& p, nd::SampleBlock& m) {
    p.first_index = m.first_index = next;
    p.frames = m.frames = nd::SampleBlock::kMaxFrames;
    p.channels = nd::kPressureStreamChannels;
    m.channels = 10;
    for (std::uint32_t f = 0; f < p.frames; ++f, ++next) {
      const double crank = std::fmod(static_cast<double>(next) * 720.0 / 1600.0, 720.0) - 360.0;
      p.data[f * 2 + nd::kPressureChannel] = pulse(crank);
      p.data[f * 2 + nd::kCrankChannel] = crank;
      for (int i = 0; i < 10; ++i)
        m.data[f * 10 + i] = 2.0 * std::sin(2 * M_PI * 1000.0 * static_cast<double>(next) / 40000.0 + i);
    }
  }
};

TEST(RealTimePath, ProcessingNeitherAllocatesNorLocksOnceRunning) {
  nd::StreamInfo info;
  info.mic_count = 10;
  info.radius_m = 1.75;
  int reports = 0;
  noisemon::daemon::CycleProcessor processor({}, info, [&](const noisemon::daemon::CycleReport&) { ++reports; });
  Streams streams;
  nd::SampleBlock p, m;
  auto run = [&](int blocks) {
    for (int b = 0; b < blocks; ++b) {
      streams.fill(p, m);
      processor.add_pressure(p);
      processor.add_mics(m);
      processor.process();
    }
  };
  run(200);  // warm-up: 1.3 s, the first cycles and their scratch
  const int before = reports;
  const Counted c = count([&] { run(1000); });  // 6.4 s, 160 cycles
  EXPECT_GE(reports - before, 150);
  EXPECT_EQ(c.allocations, 0);
  EXPECT_EQ(c.locks, 0);
}

// The same with the crank-angle stream, whose cycles the combustion figures are computed on.
TEST(RealTimePath, TheCrankAngleStreamNeitherAllocatesNorLocksOnceRunning) {
  nd::StreamInfo info;
  info.mic_count = 10;
  info.radius_m = 1.75;
  info.pressure_angle_step_deg = 0.1;
  int reports = 0, with_figures = 0;
  noisemon::daemon::CycleProcessor processor({}, info, [&](const noisemon::daemon::CycleReport& r) {
    ++reports;
    if (std::isfinite(r.combustion.imep_gross_pa)) ++with_figures;
  });
  Streams streams;
  nd::SampleBlock p, m, a;
  auto run = [&](int blocks) {
    for (int b = 0; b < blocks; ++b) {
      streams.fill(p, m);
      streams.edges(streams.next, processor, a);
      processor.add_pressure(p);
      processor.add_mics(m);
      processor.process();
    }
  };
  run(200);
  const int before = reports;
  const Counted c = count([&] { run(1000); });
  EXPECT_GE(reports - before, 150);
  EXPECT_EQ(with_figures, reports);
  EXPECT_EQ(c.allocations, 0);
  EXPECT_EQ(c.locks, 0);
}

}  // namespace
