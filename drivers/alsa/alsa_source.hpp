// The `alsa` microphone source: the cell's microphones on an audio interface (or an acoustics front-end with an
// ALSA driver), on the interface's own crystal, composed with another source's pressure and crank angle.
//
// Its driver thread (`alsa.microphones`, nm-mics) reads the capture PCM a period at a time, picks the microphones'
// channels, scales them to Pa (full_scale_v / sensitivity) and resamples them from the interface's rate to the
// pipeline's 40 kHz on the encoder's clock (drivers/aligned_stream.hpp: by a sync pulse on a spare channel when
// there is one, else by the host clock; the tracked drift, the alignment's uncertainty and the sync's state are
// counters of the status). An overrun of the interface's buffer (xrun: the thread was not
// scheduled in time) is counted and survived: capture starts again, the stream has a gap there and the cycles
// across it are dropped downstream, as after a comedi card's overrun. A device that fails for good (unplugged)
// fails the thread with an error naming it.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "drivers/alsa/alsa_capture.hpp"
#include "drivers/source.hpp"
#include "drivers/worker_thread.hpp"

namespace noisemon::drivers::alsa {

inline constexpr unsigned kMaxCaptureChannels = 32;
inline constexpr unsigned kMinRateHz = 8000, kMaxRateHz = 384000;

struct AlsaSourceConfig {
  CaptureConfig capture;           // channels 0: the fewest the device offers that reach the highest microphone channel
  std::vector<unsigned> channels;  // the capture channel (0-based) of each microphone
  std::vector<double> sensitivity_mv_per_pa;       // one per microphone
  double full_scale_v = 1.0;                       // the input's peak voltage at digital full scale
  std::vector<std::array<double, 3>> positions_m;  // empty: the ten of thesis Table 3.1, scaled to radius_m
  double radius_m = 1.75;
  double speed_of_sound_m_s = 343.0;
  // A once-per-revolution pulse (the encoder's index, a tacho) on a spare capture channel aligns the interface's
  // clock to the encoder's (drivers/aligned_stream.hpp): its capture channel (-1: none, the host clock aligns it)
  // and the crank angle of its rising edge, degrees after firing TDC.
  int sync_channel = -1;
  double sync_angle_deg = 0.0;
  double host_delay_uncertainty_s = 1e-3;  // without a sync pulse: how well the transport's delay is known
  ThreadPolicy thread;
};

// Checks the configuration (std::invalid_argument naming the field) and opens the PCM now (std::runtime_error
// naming it when it is missing, busy or cannot do what is asked).
std::unique_ptr<MicSource> make_alsa_source(const AlsaSourceConfig& config);

}  // namespace noisemon::drivers::alsa
