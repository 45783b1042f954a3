// The waveform CSV (`u,y` for waveform-mode fitting) read through the formats' one line splitter: Unix and Windows
// line ends give the same samples, errors name the file and the line as an editor numbers it.
#include <gtest/gtest.h>

#include <string>
#include <string_view>
#include <vector>

#include "cli/formats/waveform_csv.hpp"

namespace nf = noisemon::cli::formats;

TEST(WaveformCsv, WindowsAndUnixLineEndsGiveTheSameSamples) {
  const std::string unix_text = "# a comment\nu,y\n1,2\n\n3.5,-4e-3\n";
  std::string windows_text;
  for (const char c : unix_text) windows_text += c == '\n' ? std::string("\r\n") : std::string(1, c);
  const nf::Waveform a = nf::parse_waveform_csv(unix_text, "a.csv");
  const nf::Waveform b = nf::parse_waveform_csv(windows_text, "b.csv");
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
      (void)nf::parse_waveform_csv(text, "w.csv");
    } catch (const nf::WaveformCsvError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message("u,y\r\n1,2\r\n3,x\r\n").find("w.csv:3:"), std::string::npos) << message("u,y\r\n1,2\r\n3,x\r\n");
  EXPECT_NE(message("1,2\n\n1,2,3\n").find("w.csv:3:"), std::string::npos);
  EXPECT_NE(message("").find("no data rows"), std::string::npos);
}
