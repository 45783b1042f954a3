#include "cli/config_edit.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <vector>

namespace noisemon::cli {
namespace {

std::vector<std::string> split_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = text.find('\n', start);
    lines.push_back(text.substr(start, end == std::string::npos ? std::string::npos : end - start));
    start = end == std::string::npos ? text.size() : end + 1;
  }
  return lines;
}

std::string trimmed(const std::string& s) {
  const std::size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r") - a + 1);
}

bool is_header(const std::string& line) { return trimmed(line).starts_with("["); }
bool is_header_of(const std::string& line, const std::string& table) {
  const std::string t = trimmed(line);
  return t.starts_with("[" + table + "]") && !t.starts_with("[[");
}

// `key = ...` at the start of the line (spaces aside).
bool assigns(const std::string& line, const std::string& key) {
  const std::string t = trimmed(line);
  if (!t.starts_with(key)) return false;
  const std::string rest = trimmed(t.substr(key.size()));
  return rest.starts_with("=");
}

// Where a value's comment starts on its last line ('#' outside a string), or npos.
std::size_t comment_at(const std::string& line) {
  bool in_string = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '"') in_string = !in_string;
    if (line[i] == '#' && !in_string) return i;
  }
  return std::string::npos;
}

// The last line of the value starting on `first` (an array runs until its brackets balance).
std::size_t value_end(const std::vector<std::string>& lines, std::size_t first) {
  int depth = 0;
  for (std::size_t i = first; i < lines.size(); ++i) {
    const std::string& l = lines[i];
    const std::size_t from = i == first ? l.find('=') + 1 : 0;
    for (std::size_t k = from; k < std::min(l.size(), comment_at(l)); ++k)
      depth += l[k] == '[' ? 1 : l[k] == ']' ? -1 : 0;
    if (depth <= 0) return i;
  }
  return lines.size() - 1;
}

}  // namespace

std::string set_toml_value(const std::string& text, const std::string& table, const std::string& key,
                           const std::string& value_text) {
  std::vector<std::string> lines = split_lines(text);
  const std::string assignment = key + " = " + value_text;
  std::size_t header = lines.size();
  for (std::size_t i = 0; i < lines.size() && header == lines.size(); ++i)
    if (is_header_of(lines[i], table)) header = i;
  if (header == lines.size()) {
    lines.push_back("");
    lines.push_back("[" + table + "]");
    lines.push_back(assignment);
  } else {
    std::size_t i = header + 1;
    while (i < lines.size() && !is_header(lines[i]) && !assigns(lines[i], key)) ++i;
    if (i == lines.size() || is_header(lines[i])) {
      lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(header) + 1, assignment);
    } else {
      const std::size_t last = value_end(lines, i);
      const std::size_t comment = comment_at(lines[last]);
      const std::string indent = lines[i].substr(0, lines[i].find_first_not_of(" \t"));
      std::string replaced = indent + assignment;
      if (comment != std::string::npos) replaced += "  " + lines[last].substr(comment);
      lines.erase(lines.begin() + static_cast<std::ptrdiff_t>(i) + 1,
                  lines.begin() + static_cast<std::ptrdiff_t>(last) + 1);
      lines[i] = replaced;
    }
  }
  std::string out;
  for (const std::string& l : lines) out += l + "\n";
  return out;
}

void edit_config_file(const std::string& path, const std::vector<TomlEdit>& edits,
                      const std::function<bool(const daemon::Config&)>& holds) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  for (const TomlEdit& e : edits) text = set_toml_value(text, e.table, e.key, e.value_text);
  if (!holds(daemon::parse_config(text, path)))
    throw std::logic_error("the edited configuration " + path + " does not hold the new values; nothing written");
  replace_file_atomically(path, text);
}

void replace_file_atomically(const std::string& path, const std::string& text) {
  const std::string temp = path + ".new";
  struct stat st {};
  const mode_t mode = ::stat(path.c_str(), &st) == 0 ? st.st_mode & 07777 : 0644;
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
  if (fd < 0) throw std::runtime_error("cannot write " + temp + ": " + std::strerror(errno));
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int err = errno;
      ::close(fd);
      ::unlink(temp.c_str());
      throw std::runtime_error("cannot write " + temp + ": " + std::strerror(err));
    }
    done += static_cast<std::size_t>(n);
  }
  const bool synced = ::fsync(fd) == 0;
  const bool closed = ::close(fd) == 0;
  if (!synced || !closed || ::rename(temp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(temp.c_str());
    throw std::runtime_error("cannot replace " + path + ": " + std::strerror(err));
  }
}

}  // namespace noisemon::cli
