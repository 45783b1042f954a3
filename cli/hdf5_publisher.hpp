// Cycle reports into an HDF5 file a scientist opens with h5py or MATLAB: one row per cycle, every quantity a
// dataset with its units and meaning as attributes (docs/sources-and-formats.md, "HDF5 export").
//   /cycles/<scalar>   (N)           utime, cycle, run, speed_rpm, ..., lpa_measured_db, ..., flags, metrics
//   /bands/band_hz     (B)           nominal mid-band frequencies
//   /bands/<level>     (N, B)        spl_a_measured_db, spl_a_predicted_db, cpl_db, att_*_db, band_flags
//   /mics/<level>      (N, M)        mic_lpa_db, mic_flags
//   /runs/condition    (R)           the condition name of each run (/cycles/run indexes it)
// Rows are written in chunks as they come (the file grows during a long replay); flush() writes the rest.
#pragma once

#include <memory>
#include <string>

#include "daemon/publisher.hpp"

namespace noisemon::cli {

class Hdf5Publisher final : public daemon::Publisher {
 public:
  // Creates (replaces) the file; throws std::runtime_error naming it when it cannot.
  explicit Hdf5Publisher(const std::string& path);
  ~Hdf5Publisher() override;

  // The run the following reports belong to (session_t::condition; "" when unknown): a new run index.
  void begin_run(const std::string& condition) override;

  // Throws std::runtime_error naming the file and the cycle when a report does not fit the file's layout (more
  // bands or microphones than its first report; fewer are padded with NaN).
  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override;
  void flush() override;

 private:
  struct File;
  std::unique_ptr<File> file_;
};

}  // namespace noisemon::cli
