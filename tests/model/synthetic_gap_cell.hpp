// A test cell for the gap watch made in a few lines of powers, sharing nothing with the virtual engine or with the
// attribution's candidate formulas: per cycle and band a cylinder pressure power with a common cycle-to-cycle
// variation, a fixed structure attenuation (the "model", and the engine's truth too), ten microphones each with its
// own offset and per-band directivity and its own per-cycle scatter; effects are added as powers (a microphone's
// sensitivity multiplies its powers, additive sound adds to every microphone's, transducer noise adds to the
// pressure's power) and the report's levels are then taken as the daemon takes them (energy mean over microphones,
// a microphone's level the sum over its bands).
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "model/diagnosis/gap_watch.hpp"

namespace gapcell {

inline const std::vector<double> kBandsHz{100,  125,  160,  200,  250,  315,  400,  500,  630,  800,
                                          1000, 1250, 1600, 2000, 2500, 3150, 4000, 5000, 6300, 8000};
constexpr std::size_t kMics = 10;

struct Effects {
  int gain_mic = -1;  // 0-based; -1: none
  double gain_db = 0.0;
  std::vector<double> additive_pa2;  // per band, added to every microphone (A-weighted power, Pa^2); empty: none
  double transducer_pa2_per_hz = 0.0;
  std::vector<double> structure_db;  // per band, added to the true attenuation's output (a resonance); empty: none
};

class Cell {
 public:
  explicit Cell(unsigned seed, double speed_rpm = 3050.0, double gap_offset_db = 0.0)
      : rng_(seed), speed_(speed_rpm), gap_offset_(gap_offset_db) {
    std::mt19937_64 installation(12345);  // microphone offsets and directivity: the same cell whatever the seed
    std::normal_distribution<double> n(0.0, 1.0);
    for (std::size_t m = 0; m < kMics; ++m) {
      mic_offset_db_.push_back(0.5 * n(installation));
      std::vector<double> d;
      for (std::size_t b = 0; b < kBandsHz.size(); ++b) d.push_back(0.7 * n(installation));
      directivity_db_.push_back(d);
    }
  }

  static double cpl_db(std::size_t b) { return 150.0 - 1.5 * static_cast<double>(b); }
  static double attenuation_db(std::size_t b) { return 50.0 + 0.5 * static_cast<double>(b); }

  noisemon::model::diagnosis::CycleGap next(const Effects& e = {}) {
    std::normal_distribution<double> common(0.0, 0.5), scatter(0.0, 0.6);
    noisemon::model::diagnosis::CycleGap c;
    c.cycle = cycle_++;
    c.time_s = time_s_;
    time_s_ += 120.0 / speed_;
    c.speed_rpm = speed_;
    c.band_hz = kBandsHz;
    std::vector<double> mic_power(kMics, 0.0);
    const double p0 = 4e-10;  // (20 uPa)^2
    for (std::size_t b = 0; b < kBandsHz.size(); ++b) {
      const double v = common(rng_);
      double cpl_power = p0 * std::pow(10.0, (cpl_db(b) + v) / 10.0);
      const double bandwidth = kBandsHz[b] * (std::pow(10.0, 0.05) - std::pow(10.0, -0.05));
      cpl_power += e.transducer_pa2_per_hz * bandwidth;
      c.cpl_db.push_back(10.0 * std::log10(cpl_power / p0));
      c.predicted_db.push_back(c.cpl_db.back() - attenuation_db(b));  // the model follows the measured pressure
      const double structure = e.structure_db.empty() ? 0.0 : e.structure_db[b];
      double sum = 0.0;
      for (std::size_t m = 0; m < kMics; ++m) {
        const double level = cpl_db(b) + v - attenuation_db(b) + gap_offset_ + structure + mic_offset_db_[m] +
                             directivity_db_[m][b] + scatter(rng_);
        double power = p0 * std::pow(10.0, level / 10.0);
        if (!e.additive_pa2.empty()) power += e.additive_pa2[b];
        if (static_cast<int>(m) == e.gain_mic) power *= std::pow(10.0, e.gain_db / 10.0);
        sum += power;
        mic_power[m] += power;
      }
      c.measured_db.push_back(10.0 * std::log10(sum / kMics / p0));
    }
    double all = 0.0, predicted = 0.0;
    for (std::size_t m = 0; m < kMics; ++m) {
      c.mic_db.push_back(10.0 * std::log10(mic_power[m] / p0));
      all += mic_power[m] / kMics;
    }
    for (const double l : c.predicted_db) predicted += p0 * std::pow(10.0, l / 10.0);
    c.overall_measured_db = 10.0 * std::log10(all / p0);
    c.overall_predicted_db = 10.0 * std::log10(predicted / p0);
    return c;
  }

  void set_speed(double rpm) { speed_ = rpm; }
  void set_gap_offset(double db) { gap_offset_ = db; }

 private:
  std::mt19937_64 rng_;
  double speed_;
  double gap_offset_;
  std::int64_t cycle_ = 0;
  double time_s_ = 0.0;
  std::vector<double> mic_offset_db_;
  std::vector<std::vector<double>> directivity_db_;
};

}  // namespace gapcell
