// Frequency weightings of IEC 61672-1 (analytic form, clause 5.4 / annex E).
#pragma once

#include <vector>

#include "dsp/iir_design.hpp"

namespace noisemon::dsp {

// A-weighting in dB at frequency f_hz (0 dB at 1 kHz).
double a_weighting_db(double f_hz);
// C-weighting in dB at frequency f_hz (0 dB at 1 kHz).
double c_weighting_db(double f_hz);

// A-weighting as a time-domain filter at fs_hz: the annex E poles, the two at 12.2 kHz matched (z = exp(-w T),
// where the bilinear transform would bend them), the others and the four zeros at 0 Hz by the bilinear transform;
// 0 dB at 1 kHz. Three sections. At 40 kHz within 0.15 dB of IEC 61672-1 Table 3 up to 3.15 kHz, within its class 1
// limits up to 10 kHz (+1.5 dB there; tests/dsp/test_weighting.cpp): for levels of short stretches (a crank-angle
// window), not for a sound level meter.
std::vector<Biquad> a_weighting_sections(double fs_hz);

}  // namespace noisemon::dsp
