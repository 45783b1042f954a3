#include "daemon/sources.hpp"

#include <spdlog/spdlog.h>

#include "drivers/alsa/alsa_source.hpp"
#include "drivers/can/can_source.hpp"
#include "drivers/combined_source.hpp"
#include "drivers/comedi/comedi_source.hpp"
#include "drivers/lcm/lcm_source.hpp"
#include "drivers/sim/sim_source.hpp"

namespace noisemon::daemon {
namespace {

std::unique_ptr<drivers::Source> make_sim(const Config& c, PressureClock /*at rest when [sim] stopped says so*/) {
  drivers::sim::SimConfig sim = c.sim;
  sim.threads = {c.threads.pressure, c.threads.mics, c.threads.operating_point};
  // A sim chain of a sheet sensitivity is read as [comedi.pressure] converts a voltage-output chain: its
  // calibration (`noisemon calibrate --pressure`) shows on the virtual engine.
  sim.pressure_readout.card_mv_per_bar = c.comedi.pressure.sensitivity_mv_per_bar;
  sim.pressure_readout.card_offset_bar = c.comedi.pressure.offset_bar;
  return drivers::sim::make_sim_source(sim);
}

std::unique_ptr<drivers::Source> make_lcm(const Config& c, PressureClock /*as the other process sends it*/) {
  drivers::lcm::LcmSourceConfig l;
  l.url = c.lcm.url;
  l.raw_channel = c.lcm.raw_channel;
  l.operating_point_channel = c.lcm.operating_point_channel;
  l.session_channel = c.lcm.session_channel;
  l.session_timeout_s = c.lcm.session_timeout_s;
  l.thread = c.threads.lcm_receive;
  spdlog::info("lcm source: waiting up to {} s for {} (start lcm-logplayer now)", l.session_timeout_s,
               l.session_channel);
  return drivers::lcm::make_lcm_source(l);
}

std::unique_ptr<drivers::Source> make_comedi(const Config& c, PressureClock clock) {
  try {
    return drivers::comedi::make_comedi_source(comedi_source_config(c, clock));
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("comedi source: ") + e.what());
  }
}

constexpr StreamSourceKind kStreamSources[] = {
    {"sim", "the virtual engine", make_sim},
    {"lcm", "raw blocks on the bus: lcm-logplayer or another daemon", make_lcm},
    {"comedi", "a DAQ card, see [comedi]", make_comedi},
};

std::unique_ptr<drivers::MicSource> make_alsa(const Config& c) {
  drivers::alsa::AlsaSourceConfig alsa = c.alsa;
  alsa.thread = c.threads.mics;
  try {
    return drivers::alsa::make_alsa_source(alsa);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(e.what());
  }
}

constexpr MicSourceKind kMicSources[] = {
    {"alsa", "an audio interface through ALSA, see [alsa]", make_alsa},
};

template <class Kind>
const Kind* find_kind(std::span<const Kind> kinds, std::string_view name) {
  for (const Kind& k : kinds)
    if (k.name == name) return &k;
  return nullptr;
}

template <class Kind>
std::string names_of(std::span<const Kind> kinds) {
  std::string names;
  for (const Kind& k : kinds) names += (names.empty() ? "" : ", ") + std::string(k.name);
  return names;
}

}  // namespace

drivers::comedi::ComediSourceConfig comedi_source_config(const Config& c, PressureClock clock) {
  drivers::comedi::ComediSourceConfig comedi = c.comedi;
  comedi.threads = {c.threads.pressure, c.threads.mics};
  comedi.log_info = [](const std::string& m) { spdlog::info("{}", m); };
  comedi.at_rest = clock == PressureClock::kAtRest;
  return comedi;
}

std::span<const StreamSourceKind> stream_sources() { return kStreamSources; }
const StreamSourceKind* find_stream_source(std::string_view name) { return find_kind(stream_sources(), name); }
std::string stream_source_names() { return names_of(stream_sources()); }

std::span<const MicSourceKind> mic_sources() { return kMicSources; }
const MicSourceKind* find_mic_source(std::string_view name) { return find_kind(mic_sources(), name); }
std::string mic_source_names() { return names_of(mic_sources()); }

std::unique_ptr<drivers::Source> make_source(const Config& config, PressureClock clock) {
  const StreamSourceKind* kind = find_stream_source(config.source);
  if (!kind)
    throw ConfigError("unknown source '" + config.source + "' (this build knows: " + stream_source_names() + ")");
  auto streams = kind->make(config, clock);
  if (!config.microphones.empty()) {
    const MicSourceKind* mics = find_mic_source(config.microphones);
    if (!mics)
      throw ConfigError("unknown microphone source '" + config.microphones +
                        "' (this build knows: " + mic_source_names() + ")");
    streams = drivers::compose_microphones(std::move(streams), mics->make(config));
    spdlog::info("microphones from {} ({})", config.microphones, mics->what);
  }
  if (!config.can.configured()) return streams;
  drivers::can::CanSourceConfig can_config = config.can;
  can_config.thread = config.threads.can;
  auto can = drivers::can::make_can_source(can_config);
  spdlog::info(
      "operating points from {} ({} signals)",
      config.can.candump_path.empty() ? "CAN interface " + config.can.interface : "candump log " + config.can.candump_path,
      config.can.map.signals().size());
  return drivers::combine_sources(std::move(streams), std::move(can));
}

}  // namespace noisemon::daemon
