// `noisemon dash`: the thesis's linear attenuation curve, the reference drawn beside the measured and predicted ones.
#pragma once

#include <nlohmann/json.hpp>

namespace noisemon::cli {

// Att(band) = CPL - SPL_A of the Table 4.1 "linear" preset (eq. 4.13 with k3 = b3 = 0), per 1/3-octave band of the
// processing rate fs_hz, as the daemon's report computes it: the band's mean of |H(f)|^2 over frequency (a pressure
// spectrum flat within the band), A-weighted at the exact mid-band frequency. The Nyquist-cut top band ends at fs/2.
// {"preset": "linear", "band_hz": [nominal...], "att_db": [...]}
nlohmann::json linear_reference_json(double fs_hz = 40000.0);

}  // namespace noisemon::cli
