#include "daemon/params_file.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "daemon/config.hpp"

namespace noisemon::daemon {

void write_params_file(const std::string& path, const model::BlockParams& p, const std::string& preset,
                       const std::vector<std::string>& comment_lines) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot write parameter file");
  for (const std::string& line : comment_lines) f << "# " << line << '\n';
  char buf[64];
  const auto num = [&](const char* key, double v) {
    std::snprintf(buf, sizeof buf, "%.17g", v);
    f << key << " = " << buf << '\n';
  };
  f << "[model]\n"
    << "preset = \"" << preset << "\"\n";
  num("m", p.m);
  num("k1", p.k1);
  num("k3", p.k3);
  num("b1", p.b1);
  num("b3", p.b3);
  num("c0", p.c0);
  num("c1", p.c1);
  if (!f.flush()) throw std::runtime_error(path + ": write failed");
}

model::BlockParams resolve_model(const std::string& preset_or_file, std::string* name) {
  if (name) *name = preset_or_file;
  for (const std::string& p : model::preset_names())
    if (p == preset_or_file) return model::preset(p);
  if (!std::filesystem::is_regular_file(preset_or_file)) {
    std::string list;
    for (const std::string& p : model::preset_names()) list += (list.empty() ? "" : ", ") + p;
    throw std::runtime_error("--model " + preset_or_file + ": neither a preset (" + list + ") nor a parameter file");
  }
  return load_config(preset_or_file).model;
}

}  // namespace noisemon::daemon
