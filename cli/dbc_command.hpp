// `noisemon dbc`: what an engine controller's DBC file holds, as the CAN signal map reads it (drivers/formats/dbc.hpp):
// each message's id (and PGN for a J1939 group), each signal's layout, scaling, unit and multiplexing, so a test
// engineer finds the names to put in [[can.signal]] dbc_signal.
#pragma once

#include <string>

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

class DbcCommand {
 public:
  explicit DbcCommand(CLI::App& app);
  // After app.parse(): runs `dbc` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* dbc_ = nullptr;
  std::string path_, grep_;
};

}  // namespace noisemon::cli
