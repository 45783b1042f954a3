// The 40 kHz streams as LCM messages (noisemon.raw_block_t, operating_point_t, session_t) and back: what the
// daemon publishes for recording. Readers of the raw stream decode it with raw_stream_decoder.hpp, built on these.
#pragma once

#include <cstdint>
#include <string>

#include "drivers/source.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/raw_block_t.hpp"
#include "noisemon/session_t.hpp"

namespace noisemon::drivers::formats {

noisemon::operating_point_t to_message(const OperatingPoint& op);
noisemon::raw_block_t to_message(const SampleBlock& b, std::int8_t stream, std::int64_t epoch_utime);
// The same message's fields for frames [first_index, first_index + frames) of `channels` channels, written into m,
// whose data is sized for them and left for the caller to fill (its storage is reused: a writer of many blocks
// keeps one message).
void set_raw_block(noisemon::raw_block_t& m, std::int64_t first_index, std::size_t frames, std::uint32_t channels,
                   std::int8_t stream, std::int64_t epoch_utime);
// condition: the run's condition name (session_t::condition), "" when unknown.
noisemon::session_t to_message(const StreamInfo& info, const std::string& source, std::int64_t utime,
                               const std::string& condition = "");
// Back from the messages. Throw std::invalid_argument naming what does not fit. A session may have 0
// microphones (a pressure-only recording); its condition name is session_t::condition.
StreamInfo from_message(const noisemon::session_t& m);

// Decode an LCM payload of exactly `size` bytes; false when it is not a well-formed message of that type (wrong
// fingerprint, short, or array/string lengths that do not fit the payload). The lengths are checked before
// decoding because the generated decoders trust them (a damaged length would allocate gigabytes or read past
// the buffer). Never throws.
bool decode_message(const void* data, std::size_t size, noisemon::session_t& m);
bool decode_message(const void* data, std::size_t size, noisemon::raw_block_t& m);
bool decode_message(const void* data, std::size_t size, noisemon::operating_point_t& m);

// Why a decoded raw block cannot be used as part of the session `info` ("" when it can): a sample rate other
// than 40 kHz, frames/channels out of range or not matching nsamples, another session's epoch, a utime that
// contradicts first_index (a damaged field), an unknown stream, a channel count its stream does not have,
// infinite samples, a crank angle outside [-360, 360]. NaN samples are what the device delivered (NaN crank: the
// angle is unknown; NaN pressure or sound: a faulty channel): the processing flags them, so they pass here.
// from_message() then succeeds on it.
std::string raw_block_problem(const noisemon::raw_block_t& m, const StreamInfo& info);
// The same, and "non-finite sample" for NaN too: for recordings that become run directories and fits.
std::string raw_block_problem_for_recording(const noisemon::raw_block_t& m, const StreamInfo& info);
SampleBlock from_message(const noisemon::raw_block_t& m);
// Operating points: an unknown value is NaN both ways (always the positive quiet NaN, so text says "nan").
OperatingPoint from_message(const noisemon::operating_point_t& m);

}  // namespace noisemon::drivers::formats
