// The one line splitter of the text formats: lines ended by "\n" or "\r\n" (a Windows file reads as a Unix one),
// the last one with or without an end, numbered from 1 for error messages.
#pragma once

#include <cstddef>
#include <string_view>

namespace noisemon::drivers::formats {

class TextLines {
 public:
  explicit TextLines(std::string_view text) : text_(text) {}

  // The next line without its end; false once every line has been given.
  [[nodiscard]] bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    std::size_t eol = text_.find('\n', pos_);
    if (eol == std::string_view::npos) eol = text_.size();
    line = text_.substr(pos_, eol - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = eol + 1;
    ++number_;
    return true;
  }
  // The number of the line next() gave last (1-based; 0 before the first).
  [[nodiscard]] std::size_t number() const { return number_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t number_ = 0;
};

}  // namespace noisemon::drivers::formats
