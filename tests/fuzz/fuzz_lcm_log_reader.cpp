// libFuzzer target: the tolerant LCM log reader (drivers::formats::LcmLogReader) on arbitrary bytes, from a buffer and
// from a file. Every byte must be accounted for, either inside a well-framed event or in a counted damaged
// stretch, and both ways of reading must agree.
#include <cstring>
#include <vector>

#include "drivers/formats/lcm_log_reader.hpp"
#include "fuzz_util.hpp"

using noisemon::drivers::formats::LcmLogEvent;
using noisemon::drivers::formats::LcmLogReader;
using noisemon::fuzz::fail;

namespace {

constexpr std::size_t kHeader = 4 + 8 + 8 + 4 + 4;  // sync, event number, timestamp, two lengths

std::vector<LcmLogEvent> read_all(LcmLogReader& r, const std::uint8_t* base, std::size_t size) {
  static const std::uint8_t sync[4] = {0xED, 0xA1, 0xDA, 0x01};
  std::vector<LcmLogEvent> events;
  std::uint64_t event_bytes = 0;
  LcmLogEvent e;
  while (r.next(e)) {
    if (!events.empty() && e.offset < events.back().offset + kHeader) fail("events overlap or go backwards");
    if (e.channel.empty() || e.datalen < 0) fail("empty channel or negative length");
    const std::size_t end = e.offset + kHeader + e.channel.size() + static_cast<std::size_t>(e.datalen);
    if (end > size || r.position() != end) fail("event runs past the log or position() is off");
    if (std::memcmp(base + e.offset, sync, 4) != 0) fail("event does not start at a sync word");
    if (reinterpret_cast<const std::uint8_t*>(e.channel.data()) != base + e.offset + kHeader ||
        e.data != base + e.offset + kHeader + e.channel.size())
      fail("views do not point at the event's channel and data");
    event_bytes += end - e.offset;
    events.push_back(e);
  }
  if (r.next(e)) fail("an event after the end");
  if (r.position() != size || event_bytes + r.damaged_bytes() != size)
    fail("bytes neither in an event nor counted damaged");
  if ((r.damaged() > 0) != (r.damaged_bytes() > 0)) fail("damage count and damaged bytes disagree");
  return events;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  LcmLogReader from_buffer(data, size);
  const std::vector<LcmLogEvent> a = read_all(from_buffer, data, size);

  const auto path = noisemon::fuzz::scratch_dir() / "input.lcmlog";
  noisemon::fuzz::write_file(path, data, size);
  LcmLogReader from_file(path);
  LcmLogEvent e;
  std::size_t n = 0;
  while (from_file.next(e)) {
    if (n >= a.size() || e.offset != a[n].offset || e.eventnum != a[n].eventnum || e.timestamp != a[n].timestamp ||
        e.channel != a[n].channel || e.datalen != a[n].datalen || std::memcmp(e.data, a[n].data, e.datalen) != 0)
      fail("file and buffer readings differ");
    ++n;
  }
  if (n != a.size() || from_file.damaged() != from_buffer.damaged() || from_file.truncated() != from_buffer.truncated())
    fail("file and buffer readings differ in counts");
  return 0;
}
