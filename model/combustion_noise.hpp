// Combustion-noise level from cylinder pressure through a fixed structure-attenuation (SA) curve, the way indicating
// systems (AVL 450 / IndiCom, Kistler KiBox, Dewesoft CA NOISE) define their "combustion noise":
//
//   CN = 10 lg sum_b 10^((CPL_b - SA(f_b) + A(f_b)) / 10)   dB(A)
//
// CPL_b: cylinder pressure level of 1/3-octave band b, dB re 20 uPa; SA: the structure attenuation, dB (CPL minus
// the radiated SPL it stands for); A: the IEC 61672-1 A-weighting (dsp/weighting.hpp). The sum is an energy sum of
// the weighted band levels; the SA curve is data, carried with its citation.
//
// Sources, and what could and could not be reproduced:
// - The curve of the commercial meters (the AVL/Lucas "S"/"U" filter chain) is documented by A. J. Shahlari,
//   C. Hocking, E. Kurtz, J. Ghandhi, "Comparison of Compression Ignition Engine Noise Metrics in Low-Temperature
//   Combustion Regimes", SAE Int. J. Engines 6(1):541-552, 2013, doi:10.4271/2013-01-1659. Its values were NOT
//   available to us: no readable copy of the paper, of Austen & Priede (1958) or of Russell & Haworth
//   (SAE 850973), and no public code implementing the curve, was found; the Dewesoft manual ("CA noise") says only
//   that its "U weighting" is "basically a band pass". No such curve is shipped here, and none is typed from memory.
//   To use it, fill a StructureAttenuation with the published per-band values and their exact citation.
// - The one published SA this file reproduces exactly is cao2015_eq_4_1_attenuation() below: the linear block
//   attenuation of the thesis this project implements, a filter with stated constants. It belongs to one engine
//   (the Yanmar L70 of the thesis, sound at 1.75 m): CN computed with it is that engine's predicted A-weighted
//   band-sum SPL at 1.75 m, and is NOT comparable with an AVL/KiBox/Dewesoft combustion-noise reading.
#pragma once

#include <array>
#include <cstddef>
#include <span>

#include "dsp/third_octave_bank.hpp"

namespace noisemon::model {

// IEC 61260-1 base-10 1/3-octave bands, nominal 20 Hz ... 20 kHz.
inline constexpr std::size_t kSaBandCount = dsp::kThirdOctaveNominalHz.size();
inline constexpr const std::array<double, kSaBandCount>& kSaNominalBandsHz = dsp::kThirdOctaveNominalHz;
// Exact mid-band frequency of table band i (0 = the 20 Hz band): 1000 * 10^((i - 17) / 10) Hz.
double sa_band_exact_mid_hz(std::size_t band);

struct StructureAttenuation {
  std::array<double, kSaBandCount> db{};  // SA of band i (nominal kSaNominalBandsHz[i]), dB; NaN: not published
  const char* source = "";                // citation: publication, table or figure or equation, page
};

// Cao, J., "Analysis and Simulation of Nonlinearities in Noise Attenuation Model for a Diesel Engine Block", MSME
// thesis, Purdue University, 2015 (Purdue e-Pubs, Open Access Theses 1171), sec. 4.3.1, eq. (4.1), pp. 23-25:
//   SA(f) = -20 lg |ka (s + wb) / (s^2 + 2 zeta wn s + wn^2)|,  s = j 2 pi f,
//   ka = 11.885, wb = 2 pi 100 rad/s, zeta = 0.35, wn = 2 pi 5000 rad/s,
// fitted to the idle attenuation curves (thesis Fig. 4.4) with the A-weighting taken out (sec. 4.3.1), so
// CPL - SA + A is the thesis's own chain. Tabulated exactly at the exact mid-band frequencies; between bands the
// log-frequency interpolation departs from eq. (4.1) by at most 0.35 dB (near the 5 kHz resonance).
const StructureAttenuation& cao2015_eq_4_1_attenuation();

// SA at f_hz, linear in log10(f) between the exact mid-band frequencies of the table (the table value at a
// mid-band frequency), held at the end bands' values out to their outer band edges (17.8 Hz, 22.4 kHz). NaN below
// or above those edges, for non-finite f, and wherever an entry it interpolates from is NaN.
double structure_attenuation_db(const StructureAttenuation& sa, double f_hz);

// CN over the bands given: cpl_band_db[b] at band frequency band_hz[b] (nominal or exact mid-band: SA and A are
// both evaluated at the frequency given). A NaN CPL band is skipped; which bands to include is the caller's choice.
// Returns NaN when no band is left. Throws std::invalid_argument when the spans differ in length, or when a band
// to be summed lies where the curve has no value (outside its bands, or a NaN entry): a curve that does not cover a
// band must not silently drop it. No allocation unless it throws.
double combustion_noise_level_db(std::span<const double> cpl_band_db, std::span<const double> band_hz,
                                 const StructureAttenuation& sa);

}  // namespace noisemon::model
