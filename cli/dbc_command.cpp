#include "cli/dbc_command.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cctype>
#include <cstdio>

#include "cli/cli_support.hpp"
#include "drivers/formats/dbc.hpp"

namespace noisemon::cli {
namespace {

using drivers::formats::CanByteOrder;
using drivers::formats::DbcMessage;
using drivers::formats::DbcSignal;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// "0x0CF004FE ext" or "0x1F0", with the PGN of a J1939 group.
std::string id_text(const DbcMessage& m) {
  char text[64];
  if (!m.j1939) {
    std::snprintf(text, sizeof text, m.extended ? "0x%08X ext" : "0x%03X", m.id);
  } else {
    const std::uint32_t pgn = (m.id & drivers::formats::j1939_pgn_mask(m.id)) >> 8;
    std::snprintf(text, sizeof text, "0x%08X ext, J1939 PGN 0x%04X (%u)", m.id, pgn, pgn);
  }
  return text;
}

std::string mux_text(const DbcSignal& s) {
  std::string t = s.multiplexor ? " multiplexor" : "";
  if (!s.multiplexed) return t;
  t += " when " + (s.mux_switch.empty() ? std::string("the multiplexor") : s.mux_switch) + " is ";
  if (s.mux_ranges.empty()) return t + std::to_string(s.mux_value);
  for (std::size_t i = 0; i < s.mux_ranges.size(); ++i) {
    const auto [low, high] = s.mux_ranges[i];
    t += (i ? "," : "") + std::to_string(low) + (high != low ? "-" + std::to_string(high) : "");
  }
  return t;
}

void print_signal(const DbcSignal& s) {
  std::printf("  %-32s %2u|%-2u %-8s %-8s x %-10g + %-8g [%s]%s%s\n", s.name.c_str(), s.start_bit, s.length,
              s.byte_order == CanByteOrder::kIntel ? "intel" : "motorola", s.is_signed ? "signed" : "unsigned",
              s.factor, s.offset, s.unit.c_str(), mux_text(s).c_str(),
              s.float_bits ? (" IEEE float" + std::to_string(s.float_bits) + ": not decoded").c_str() : "");
}

}  // namespace

DbcCommand::DbcCommand(CLI::App& app) {
  dbc_ = app.add_subcommand("dbc",
                            "list the messages and signals of a DBC file as the CAN signal map reads them: the "
                            "names for [[can.signal]] dbc_signal");
  dbc_->add_option("FILE", path_, "the DBC file")->required()->check(CLI::ExistingFile);
  dbc_->add_option("--grep", grep_, "only signals (or messages) whose name holds this text, any case");
  dbc_->footer("\nExamples:\n  noisemon dbc engine.dbc\n  noisemon dbc engine.dbc --grep speed\n");
}

int DbcCommand::run() {
  if (!dbc_->parsed()) return -1;
  return exit_status_of("dbc", [&] {
    const drivers::formats::DbcFile file = drivers::formats::read_dbc(path_);
    const std::string wanted = lower(grep_);
    std::size_t messages = 0, signals = 0;
    for (const DbcMessage& m : file.messages) {
      const bool message_matches = lower(m.name).find(wanted) != std::string::npos;
      std::vector<const DbcSignal*> shown;
      for (const DbcSignal& s : m.signals)
        if (message_matches || lower(s.name).find(wanted) != std::string::npos) shown.push_back(&s);
      if (shown.empty()) continue;
      ++messages;
      signals += shown.size();
      std::printf("%s  %s  %u bytes\n", m.name.c_str(), id_text(m).c_str(), m.dlc);
      for (const DbcSignal* s : shown) print_signal(*s);
    }
    std::printf("%zu messages, %zu signals%s\n", messages, signals,
                grep_.empty() ? "" : (" with '" + grep_ + "'").c_str());
  });
}

}  // namespace noisemon::cli
