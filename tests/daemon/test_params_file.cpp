// Parameter files: what `noisemon fit` writes must load back bit-exactly through the daemon's own strict
// configuration parser, and --model accepts a preset name or such a file.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "daemon/config.hpp"
#include "daemon/params_file.hpp"

namespace noisemon::daemon {
namespace {

std::string temp_path(const char* name) {
  return (std::filesystem::temp_directory_path() / (std::string("noisemon_params_") + std::to_string(getpid()) + name))
      .string();
}

TEST(ParamsFile, WrittenParametersLoadBackExactlyAsADaemonConfiguration) {
  model::BlockParams p;
  p.k1 = 8.123456789012345e8;
  p.k3 = 1.0000000000000002e13;
  p.b1 = 6543.21;
  p.b3 = 3.3333333333333335e3;
  p.c0 = 7000.000000000001;
  p.c1 = 11.1;
  const std::string path = temp_path("_exact.toml");
  write_params_file(path, p, "nl_spring_damper", {"fitted by a test", "k1 = 8.1e8 +- 1e6"});
  const Config c = load_config(path);  // the daemon's parser: strict, rejects unknown keys
  EXPECT_EQ(c.model.k1, p.k1);
  EXPECT_EQ(c.model.k3, p.k3);
  EXPECT_EQ(c.model.b1, p.b1);
  EXPECT_EQ(c.model.b3, p.b3);
  EXPECT_EQ(c.model.c0, p.c0);
  EXPECT_EQ(c.model.c1, p.c1);
  EXPECT_EQ(c.model.m, 1.0);
  EXPECT_EQ(c.model_name, "nl_spring_damper");
  std::string name;
  const model::BlockParams r = resolve_model(path, &name);
  EXPECT_EQ(r.k3, p.k3);
  EXPECT_EQ(name, path);
  std::remove(path.c_str());
}

TEST(ParamsFile, ResolveModelTakesPresetNamesAndNamesWhatIsWrong) {
  // Table 4.1 of the thesis: nl_damper has b1 = 7.00e3 and b3 = 2.00e3.
  const model::BlockParams p = resolve_model("nl_damper");
  EXPECT_EQ(p.b1, 7.00e3);
  EXPECT_EQ(p.b3, 2.00e3);
  try {
    resolve_model("no_such_model");
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no_such_model"), std::string::npos) << what;
    EXPECT_NE(what.find("nl_spring_damper_opt"), std::string::npos) << what;
  }
  const std::string bad = temp_path("_bad.toml");
  std::ofstream(bad) << "[model]\nk1 = \"stiff\"\n";
  try {
    resolve_model(bad);
    FAIL() << "expected an error";
  } catch (const std::exception& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(bad), std::string::npos) << what;
    EXPECT_NE(what.find("k1"), std::string::npos) << what;
  }
  std::remove(bad.c_str());
}

}  // namespace
}  // namespace noisemon::daemon
