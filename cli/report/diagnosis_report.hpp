// `noisemon diagnose` results as report.json (its fields: docs/diagnosis.md). The JSON document is the one source of
// both reports: report.html (cli/report/report_html) renders nothing that is not in it.
//
// Band mode (run directories, LCM logs): figures in dB. baseline.heldout_rms_db, candidates[].heldout_rms_db and
// verdict.heldout_rms_*_db are the gap the candidates are ranked by (model/diagnosis/diagnosis.hpp: the thesis gap plus
// the microphone-calibration and crank-window parts, each zero for a model that explains the data); the thesis
// metric alone (attenuation-curve RMS over bands, per held-out condition, averaged) sits beside it as
// *_thesis_rms_db. Nulls stand for bands that are not scored (NaN inside).
//
// Waveform mode (u,y CSV): "units" says what the RMS figures are in (free-run output error in the data's
// units, not dB); the schema's *_rms_db keys carry them so every reader finds the same fields.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "model/diagnosis/diagnosis.hpp"
#include "model/diagnosis/waveform_diagnosis.hpp"
#include "model/fit/band_dataset.hpp"

namespace noisemon::cli::report {

struct ReportContext {
  std::vector<std::string> data;  // DATA paths as given
  std::string command;            // the command line, for the record
};

nlohmann::json band_report_json(const model::fit::BandDataset& data, const model::diagnosis::DiagnosisResult& result,
                                const model::diagnosis::DiagnosisOptions& options, const ReportContext& context);

// Free-run RMS of a model on a named test range (waveform mode --test).
struct WaveformTestSet {
  std::string name;
  model::fit::SampleRange range;
  double baseline_rms = 0.0;
  double best_rms = 0.0;
};

nlohmann::json waveform_report_json(const model::diagnosis::WaveformDiagnosis& diagnosis, const std::string& units,
                                    const std::vector<WaveformTestSet>& tests, const ReportContext& context);

}  // namespace noisemon::cli::report
