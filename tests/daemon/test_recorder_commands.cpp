// The recorder's commands (record start NAME, stop, mark) in-process: each takes effect between the very messages it
// was given between, in the file a reader sees: a start begins a file of its test point with the session and
// operating point published before it (a part replays on its own), a stop ends it, and messages between recordings
// go nowhere; each is acknowledged once to the sink and, where a file is open, in the file at its place.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "daemon/recorder.hpp"
#include "drivers/formats/lcm_log_reader.hpp"
#include "noisemon/command_ack_t.hpp"
#include "tests/support/unique_temp.hpp"

namespace noisemon::daemon {
namespace {

namespace fs = std::filesystem;

struct CmdEvent {
  std::string channel;
  std::int64_t utime = 0;
  std::vector<std::uint8_t> data;
};

// Message i on a channel of its own kind: the session every 50th, otherwise a raw block; its bytes say i.
CmdEvent cmd_message(const LcmConfig& lcm, int i) {
  CmdEvent e{i % 50 == 0 ? lcm.session_channel : lcm.raw_channel, 1'700'000'000'000'000 + 25 * i, {}};
  e.data.assign(16, static_cast<std::uint8_t>(i));
  e.data[1] = static_cast<std::uint8_t>(i >> 8);
  return e;
}

std::vector<CmdEvent> cmd_read(const fs::path& file) {
  drivers::formats::LcmLogReader reader(file);
  std::vector<CmdEvent> out;
  drivers::formats::LcmLogEvent e;
  while (reader.next(e))
    out.push_back({std::string(e.channel), e.timestamp, std::vector<std::uint8_t>(e.data, e.data + e.datalen)});
  return out;
}

int cmd_index(const CmdEvent& e) { return e.data[0] + 256 * e.data[1]; }

noisemon::command_ack_t cmd_ack(const CmdEvent& e) {
  noisemon::command_ack_t a;
  EXPECT_GE(a.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
  return a;
}

struct Acks {
  std::mutex mutex;
  std::vector<noisemon::command_ack_t> got;
  void add(const noisemon::command_ack_t& a) {
    std::lock_guard lock(mutex);
    got.push_back(a);
  }
};

}  // namespace

TEST(RecorderCommands, StartStopAndMarkTakeEffectBetweenTheMessagesTheyWereGivenBetween) {
  const std::string dir = noisemon::test::unique_temp_dir() + "/by-command";
  fs::remove_all(dir);
  LcmConfig lcm;
  set_cell(lcm, "c3");
  RecordConfig config;
  config.enabled = true;
  config.autostart = false;
  config.dir = dir;
  Acks acks;
  {
    Recorder recorder(config, lcm);
    recorder.set_ack_sink([&](const noisemon::command_ack_t& a) { acks.add(a); });
    const auto publish = [&](int from, int to) {
      for (int i = from; i < to; ++i) {
        const CmdEvent e = cmd_message(lcm, i);
        recorder.publish_bytes(e.channel, e.data.data(), e.data.size(), e.utime);
      }
    };
    publish(0, 120);  // no recording yet: nowhere, but the session of message 100 is kept
    recorder.request({CommandVerb::kRecordStart, "id-1", "idle-1800", ""});
    publish(120, 200);
    recorder.request({CommandVerb::kMark, "id-2", "", "door opened"});
    publish(200, 260);
    recorder.request({CommandVerb::kRecordStop, "id-3", "", ""});
    publish(260, 320);  // between recordings: nowhere
    recorder.request({CommandVerb::kRecordStart, "id-4", "full-load", ""});
    publish(320, 340);
    recorder.request({CommandVerb::kRecordStart, "id-5", "bad/name", ""});  // refused at once
    recorder.stop();
    EXPECT_EQ(recorder.state().messages_sent, 160);
    EXPECT_EQ(recorder.state().messages_lost, 0);
  }

  std::vector<fs::path> files;
  for (const auto& f : fs::directory_iterator(dir)) files.push_back(f.path());
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
    return a.filename().string().find("idle") != std::string::npos &&
           b.filename().string().find("idle") == std::string::npos;
  });
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[0].filename().string().rfind("c3_idle-1800_", 0), 0u) << files[0];
  EXPECT_EQ(files[1].filename().string().rfind("c3_full-load_", 0), 0u) << files[1];

  // The first recording: the kept session (message 100), the start's acknowledgement, 120..199, the mark, 200..259,
  // the stop's acknowledgement.
  const std::vector<CmdEvent> first = cmd_read(files[0]);
  ASSERT_EQ(first.size(), 1u + 1 + 80 + 1 + 60 + 1);
  EXPECT_EQ(first[0].channel, lcm.session_channel);
  EXPECT_EQ(cmd_index(first[0]), 100);
  ASSERT_EQ(first[1].channel, lcm.command_ack_channel);
  EXPECT_EQ(cmd_ack(first[1]).id, "id-1");
  for (int i = 120; i < 200; ++i) EXPECT_EQ(cmd_index(first[static_cast<std::size_t>(i - 118)]), i);
  const noisemon::command_ack_t mark = cmd_ack(first[82]);
  EXPECT_EQ(first[82].channel, lcm.command_ack_channel);
  EXPECT_EQ(mark.verb, "mark");
  EXPECT_EQ(mark.text, "door opened");
  for (int i = 200; i < 260; ++i) EXPECT_EQ(cmd_index(first[static_cast<std::size_t>(i - 117)]), i);
  EXPECT_EQ(cmd_ack(first.back()).verb, "record_stop");

  // The second: the session of message 300 (between the recordings), its start, 320..339.
  const std::vector<CmdEvent> second = cmd_read(files[1]);
  ASSERT_EQ(second.size(), 1u + 1 + 20);
  EXPECT_EQ(cmd_index(second[0]), 300);
  EXPECT_EQ(cmd_ack(second[1]).test_point, "full-load");
  EXPECT_EQ(cmd_index(second.back()), 339);

  // Each acknowledged once: the writer's in the order given; the bad name refused at once, whenever the writer got
  // to the others.
  std::lock_guard lock(acks.mutex);
  ASSERT_EQ(acks.got.size(), 5u);
  std::vector<noisemon::command_ack_t> carried_out;
  for (const auto& a : acks.got) {
    EXPECT_EQ(a.ok, a.id != "id-5") << a.id << ": " << a.message;
    if (a.id != "id-5") carried_out.push_back(a);
  }
  ASSERT_EQ(carried_out.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(carried_out[k].id, "id-" + std::to_string(k + 1));
  EXPECT_EQ(carried_out[0].file, files[0].string());
  EXPECT_EQ(carried_out[2].file, files[0].string());  // the stop names the file it closed
  EXPECT_EQ(carried_out[3].file, files[1].string());
  const auto refused = std::find_if(acks.got.begin(), acks.got.end(), [](const auto& a) { return a.id == "id-5"; });
  EXPECT_NE(refused->message.find("bad/name"), std::string::npos) << refused->message;
}

}  // namespace noisemon::daemon
