// The recorder in-process: what it is given comes back from its files, every message equal and in order, through
// the project's log reader and LCM's own (lcm-logplayer's); a writer held up (a pipe nobody reads) loses messages
// that are counted exactly, sent = written + lost, with a marker in the file where each loss was; rotation by size
// gives parts named as documented whose events, less each part's leads, are what was published; a disk that is full
// (/dev/full) stops the recording with the error in its state while publish_bytes goes on returning; an unwritable
// folder is an error at start; a file cut inside an event reads back to its last whole event.
#include "daemon/recorder.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "daemon/record_files.hpp"
#include "drivers/formats/lcm_log_reader.hpp"
#include "noisemon/record_loss_t.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace noisemon::daemon {
namespace {

namespace fs = std::filesystem;

struct RecEvent {
  std::string channel;
  std::int64_t utime = 0;
  std::vector<std::uint8_t> data;
  bool operator==(const RecEvent&) const = default;
};

// Message i: its own size (12 ... 4 KiB), channel and bytes, so a swapped, lost or damaged one shows.
RecEvent rec_message(int i, std::size_t size = 0) {
  static const char* const channels[] = {"NOISEMON_RAW", "NOISEMON_CYCLE", "NOISEMON_STATUS"};
  RecEvent e{channels[i % 3], 1'700'000'000'000'000 + 25 * i, {}};
  e.data.resize(size > 0 ? size : 12 + (static_cast<std::size_t>(i) * 977) % 4096);
  for (std::size_t k = 0; k < e.data.size(); ++k) e.data[k] = static_cast<std::uint8_t>(i * 31 + k * 7);
  return e;
}

void rec_publish(Recorder& r, const RecEvent& e) { r.publish_bytes(e.channel, e.data.data(), e.data.size(), e.utime); }

// Every well-framed event of a log, by the project's reader.
std::vector<RecEvent> rec_read(drivers::formats::LcmLogReader& reader) {
  std::vector<RecEvent> out;
  drivers::formats::LcmLogEvent e;
  while (reader.next(e))
    out.push_back({std::string(e.channel), e.timestamp, std::vector<std::uint8_t>(e.data, e.data + e.datalen)});
  return out;
}
std::vector<RecEvent> rec_read(const fs::path& file) {
  drivers::formats::LcmLogReader reader(file);
  return rec_read(reader);
}

// The same by LCM's own reader (lcm-logplayer's).
std::vector<RecEvent> rec_read_with_lcm(const fs::path& file) {
  lcm::LogFile log(file.string(), "r");
  std::vector<RecEvent> out;
  if (!log.good()) return out;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    const auto* bytes = static_cast<const std::uint8_t*>(e->data);
    out.push_back({e->channel, e->timestamp, std::vector<std::uint8_t>(bytes, bytes + e->datalen)});
  }
  return out;
}

// The running test's folder, emptied: a test repeated in one process (--gtest_repeat) starts again from nothing.
std::string rec_fresh_dir() {
  const std::string dir = noisemon::test::unique_temp_dir();
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

RecordConfig rec_config(const std::string& dir, double buffer_mb = 16) {
  RecordConfig c;
  c.enabled = true;
  c.dir = dir;
  c.buffer_mb = buffer_mb;
  return c;
}

LcmConfig rec_lcm(const std::string& cell = "") {
  LcmConfig l;
  set_cell(l, cell);
  return l;
}

std::vector<fs::path> rec_files_in(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

TEST(Recorder, EveryMessageComesBackEqualAndInOrderFromAFileNamedAsDocumented) {
  const std::string dir = rec_fresh_dir() + "/made/by/the/recorder";
  std::vector<RecEvent> sent;
  {
    RecordConfig config = rec_config(dir);
    config.test_point = "idle-1800";
    Recorder recorder(config, rec_lcm("cell7"));
    for (int i = 0; i < 600; ++i) {
      sent.push_back(rec_message(i));
      rec_publish(recorder, sent.back());
    }
    recorder.flush();
    const RecorderState s = recorder.state();
    EXPECT_TRUE(s.recording);
    EXPECT_EQ(s.messages_sent, 600);
    EXPECT_EQ(s.messages_written, 600);
    EXPECT_EQ(s.messages_lost, 0);
    EXPECT_EQ(s.files, 1);
    EXPECT_EQ(fs::path(s.file).parent_path(), fs::path(dir));
  }
  const std::vector<fs::path> files = rec_files_in(dir);
  ASSERT_EQ(files.size(), 1u);
  EXPECT_TRUE(
      std::regex_match(files[0].filename().string(), std::regex(R"(cell7_idle-1800_20[0-9]{6}-[0-9]{6}_001\.lcmlog)")))
      << files[0];
  EXPECT_EQ(rec_read(files[0]), sent);
  EXPECT_EQ(rec_read_with_lcm(files[0]), sent);
  // Without a cell the name starts with the test point.
  EXPECT_EQ(record_file_name("", "run", 0, 12).substr(0, 4), "run_");
  EXPECT_TRUE(record_file_name("", "run", 0, 12).ends_with("_012.lcmlog"));
}

TEST(Recorder, AWriterHeldUpLosesMessagesThatAreCountedExactlyAndMarkedInTheFile) {
  // A pipe nobody reads for a while: the writer blocks once the pipe holds 64 KiB, its 64 KiB buffer fills behind it,
  // and the rest of the burst is lost.
  const std::string dir = rec_fresh_dir(), fifo = dir + "/held-up.pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  const int read_end = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(read_end, 0);
  constexpr int kBurst = 400;  // 4 KiB each: 1.6 MB
  std::vector<RecEvent> sent;
  std::string bytes;
  RecorderState s;
  {
    Recorder recorder(rec_config(dir, 1.0 / 16), rec_lcm(), {}, [&](int) { return fs::path(fifo); });
    for (int i = 0; i < kBurst; ++i) {
      sent.push_back(rec_message(i, 4000));
      rec_publish(recorder, sent.back());
    }
    EXPECT_GT(recorder.state().messages_lost, 0);
    std::thread reader([&] {  // until the recorder closes the pipe
      char buf[65536];
      for (;;) {
        const ssize_t n = ::read(read_end, buf, sizeof buf);
        if (n > 0) bytes.append(buf, static_cast<std::size_t>(n));
        if (n == 0) break;
        if (n < 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    });
    recorder.flush();  // the losses since the last message kept are marked too
    sent.push_back(rec_message(kBurst, 100));
    rec_publish(recorder, sent.back());
    recorder.stop();
    reader.join();
    s = recorder.state();
  }
  ::close(read_end);
  EXPECT_EQ(s.messages_sent, kBurst + 1);
  EXPECT_GT(s.messages_lost, 0);
  EXPECT_EQ(s.messages_sent, s.messages_written + s.messages_lost);
  EXPECT_EQ(s.bytes_lost, 4000 * s.messages_lost);
  drivers::formats::LcmLogReader reader(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  const std::vector<RecEvent> got = rec_read(reader);
  EXPECT_EQ(reader.damaged(), 0);
  // The messages kept are those sent, in order; before each that follows a loss a marker counts exactly the gap.
  std::size_t next = 0;
  std::int64_t marked = 0, written = 0, markers = 0, marked_pending = 0;
  for (const RecEvent& e : got) {
    if (e.channel == "NOISEMON_RECORD_LOSS") {
      noisemon::record_loss_t m;
      ASSERT_GE(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
      EXPECT_EQ(m.bytes, 4000 * m.messages);
      EXPECT_EQ(m.first_lost_utime, sent[next + static_cast<std::size_t>(marked_pending)].utime);
      marked_pending += m.messages;
      marked += m.messages;
      ++markers;
      continue;
    }
    const auto at = std::find(sent.begin() + static_cast<std::ptrdiff_t>(next), sent.end(), e);
    ASSERT_NE(at, sent.end()) << "an event that was not sent, or out of order";
    EXPECT_EQ(at - sent.begin() - static_cast<std::ptrdiff_t>(next), marked_pending) << "a loss without its marker";
    marked_pending = 0;
    next = static_cast<std::size_t>(at - sent.begin()) + 1;
    ++written;
  }
  EXPECT_GT(markers, 0);
  EXPECT_EQ(written, s.messages_written);
  EXPECT_EQ(marked, s.messages_lost);
  std::int64_t by_channel = 0;
  for (const auto& [channel, n] : s.lost_by_channel) by_channel += n;
  EXPECT_EQ(by_channel, s.messages_lost);
}

TEST(Recorder, RotationBySizeGivesNumberedPartsThatHoldWhatWasPublishedEachStartingWithTheSession) {
  const std::string dir = rec_fresh_dir();
  const LcmConfig lcm = rec_lcm();
  RecordConfig config = rec_config(dir);
  config.rotate_mb = 50.0 / 1024;  // 51200 bytes
  const RecEvent session{lcm.session_channel, 1'700'000'000'000'000, std::vector<std::uint8_t>(300, 5)};
  const RecEvent op{lcm.operating_point_channel, 1'700'000'000'000'001, std::vector<std::uint8_t>(60, 9)};
  std::vector<RecEvent> sent{session, op};
  {
    Recorder recorder(config, lcm);
    for (const RecEvent& e : sent) rec_publish(recorder, e);
    for (int i = 0; i < 300; ++i) {
      sent.push_back(rec_message(i, 1000));
      rec_publish(recorder, sent.back());
    }
    recorder.stop();
    EXPECT_EQ(recorder.state().messages_lost, 0);
    EXPECT_GE(recorder.state().files, 6);
  }
  const std::vector<fs::path> files = rec_files_in(dir);
  ASSERT_GE(files.size(), 6u);
  std::vector<RecEvent> joined;
  for (std::size_t k = 0; k < files.size(); ++k) {
    char part[32];
    std::snprintf(part, sizeof part, "_%03zu.lcmlog", k + 1);
    EXPECT_TRUE(files[k].filename().string().ends_with(part)) << files[k];
    EXPECT_LE(fs::file_size(files[k]), 51200u) << files[k];
    std::vector<RecEvent> events = rec_read(files[k]);
    if (k > 0) {  // each later part starts with the latest session and operating point, then its own events
      ASSERT_GE(events.size(), 3u);
      EXPECT_EQ(events[0], session);
      EXPECT_EQ(events[1], op);
      events.erase(events.begin(), events.begin() + 2);
    }
    joined.insert(joined.end(), events.begin(), events.end());
  }
  EXPECT_EQ(joined, sent);
}

TEST(Recorder, RotationByAgeStartsANewPartWithTheFirstMessageAfterTheFileIsOld) {
  const std::string dir = rec_fresh_dir();
  RecordConfig config = rec_config(dir);
  config.rotate_s = 0.05;  // the configuration file allows 1 s at the least: a test need not wait that long
  {
    Recorder recorder(config, rec_lcm());
    for (int i = 0; i < 3; ++i) {
      rec_publish(recorder, rec_message(2 * i));
      rec_publish(recorder, rec_message(2 * i + 1));
      recorder.flush();
      std::this_thread::sleep_for(std::chrono::milliseconds(60));
    }
  }
  // The first message after each pause starts a part (a stall of the writer on a loaded machine may start more).
  const std::vector<fs::path> files = rec_files_in(dir);
  ASSERT_GE(files.size(), 3u);
  std::vector<RecEvent> joined, firsts;
  for (const fs::path& f : files) {
    const std::vector<RecEvent> events = rec_read(f);
    ASSERT_FALSE(events.empty()) << f;
    firsts.push_back(events.front());
    joined.insert(joined.end(), events.begin(), events.end());
  }
  std::vector<RecEvent> sent;
  for (int i = 0; i < 6; ++i) sent.push_back(rec_message(i));
  EXPECT_EQ(joined, sent);
  for (const int i : {0, 2, 4}) EXPECT_NE(std::find(firsts.begin(), firsts.end(), sent[i]), firsts.end()) << i;
}

TEST(Recorder, AFullDiskStopsTheRecordingWithTheErrorInItsStateAndPublishingGoesOn) {
  Recorder recorder(rec_config(rec_fresh_dir()), rec_lcm(), {}, [](int) { return fs::path("/dev/full"); });
  EXPECT_TRUE(recorder.state().recording);
  // Writes reach the device once the stream's buffer is handed on: when the writer is idle, or 4 KiB on.
  for (int i = 0; i < 50; ++i) rec_publish(recorder, rec_message(i, 4000));
  const auto deadline = std::chrono::steady_clock::now() + noisemon::test::allowance(std::chrono::seconds(1));
  while (recorder.state().recording && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const RecorderState s = recorder.state();
  EXPECT_FALSE(s.recording);
  EXPECT_NE(s.error.find("/dev/full"), std::string::npos) << s.error;
  EXPECT_NE(s.error.find(std::strerror(ENOSPC)), std::string::npos) << s.error;
  EXPECT_TRUE(s.file.empty());
  for (int i = 0; i < 50; ++i) rec_publish(recorder, rec_message(i));  // returns at once, and throws nothing
  recorder.flush();
  noisemon::status_t status;
  recorder.add_status(status);
  ASSERT_EQ(status.thread_name.size(), 1u);
  EXPECT_EQ(status.thread_name[0], "record");
  EXPECT_EQ(status.thread_state[0], static_cast<std::int8_t>(noisemon::status_t::THREAD_FAILED));
  EXPECT_EQ(status.thread_error[0], s.error);
  EXPECT_TRUE(status.record_file.empty());
}

TEST(Recorder, AFolderThatCannotBeMadeIsAnErrorAtStartNamingIt) {
  const std::string file = rec_fresh_dir() + "/a-file";
  std::ofstream(file) << "not a folder";
  try {
    Recorder recorder(rec_config(file + "/records"), rec_lcm());
    FAIL() << "recorded under a file";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(file + "/records"), std::string::npos) << e.what();
  }
}

TEST(Recorder, AFileCutInsideAnEventReadsBackToItsLastWholeEvent) {
  const std::string scratch = rec_fresh_dir(), dir = scratch + "/whole";
  std::vector<RecEvent> sent;
  {
    Recorder recorder(rec_config(dir), rec_lcm());
    for (int i = 0; i < 40; ++i) {
      sent.push_back(rec_message(i));
      rec_publish(recorder, sent.back());
    }
  }
  const fs::path whole = rec_files_in(dir).at(0);
  const std::string bytes = noisemon::test::slurp(whole);
  // Where each event ends, from the sizes of those written (the log's framing: 28 bytes, channel, data).
  std::vector<std::size_t> ends;
  std::size_t at = 0;
  for (const RecEvent& e : sent) ends.push_back(at += 28 + e.channel.size() + e.data.size());
  ASSERT_EQ(ends.back(), bytes.size());
  for (const std::size_t whole_events : {std::size_t{0}, std::size_t{1}, std::size_t{17}, std::size_t{39}}) {
    const std::size_t start = whole_events == 0 ? 0 : ends[whole_events - 1];
    for (const std::size_t into : {std::size_t{3}, std::size_t{20}, std::size_t{30}, sent[whole_events].data.size()}) {
      const fs::path cut = fs::path(scratch) / "cut.lcmlog";
      std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(start + into));
      const std::vector<RecEvent> want(sent.begin(), sent.begin() + static_cast<std::ptrdiff_t>(whole_events));
      drivers::formats::LcmLogReader reader(cut);
      EXPECT_EQ(rec_read(reader), want) << whole_events << " whole events and " << into << " bytes";
      EXPECT_TRUE(reader.truncated());
      EXPECT_EQ(rec_read_with_lcm(cut), want) << whole_events << " whole events and " << into << " bytes";
    }
  }
}

}  // namespace noisemon::daemon
