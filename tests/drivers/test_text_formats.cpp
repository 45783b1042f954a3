// The formats' one line splitter (TextLines): Unix and Windows line ends give the same lines, numbered as an editor
// numbers them.
#include <gtest/gtest.h>

#include <string>
#include <string_view>
#include <vector>

#include "drivers/formats/text_lines.hpp"

namespace nd = noisemon::drivers;

TEST(TextLines, SplitsOnNewlinesDropsOneCarriageReturnAndNumbersFromOne) {
  nd::formats::TextLines lines("a\r\n\nb\r\r\nc");
  std::vector<std::string> got;
  std::vector<std::size_t> numbers;
  for (std::string_view line; lines.next(line);) {
    got.emplace_back(line);
    numbers.push_back(lines.number());
  }
  EXPECT_EQ(got, (std::vector<std::string>{"a", "", "b\r", "c"}));
  EXPECT_EQ(numbers, (std::vector<std::size_t>{1, 2, 3, 4}));
  nd::formats::TextLines empty("");
  std::string_view line;
  EXPECT_FALSE(empty.next(line));
  nd::formats::TextLines ended("x\n");  // a final line end opens no further line
  ASSERT_TRUE(ended.next(line));
  EXPECT_FALSE(ended.next(line));
}
