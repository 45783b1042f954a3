// noisemond configuration: a TOML file (every field has a default that runs the simulated engine) plus
// command-line overrides. systemd/noisemond.toml documents every field.
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

#include "daemon/sound_power_setup.hpp"
#include "drivers/alsa/alsa_source.hpp"
#include "drivers/can/can_source.hpp"
#include "drivers/comedi/comedi_source.hpp"
#include "drivers/sim/sim_source.hpp"
#include "drivers/worker_thread.hpp"
#include "model/block_params.hpp"
#include "model/combustion_metrics.hpp"
#include "model/engine_geometry.hpp"

namespace noisemon::daemon {

struct LcmConfig {
  std::string url;  // empty: LCM's default (udpm://239.255.76.67:7667?ttl=0)
  std::string report_channel = "NOISEMON_CYCLE";
  std::string status_channel = "NOISEMON_STATUS";
  std::string raw_channel = "NOISEMON_RAW";
  std::string operating_point_channel = "NOISEMON_OP";
  std::string session_channel = "NOISEMON_SESSION";
  std::string stats_channel = "NOISEMON_STATS";              // the rolling statistics (cycle_stats_t)
  std::string gap_event_channel = "NOISEMON_GAP_EVENT";      // noisemon gapwatch's events (gap_event_t)
  std::string gap_status_channel = "NOISEMON_GAP_STATUS";    // and its state, 1 Hz (gap_status_t)
  std::string check_channel = "NOISEMON_CHECK";              // noisemon check --publish's table (check_t)
  std::string record_loss_channel = "NOISEMON_RECORD_LOSS";  // the recorder's loss markers (record_loss_t), in its
                                                             // files only
  std::string command_channel = "NOISEMON_CMD";              // the test bed's commands (command_t)
  std::string command_ack_channel = "NOISEMON_CMD_ACK";      // and the daemon's answers (command_ack_t)
  bool publish_raw = true;
  bool publish_operating_point = true;
  double session_timeout_s = 30.0;  // source "lcm": how long to wait for the session message
  std::string cell;                 // test cell id, appended to every channel as "_<cell>" (empty: the plain names)

  // Every channel with its key in [lcm]: the reader and the cell's suffix walk this one list.
  [[nodiscard]] std::array<std::pair<const char*, std::string*>, 12> channels() {
    return {{{"report_channel", &report_channel},
             {"status_channel", &status_channel},
             {"raw_channel", &raw_channel},
             {"operating_point_channel", &operating_point_channel},
             {"session_channel", &session_channel},
             {"stats_channel", &stats_channel},
             {"gap_event_channel", &gap_event_channel},
             {"gap_status_channel", &gap_status_channel},
             {"check_channel", &check_channel},
             {"record_loss_channel", &record_loss_channel},
             {"command_channel", &command_channel},
             {"command_ack_channel", &command_ack_channel}}};
  }
};

// When the recorder makes a file durable (fsync): never (the kernel writes it out when it likes), when the file is
// closed (rotation, stop), or also every fsync_interval_s.
enum class RecordFsync { kNone, kRotate, kInterval };

// [record]: the recorder inside the daemon (recorder.hpp), which writes what the pipeline publishes into LCM log
// files in `dir`, named <cell>_<test_point>_<YYYYmmdd-HHMMSS>_<NNN>.lcmlog (record_files.hpp).
struct RecordConfig {
  bool enabled = false;
  bool autostart = true;    // record from the daemon's start; false: from the first `record start` command
  std::string dir;          // required when enabled (relative: to the configuration file's folder)
  double buffer_mb = 256;   // between the publishing thread and the writer (rounded up to a power of two)
  double rotate_mb = 1024;  // a new file once this one holds this much
  double rotate_s = 0;      // and/or once it is this old; 0: no rotation by time
  RecordFsync fsync = RecordFsync::kRotate;
  double fsync_interval_s = 10;    // fsync = "interval": how often
  std::string test_point = "run";  // in the file names: [A-Za-z0-9._-], not starting with '.'
};

// [threads]: memory locking and the scheduling of each thread the daemon may run (drivers/worker_thread.hpp).
// Defaults: normal scheduling, any CPU, no memory lock.
struct ThreadsConfig {
  bool lock_memory = false;               // mlockall at start (needs CAP_IPC_LOCK or LimitMEMLOCK=infinity)
  drivers::ThreadPolicy pressure;         // nm-pressure: encoder and pressure (sim, comedi)
  drivers::ThreadPolicy mics;             // nm-mics: microphones (sim, comedi, alsa)
  drivers::ThreadPolicy operating_point;  // nm-op: the sim's operating points
  drivers::ThreadPolicy can;              // nm-can: operating points from SocketCAN or a candump log
  drivers::ThreadPolicy lcm_receive;      // nm-lcm-in: source "lcm", the raw streams received from the bus
  drivers::ThreadPolicy processing;       // nm-processing: cycles, model, levels
  drivers::ThreadPolicy publishing;       // nm-publish: the publishing thread (status name "lcm")
  drivers::ThreadPolicy recording;        // nm-record: the recorder's writer ([record]; status name "record")
};

struct Config {
  std::string source = "sim";  // a name of stream_sources() (daemon/sources.hpp)
  std::string microphones;     // a name of mic_sources(): the microphones from a front-end of their own; empty: the
                               // source's own
  std::string calibration_history;  // the microphones' calibrations (calibration_history.hpp); load_config sets it
                                    // beside the file; empty: none
  std::int64_t cycles = 0;          // stop after this many cycles; 0 = until SIGINT/SIGTERM
  std::string log_level = "info";
  bool live = false;  // print one line per cycle on stdout
  LcmConfig lcm;
  RecordConfig record;
  std::string model_name = "linear";  // the preset the model parameters start from
  model::BlockParams model = model::preset("linear");
  double acoustic_delay_s = -1;   // < 0: radius / speed of sound, as the source reports it
  double mic_low_db = 20.0;       // a microphone this far below the median of the others is left out (unplugged)
  bool mic_average_time = false;  // [processing] mic_average = "time": the thesis's mean time history, not "energy"
  double ring_seconds = 0.5;      // capacity of each driver ring buffer
  drivers::sim::SimConfig sim;
  drivers::comedi::ComediSourceConfig comedi;  // [comedi]: the DAQ hardware (source = "comedi")
  drivers::alsa::AlsaSourceConfig alsa;        // [alsa]: an audio interface (microphones = "alsa")
  drivers::can::CanSourceConfig can;           // [can]: operating points from CAN; when configured, they replace the
                                               // source's own (any source)
  ThreadsConfig threads;                       // [threads]: handed to the sources and the pipeline
  model::EngineGeometry engine;                // [engine]: for the combustion metrics (default: the Yanmar L100V)
  model::MetricsOptions combustion;            // [combustion]: pegging and the combustion window of dp/dtheta max
  bool tdc_deg_configured = false;             // [combustion] tdc_deg was given (else a replay takes its session's)
  std::int64_t stats_window_cycles = 100;      // [statistics] window_cycles: the rolling statistics' window; 0: none
  SoundPowerConfig sound_power;                // [sound_power]: ISO 3744's K1 (background) and K2, the surface check

  // The raw streams (and the session describing them) leave the processing thread: for the bus, the recorder or both.
  [[nodiscard]] bool raw_streams() const { return lcm.publish_raw || record.enabled; }
};

// A configuration error; what() names the file and the field.
struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Sets the cell id and appends "_<cell>" to every channel name, replacing the suffix of a previous cell; several
// daemons can so share one multicast group. Throws ConfigError unless the id is [A-Za-z0-9-]* (empty: no suffix).
void set_cell(LcmConfig& lcm, const std::string& cell);

// Reads a TOML file over the defaults. Unknown keys, wrong types and out-of-range values are errors.
Config load_config(const std::string& path);
// Parses TOML text (for tests); `origin` names the text in error messages.
Config parse_config(const std::string& text, const std::string& origin);

}  // namespace noisemon::daemon
