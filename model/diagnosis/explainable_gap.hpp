// The waveform diagnosis's explainable-gap test and the statistics of held-out errors it shares with the candidates'
// scoring (waveform_diagnosis.cpp): internal to model/diagnosis.
#pragma once

#include <span>
#include <vector>

#include "model/diagnosis/waveform_diagnosis.hpp"

namespace noisemon::model::diagnosis {

// The rms over every range's errors (NaN without any).
double rms_of(const std::vector<std::vector<double>>& e);
// Per range and sample: before^2 - after^2 (what the block bootstrap tests for a mean above 0).
std::vector<std::vector<double>> squared_difference(const std::vector<std::vector<double>>& before,
                                                    const std::vector<std::vector<double>>& after);

// The share of m's held-out error (opt.heldout) that a missing force of the state, or a short-memory linear misfit,
// explains when regressed on the training ranges' error (opt.train), and whether that is significant.
ExplainableGap explainable_gap(const fit::WaveformModel& m, double fs, const WaveformDiagnosisOptions& opt,
                               const fit::WaveformSimOptions& sim, std::span<const double> u,
                               std::span<const double> y);

}  // namespace noisemon::model::diagnosis
