// The test bed's commands to the daemon (command_t on [lcm] command_channel: `noisemon record`, the dashboard): the
// verbs as the bus spells them, declared once here for the daemon that carries them out and the tools that send them.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace noisemon::daemon {

enum class CommandVerb : std::uint8_t { kRecordStart, kRecordStop, kMark };

inline constexpr std::array<std::pair<std::string_view, CommandVerb>, 3> kCommandVerbs{
    {{"record_start", CommandVerb::kRecordStart},
     {"record_stop", CommandVerb::kRecordStop},
     {"mark", CommandVerb::kMark}}};

[[nodiscard]] inline std::optional<CommandVerb> command_verb(std::string_view name) {
  for (const auto& [n, v] : kCommandVerbs)
    if (n == name) return v;
  return std::nullopt;
}

[[nodiscard]] inline std::string_view command_verb_name(CommandVerb verb) {
  for (const auto& [n, v] : kCommandVerbs)
    if (v == verb) return n;
  return "?";
}

// One command as the recorder takes it: start (a new recording of test_point), stop, or mark (text).
struct RecorderRequest {
  CommandVerb verb = CommandVerb::kMark;
  std::string id, test_point, text;
};

}  // namespace noisemon::daemon
