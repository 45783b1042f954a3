// One value of a configuration file changed as a person would change it: that line alone (an array over several
// lines included), its comment kept, the same key of another table untouched, the key or the table added when
// missing; and the file replaced whole, with its permissions.
#include "cli/config_edit.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <string>

#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

using noisemon::cli::set_toml_value;

TEST(ConfigEdit, TheValueAloneChangesItsCommentAndEveryOtherLineKept) {
  const std::string text =
      "# cell 3\n[comedi.mics]\nsensitivity_mv_per_pa = 50.0   # the card's\n\n[alsa]\npcm = \"hw:1\"\n"
      "sensitivity_mv_per_pa = [50.0, 49.8,\n                         51.0]  # from the certificates\nrate_hz = "
      "48000\n";
  EXPECT_EQ(set_toml_value(text, "alsa", "sensitivity_mv_per_pa", "[50.0, 49.8, 52.3]"),
            "# cell 3\n[comedi.mics]\nsensitivity_mv_per_pa = 50.0   # the card's\n\n[alsa]\npcm = \"hw:1\"\n"
            "sensitivity_mv_per_pa = [50.0, 49.8, 52.3]  # from the certificates\nrate_hz = 48000\n");
  EXPECT_EQ(set_toml_value(text, "comedi.mics", "sensitivity_mv_per_pa", "[48.2]"),
            "# cell 3\n[comedi.mics]\nsensitivity_mv_per_pa = [48.2]  # the card's\n\n[alsa]\npcm = \"hw:1\"\n"
            "sensitivity_mv_per_pa = [50.0, 49.8,\n                         51.0]  # from the certificates\n"
            "rate_hz = 48000\n");
}

TEST(ConfigEdit, AMissingKeyGoesUnderItsHeaderAndAMissingTableAtTheEnd) {
  EXPECT_EQ(
      set_toml_value("[alsa]\npcm = \"hw:1\"\n[[can.signal]]\nfield = \"speed_rpm\"\n", "alsa", "rate_hz", "96000"),
      "[alsa]\nrate_hz = 96000\npcm = \"hw:1\"\n[[can.signal]]\nfield = \"speed_rpm\"\n");
  EXPECT_EQ(set_toml_value("[daemon]\nlive = true\n", "alsa", "rate_hz", "96000"),
            "[daemon]\nlive = true\n\n[alsa]\nrate_hz = 96000\n");
  // A key of the same name in the table after it is not this table's.
  EXPECT_EQ(
      set_toml_value("[alsa]\n[comedi.mics]\nsensitivity_mv_per_pa = 1.0\n", "alsa", "sensitivity_mv_per_pa", "2.0"),
      "[alsa]\nsensitivity_mv_per_pa = 2.0\n[comedi.mics]\nsensitivity_mv_per_pa = 1.0\n");
}

TEST(ConfigEdit, TheFileIsReplacedWholeWithItsPermissions) {
  const std::string path = noisemon::test::unique_temp("cell.toml").string();
  std::ofstream(path) << "[alsa]\n";
  ASSERT_EQ(::chmod(path.c_str(), 0640), 0);
  noisemon::cli::replace_file_atomically(path, "[alsa]\nrate_hz = 96000\n");
  EXPECT_EQ(noisemon::test::slurp(path), "[alsa]\nrate_hz = 96000\n");
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0640u);
  EXPECT_FALSE(std::ifstream(path + ".new").good());
  EXPECT_THROW(noisemon::cli::replace_file_atomically("/nonexistent-dir/cell.toml", "x"), std::runtime_error);
}
