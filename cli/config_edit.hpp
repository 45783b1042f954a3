// Changing one value of a configuration file the way a person would: that line alone, its comment and every other
// line kept, the file replaced atomically. For `noisemon calibrate`, which writes the sensitivities (and the pressure
// chain's zero) it measures.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "daemon/config.hpp"

namespace noisemon::cli {

// `text` with `key = value_text` in table `table` (a [table] header): the key's value replaced (an array may span
// lines), its trailing comment kept; the key added under the header when the table lacks it; the table appended
// when the text lacks it.
std::string set_toml_value(const std::string& text, const std::string& table, const std::string& key,
                           const std::string& value_text);

// One value to set: `key = value_text` in [table].
struct TomlEdit {
  std::string table, key, value_text;
};

// The configuration file `path` with each edit made (set_toml_value), written only when the daemon can read the
// result and `holds` finds the new values in it (never a file the daemon cannot read): replace_file_atomically.
// Throws, writing nothing, otherwise.
void edit_config_file(const std::string& path, const std::vector<TomlEdit>& edits,
                      const std::function<bool(const daemon::Config&)>& holds);

// Writes `text` to a temporary file beside `path`, flushes it to the disk and renames it over `path` (keeping the
// file's permissions): a reader sees the old file or the new one, never half of one. Throws naming the path.
void replace_file_atomically(const std::string& path, const std::string& text);

}  // namespace noisemon::cli
