// Frequency weightings of IEC 61672-1 (analytic form, clause 5.4 / annex E).
#pragma once

namespace noisemon::dsp {

// A-weighting in dB at frequency f_hz (0 dB at 1 kHz).
double a_weighting_db(double f_hz);
// C-weighting in dB at frequency f_hz (0 dB at 1 kHz).
double c_weighting_db(double f_hz);

}  // namespace noisemon::dsp
