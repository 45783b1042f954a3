// Block-model parameter files: what `noisemon fit` writes and what noisemond (`--config`), `noisemon replay`
// and `noisemon diagnose` (`--model`) load. The file is a noisemond configuration holding only [model], so the
// daemon reads it with the same strict parser as any configuration.
#pragma once

#include <string>
#include <vector>

#include "model/block_params.hpp"

namespace noisemon::daemon {

// Writes [model] with every parameter (full precision) under `preset` (the preset the fit started from);
// comment_lines (fit summary, uncertainties) go above it as TOML comments. Throws naming the file on failure.
void write_params_file(const std::string& path, const model::BlockParams& params, const std::string& preset,
                       const std::vector<std::string>& comment_lines = {});

// "linear", "nl_damper", ... (a Table 4.1 preset) or the path of a TOML file with a [model] section.
// Throws naming the preset/file and what is wrong. *name (optional) receives the preset name or the path.
model::BlockParams resolve_model(const std::string& preset_or_file, std::string* name = nullptr);

}  // namespace noisemon::daemon
