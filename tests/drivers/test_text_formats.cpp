// The waveform CSV (`u,y` for waveform-mode fitting) read through the formats' one line splitter: Unix and Windows
// line ends give the same samples, errors name the file and the line as an editor numbers it.
#include <gtest/gtest.h>

#include <string>
#include <string_view>
#include <vector>

#include "drivers/formats/text_lines.hpp"
#include "drivers/formats/waveform_csv.hpp"

namespace nd = noisemon::drivers;

TEST(TextLines, SplitsOnNewlinesDropsOneCarriageReturnAndNumbersFromOne) {
  nd::TextLines lines("a\r\n\nb\r\r\nc");
  std::vector<std::string> got;
  std::vector<std::size_t> numbers;
  for (std::string_view line; lines.next(line);) {
    got.emplace_back(line);
    numbers.push_back(lines.number());
  }
  EXPECT_EQ(got, (std::vector<std::string>{"a", "", "b\r", "c"}));
  EXPECT_EQ(numbers, (std::vector<std::size_t>{1, 2, 3, 4}));
  nd::TextLines empty("");
  std::string_view line;
  EXPECT_FALSE(empty.next(line));
  nd::TextLines ended("x\n");  // a final line end opens no further line
  ASSERT_TRUE(ended.next(line));
  EXPECT_FALSE(ended.next(line));
}

TEST(WaveformCsv, WindowsAndUnixLineEndsGiveTheSameSamples) {
  const std::string unix_text = "# a comment\nu,y\n1,2\n\n3.5,-4e-3\n";
  std::string windows_text;
  for (const char c : unix_text) windows_text += c == '\n' ? std::string("\r\n") : std::string(1, c);
  const nd::Waveform a = nd::parse_waveform_csv(unix_text, "a.csv");
  const nd::Waveform b = nd::parse_waveform_csv(windows_text, "b.csv");
  EXPECT_EQ(a.header, "u,y");
  EXPECT_EQ(b.header, "u,y");
  EXPECT_EQ(a.u, (std::vector<double>{1.0, 3.5}));
  EXPECT_EQ(a.y, (std::vector<double>{2.0, -4e-3}));
  EXPECT_EQ(a.u, b.u);
  EXPECT_EQ(a.y, b.y);
}

TEST(WaveformCsv, ErrorsNameTheFileAndTheLine) {
  const auto message = [](std::string_view text) {
    try {
      (void)nd::parse_waveform_csv(text, "w.csv");
    } catch (const nd::WaveformCsvError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message("u,y\r\n1,2\r\n3,x\r\n").find("w.csv:3:"), std::string::npos) << message("u,y\r\n1,2\r\n3,x\r\n");
  EXPECT_NE(message("1,2\n\n1,2,3\n").find("w.csv:3:"), std::string::npos);
  EXPECT_NE(message("").find("no data rows"), std::string::npos);
}
