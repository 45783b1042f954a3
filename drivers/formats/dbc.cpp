#include "drivers/formats/dbc.hpp"

#include <cctype>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace noisemon::drivers::formats {
namespace {

constexpr std::uint32_t kExtendedFlag = 0x80000000U;  // bit 31 of a DBC message id: a 29-bit identifier
constexpr std::uint32_t kIdMask = 0x1FFFFFFFU;
constexpr int kMaxMuxDepth = 8;
constexpr std::uint32_t kPdu1PgnMask = 0x03FF0000U;  // without priority, destination and source address
constexpr std::uint32_t kPdu2PgnMask = 0x03FFFF00U;  // without priority and source address

// Reads the tokens of one DBC statement; every failure names the file and line.
class Cursor {
 public:
  Cursor(const std::string& line, std::string where) : s_(line), where_(std::move(where)) {}

  void skip_space() {
    while (p_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[p_]))) ++p_;
  }
  bool at(char c) {
    skip_space();
    return p_ < s_.size() && s_[p_] == c;
  }
  void expect(char c, const char* what) {
    if (!at(c)) fail(std::string("expected '") + c + "' " + what);
    ++p_;
  }
  std::string word(const char* what) {  // an identifier, or a token up to a space or ':'
    skip_space();
    const std::size_t from = p_;
    while (p_ < s_.size() && !std::isspace(static_cast<unsigned char>(s_[p_])) && s_[p_] != ':' && s_[p_] != ';' &&
           s_[p_] != ',')
      ++p_;
    if (p_ == from) fail(std::string("expected ") + what);
    return s_.substr(from, p_ - from);
  }
  std::uint64_t unsigned_number(const char* what) {
    skip_space();
    const char* begin = s_.c_str() + p_;
    char* end = nullptr;
    const unsigned long long v = std::strtoull(begin, &end, 10);
    if (end == begin || *begin == '-') fail(std::string("expected ") + what + " (an unsigned integer)");
    p_ += static_cast<std::size_t>(end - begin);
    return v;
  }
  double number(const char* what) {
    skip_space();
    const char* begin = s_.c_str() + p_;
    char* end = nullptr;
    const double v = std::strtod(begin, &end);
    if (end == begin) fail(std::string("expected ") + what + " (a number)");
    p_ += static_cast<std::size_t>(end - begin);
    return v;
  }
  std::string quoted(const char* what) {
    expect('"', what);
    const std::size_t close = s_.find('"', p_);
    if (close == std::string::npos) fail(std::string("unterminated ") + what);
    std::string v = s_.substr(p_, close - p_);
    p_ = close + 1;
    return v;
  }
  bool at_end() {
    skip_space();
    return p_ >= s_.size();
  }
  char next_char(const char* what) {
    skip_space();
    if (p_ >= s_.size()) fail(std::string("expected ") + what);
    return s_[p_++];
  }
  [[noreturn]] void fail(const std::string& what) const { throw std::runtime_error(where_ + ": " + what); }

 private:
  const std::string& s_;
  std::string where_;
  std::size_t p_ = 0;
};

// "M", "mN" or "mNM".
void parse_mux_indicator(const std::string& token, DbcSignal& s, Cursor& c) {
  if (token == "M") {
    s.multiplexor = true;
    return;
  }
  if (token.size() < 2 || token[0] != 'm') c.fail("multiplex indicator '" + token + "' (expected M, mN or mNM)");
  std::size_t digits = 1;
  while (digits < token.size() && std::isdigit(static_cast<unsigned char>(token[digits]))) ++digits;
  const std::string rest = token.substr(digits);
  if (digits == 1 || !(rest.empty() || rest == "M"))
    c.fail("multiplex indicator '" + token + "' (expected M, mN or mNM)");
  s.multiplexed = true;
  s.multiplexor = rest == "M";
  s.mux_value = std::strtoull(token.c_str() + 1, nullptr, 10);
}

// SG_ name [M|mN|mNM] : start|length@order sign (factor,offset) [min|max] "unit" receivers
DbcSignal parse_signal(Cursor& c, int line) {
  DbcSignal s;
  s.line = line;
  s.name = c.word("the signal's name");
  if (!c.at(':')) parse_mux_indicator(c.word("a multiplex indicator"), s, c);
  c.expect(':', "after the signal's name");
  s.start_bit = static_cast<std::uint32_t>(c.unsigned_number("the start bit"));
  c.expect('|', "between start bit and length");
  s.length = static_cast<std::uint32_t>(c.unsigned_number("the length"));
  c.expect('@', "before the byte order");
  const char order = c.next_char("the byte order (0 or 1)");
  if (order != '0' && order != '1') c.fail(std::string("byte order '") + order + "' (expected 0 Motorola or 1 Intel)");
  s.byte_order = order == '1' ? CanByteOrder::kIntel : CanByteOrder::kMotorola;
  const char sign = c.next_char("the sign (+ or -)");
  if (sign != '+' && sign != '-') c.fail(std::string("sign '") + sign + "' (expected + or -)");
  s.is_signed = sign == '-';
  c.expect('(', "before the factor");
  s.factor = c.number("the factor");
  c.expect(',', "between factor and offset");
  s.offset = c.number("the offset");
  c.expect(')', "after the offset");
  c.expect('[', "before the minimum");
  s.minimum = c.number("the minimum");
  c.expect('|', "between minimum and maximum");
  s.maximum = c.number("the maximum");
  c.expect(']', "after the maximum");
  s.unit = c.quoted("unit");
  if (s.length < 1 || s.length > 64) c.fail("signal '" + s.name + "': length " + std::to_string(s.length));
  if (s.start_bit > 63) c.fail("signal '" + s.name + "': start bit " + std::to_string(s.start_bit));
  return s;
}

// The id as the file writes it: bit 31 set for a 29-bit id.
std::uint64_t raw_id(const DbcMessage& m) { return m.id | (m.extended ? kExtendedFlag : 0U); }

DbcMessage* message_by_raw_id(std::vector<DbcMessage>& messages, std::uint64_t raw) {
  for (DbcMessage& m : messages)
    if (raw_id(m) == raw) return &m;
  return nullptr;
}

DbcSignal& signal_of(std::vector<DbcMessage>& messages, std::uint64_t raw, const std::string& name, Cursor& c) {
  DbcMessage* m = message_by_raw_id(messages, raw);
  if (!m) c.fail("no message with id " + std::to_string(raw));
  for (DbcSignal& s : m->signals)
    if (s.name == name) return s;
  c.fail("message " + m->name + " has no signal '" + name + "'");
}

// SG_MUL_VAL_ id signal multiplexor a-b, c-d ;
void parse_mux_values(Cursor& c, std::vector<DbcMessage>& messages) {
  const std::uint64_t id = c.unsigned_number("the message id");
  DbcSignal& s = signal_of(messages, id, c.word("the signal's name"), c);
  s.mux_switch = c.word("the multiplexor's name");
  s.mux_ranges.clear();
  while (!c.at(';')) {
    const std::uint64_t low = c.unsigned_number("a range's low value");
    c.expect('-', "inside a range");
    const std::uint64_t high = c.unsigned_number("a range's high value");
    if (high < low) c.fail("range " + std::to_string(low) + "-" + std::to_string(high) + " runs backwards");
    s.mux_ranges.emplace_back(low, high);
    if (c.at(',')) c.expect(',', "between ranges");
  }
}

// SIG_VALTYPE_ id signal : 1|2 ;
void parse_value_type(Cursor& c, std::vector<DbcMessage>& messages) {
  const std::uint64_t id = c.unsigned_number("the message id");
  DbcSignal& s = signal_of(messages, id, c.word("the signal's name"), c);
  c.expect(':', "before the value type");
  const std::uint64_t type = c.unsigned_number("the value type");
  if (type > 2) c.fail("value type " + std::to_string(type) + " (expected 0 integer, 1 float or 2 double)");
  s.float_bits = type == 1 ? 32 : type == 2 ? 64 : 0;
}

// The VFrameFormat attribute (Vector's): its enum's names, its default, each message's value (raw id, index).
struct FrameFormats {
  std::vector<std::string> names;
  std::string default_name;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> by_id;
};

// BA_DEF_ [BO_] "name" type ...; BA_DEF_DEF_ "name" value; BA_ "name" [BO_ id] value: only VFrameFormat is kept.
void parse_attribute(const std::string& keyword, Cursor& c, FrameFormats& formats) {
  if (keyword == "BA_DEF_") {
    const std::string object = c.at('"') ? std::string() : c.word("the attribute's object type");
    if (object != "BO_" || c.quoted("attribute name") != "VFrameFormat" || c.word("the attribute's type") != "ENUM")
      return;
    formats.names.clear();
    while (c.at('"')) {
      formats.names.push_back(c.quoted("enum value"));
      if (c.at(',')) c.expect(',', "between enum values");
    }
  } else if (keyword == "BA_DEF_DEF_") {
    if (c.quoted("attribute name") == "VFrameFormat" && c.at('"')) formats.default_name = c.quoted("default value");
  } else if (keyword == "BA_") {
    if (c.quoted("attribute name") != "VFrameFormat" || c.word("the attribute's object type") != "BO_") return;
    const std::uint64_t id = c.unsigned_number("the message id");
    formats.by_id.emplace_back(id, c.unsigned_number("the frame format's index"));
  }
}

// A J1939 parameter group: a 29-bit id whose VFrameFormat (its own, else the default) is J1939PG.
void mark_j1939(std::vector<DbcMessage>& messages, const FrameFormats& formats) {
  for (DbcMessage& m : messages) {
    std::string format = formats.default_name;
    for (const auto& [id, index] : formats.by_id)
      if (id == raw_id(m)) format = index < formats.names.size() ? formats.names[index] : std::string();
    m.j1939 = m.extended && format == "J1939PG";
  }
}

// One statement: BO_ starts a message, SG_ adds to it; the rest of the file's keywords are skipped.
void parse_statement(const std::string& line, const std::string& where, int number, DbcFile& f, FrameFormats& formats) {
  Cursor c(line, where);
  const std::string keyword = c.word("a keyword");
  if (c.at_end()) return;  // a keyword alone: the NS_ section's list of the keywords the file may use
  if (keyword == "BO_") {
    DbcMessage m;
    const std::uint64_t raw = c.unsigned_number("the message id");
    if (raw > 0xFFFFFFFFULL) c.fail("message id " + std::to_string(raw) + " exceeds 32 bits");
    m.extended = (raw & kExtendedFlag) != 0;
    m.id = static_cast<std::uint32_t>(raw) & (m.extended ? kIdMask : 0xFFFFFFFFU);
    m.name = c.word("the message's name");
    c.expect(':', "after the message's name");
    m.dlc = static_cast<std::uint32_t>(c.unsigned_number("the message's length"));
    f.messages.push_back(std::move(m));
  } else if (keyword == "SG_") {
    if (f.messages.empty()) c.fail("SG_ before any BO_");
    f.messages.back().signals.push_back(parse_signal(c, number));
  } else if (keyword == "SG_MUL_VAL_") {
    parse_mux_values(c, f.messages);
  } else if (keyword == "SIG_VALTYPE_") {
    parse_value_type(c, f.messages);
  } else if (keyword == "BA_DEF_" || keyword == "BA_DEF_DEF_" || keyword == "BA_") {
    try {
      parse_attribute(keyword, c, formats);
    } catch (const std::runtime_error&) {
      // An attribute written some other way: attributes are descriptions, and without the frame format the
      // message's whole id is matched.
    }
  }
}

// Whether a statement leaves a quoted string open (a comment running over several lines).
bool toggles_quote(const std::string& line, bool open) {
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '\\' && open) {
      ++i;
      continue;
    }
    if (line[i] == '"') open = !open;
  }
  return open;
}

const DbcSignal* the_multiplexor(const DbcMessage& m, const std::string& origin) {
  const DbcSignal* found = nullptr;
  for (const DbcSignal& s : m.signals) {
    if (!s.multiplexor || s.multiplexed) continue;
    if (found)
      throw std::invalid_argument(origin + ": message " + m.name +
                                  " has several multiplexors and no SG_MUL_VAL_ says which a signal depends on");
    found = &s;
  }
  return found;
}

// The multiplexors a signal depends on, its own first, then theirs (cascaded multiplexing).
void add_multiplexors(const DbcMessage& m, const DbcSignal& s, std::vector<CanMuxCondition>& out,
                      const std::string& origin, int depth) {
  if (!s.multiplexed) return;
  if (depth > kMaxMuxDepth)
    throw std::invalid_argument(origin + ": the multiplexing of " + m.name + " nests deeper than " +
                                std::to_string(kMaxMuxDepth) + " levels (a loop?)");
  const DbcSignal* mux = s.mux_switch.empty() ? the_multiplexor(m, origin) : m.signal(s.mux_switch);
  if (!mux)
    throw std::invalid_argument(origin + ": signal " + s.name + " of " + m.name + " is multiplexed by " +
                                (s.mux_switch.empty() ? "a multiplexor (M) the message does not have"
                                                      : "'" + s.mux_switch + "', which the message does not have"));
  CanMuxCondition c;
  c.start_bit = mux->start_bit;
  c.length = mux->length;
  c.byte_order = mux->byte_order;
  c.ranges = s.mux_ranges.empty() ? std::vector<std::pair<std::uint64_t, std::uint64_t>>{{s.mux_value, s.mux_value}}
                                  : s.mux_ranges;
  out.push_back(std::move(c));
  add_multiplexors(m, *mux, out, origin, depth + 1);
}

}  // namespace

std::uint32_t j1939_pgn_mask(std::uint32_t id) {
  const std::uint32_t pdu_format = (id >> 16) & 0xFFU;
  return pdu_format < 240 ? kPdu1PgnMask : kPdu2PgnMask;
}

const DbcSignal* DbcMessage::signal(const std::string& wanted) const {
  for (const DbcSignal& s : signals)
    if (s.name == wanted) return &s;
  return nullptr;
}

DbcFile parse_dbc(const std::string& text, const std::string& origin) {
  DbcFile f;
  f.path = origin;
  std::istringstream in(text);
  std::string line;
  bool in_quote = false;
  FrameFormats formats;
  for (int number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const bool starts_in_quote = in_quote;
    in_quote = toggles_quote(line, in_quote);
    if (starts_in_quote || line.find_first_not_of(" \t") == std::string::npos) continue;
    parse_statement(line, origin + ":" + std::to_string(number), number, f, formats);
  }
  mark_j1939(f.messages, formats);
  return f;
}

DbcFile read_dbc(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot read the DBC file");
  std::ostringstream text;
  text << in.rdbuf();
  DbcFile f = parse_dbc(text.str(), path.string());
  if (f.messages.empty()) throw std::runtime_error(path.string() + ": no messages (BO_): not a DBC file?");
  return f;
}

CanSignal DbcFile::can_signal(const std::string& name, const std::string& message, OperatingPointField field) const {
  const std::string origin = path.string();
  const DbcMessage* owner = nullptr;
  std::string owners;
  bool message_seen = message.empty();
  for (const DbcMessage& m : messages) {
    if (!message.empty() && m.name != message) continue;
    message_seen = true;
    if (!m.signal(name)) continue;
    owners += (owners.empty() ? "" : ", ") + m.name;
    if (owner)
      throw std::invalid_argument(origin + ": signal '" + name + "' is in several messages (" + owners +
                                  "...): name one with dbc_message");
    owner = &m;
  }
  if (!message_seen) throw std::invalid_argument(origin + ": no message '" + message + "'");
  if (!owner)
    throw std::invalid_argument(origin + ": no signal '" + name + "'" +
                                (message.empty() ? std::string(" in any message") : " in message " + message));
  const DbcSignal& d = *owner->signal(name);
  if (d.float_bits != 0)
    throw std::invalid_argument(origin + ":" + std::to_string(d.line) + ": signal '" + name + "' is an IEEE float" +
                                std::to_string(d.float_bits) + " (SIG_VALTYPE_), which the map does not decode");
  CanSignal s;
  s.field = field;
  s.id = owner->id;
  s.extended = owner->extended;
  s.start_bit = d.start_bit;
  s.length = d.length;
  s.byte_order = d.byte_order;
  s.is_signed = d.is_signed;
  s.factor = d.factor;
  s.offset = d.offset;
  s.unit = d.unit;
  add_multiplexors(*owner, d, s.multiplexors, origin, 0);
  if (owner->j1939) s.id_mask = j1939_pgn_mask(owner->id);
  return s;
}

}  // namespace noisemon::drivers::formats
