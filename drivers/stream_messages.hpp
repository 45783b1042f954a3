// The 40 kHz streams as LCM messages (noisemon.raw_block_t, operating_point_t, session_t) and back: what the
// daemon publishes for recording, and what the lcm source and `noisemon replay` read.
#pragma once

#include <cstdint>
#include <string>

#include "drivers/source.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/raw_block_t.hpp"
#include "noisemon/session_t.hpp"

namespace noisemon::drivers {

noisemon::operating_point_t to_message(const OperatingPoint& op);
noisemon::raw_block_t to_message(const SampleBlock& b, std::int8_t stream, std::int64_t epoch_utime);
noisemon::session_t to_message(const StreamInfo& info, const std::string& source, std::int64_t utime);
// Back from the messages. Throw std::invalid_argument naming what does not fit.
StreamInfo from_message(const noisemon::session_t& m);
SampleBlock from_message(const noisemon::raw_block_t& m);
OperatingPoint from_message(const noisemon::operating_point_t& m);

}  // namespace noisemon::drivers
