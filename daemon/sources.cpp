#include "daemon/sources.hpp"

#include <spdlog/spdlog.h>

#include "drivers/can/can_source.hpp"
#include "drivers/combined_source.hpp"
#include "drivers/comedi/comedi_source.hpp"
#include "drivers/lcm/lcm_source.hpp"
#include "drivers/sim/sim_source.hpp"

namespace noisemon::daemon {
namespace {

std::unique_ptr<drivers::Source> make_sim(const Config& c) {
  drivers::sim::SimConfig sim = c.sim;
  sim.threads = {c.threads.pressure, c.threads.mics, c.threads.operating_point};
  return drivers::sim::make_sim_source(sim);
}

std::unique_ptr<drivers::Source> make_lcm(const Config& c) {
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

std::unique_ptr<drivers::Source> make_comedi(const Config& c) {
  drivers::comedi::ComediSourceConfig comedi = c.comedi;
  comedi.threads = {c.threads.pressure, c.threads.mics};
  comedi.log_info = [](const std::string& m) { spdlog::info("{}", m); };
  try {
    return drivers::comedi::make_comedi_source(comedi);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("comedi source: ") + e.what());
  }
}

constexpr StreamSourceKind kStreamSources[] = {
    {"sim", "the virtual engine", make_sim},
    {"lcm", "raw blocks on the bus: lcm-logplayer or another daemon", make_lcm},
    {"comedi", "a DAQ card, see [comedi]", make_comedi},
};

}  // namespace

std::span<const StreamSourceKind> stream_sources() { return kStreamSources; }

const StreamSourceKind* find_stream_source(std::string_view name) {
  for (const StreamSourceKind& k : kStreamSources)
    if (k.name == name) return &k;
  return nullptr;
}

std::string stream_source_names() {
  std::string names;
  for (const StreamSourceKind& k : kStreamSources) names += (names.empty() ? "" : ", ") + std::string(k.name);
  return names;
}

std::unique_ptr<drivers::Source> make_source(const Config& config) {
  const StreamSourceKind* kind = find_stream_source(config.source);
  if (!kind)
    throw ConfigError("unknown source '" + config.source + "' (this build knows: " + stream_source_names() + ")");
  auto streams = kind->make(config);
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
