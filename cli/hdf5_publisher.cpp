#include "cli/hdf5_publisher.hpp"

#include <hdf5.h>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace noisemon::cli {
namespace {

using noisemon::cycle_report_t;
constexpr std::size_t kRowsPerWrite = 1024;  // rows buffered before they go to the file (and its chunk length)

struct RealColumn {
  const char* name;
  const char* units;
  const char* description;
  double (*get)(const cycle_report_t&);
};
struct IntegerColumn {
  const char* name;
  const char* units;
  const char* description;
  std::int64_t (*get)(const cycle_report_t&);
};
struct BandColumn {  // per band (or per microphone) of a report
  const char* name;
  const char* units;
  const char* description;
  float (*get)(const cycle_report_t&, int index);
};

const IntegerColumn kIntegerColumns[] = {
    {"utime", "us", "start of the cycle (crank angle -360 deg), microseconds since 1970",
     [](auto& m) { return m.utime; }},
    {"cycle", "1", "index since the run started, 0-based, counting dropped cycles", [](auto& m) { return m.cycle; }},
    {"flags", "1", "CYCLE_* bits of cycle_report_t (msgs/cycle_report_t.lcm); 0 = fully valid",
     [](auto& m) { return static_cast<std::int64_t>(m.flags); }},
    {"motored", "1", "1 when the engine was motored (not fired)", [](auto& m) { return std::int64_t{m.motored}; }},
};
const RealColumn kRealColumns[] = {
    {"duration_s", "s", "length of the cycle", [](auto& m) { return m.duration_s; }},
    {"speed_rpm", "rpm", "engine speed, 720 deg over the cycle's duration", [](auto& m) { return m.speed_rpm; }},
    {"load_nm", "N m", "engine load", [](auto& m) { return m.load_nm; }},
    {"soi_deg_btdc", "deg", "start of injection before firing TDC", [](auto& m) { return m.soi_deg_btdc; }},
    {"rail_pressure_bar", "bar", "common-rail pressure (NaN: unknown)", [](auto& m) { return m.rail_pressure_bar; }},
    {"lpa_measured_db", "dB(A) re 20 uPa", "A-weighted sound pressure level, energy mean over the microphones",
     [](auto& m) { return m.lpa_measured_db; }},
    {"lpa_predicted_db", "dB(A) re 20 uPa", "the block model's A-weighted level from the cylinder pressure",
     [](auto& m) { return m.lpa_predicted_db; }},
    {"lwa_measured_db", "dB(A) re 1 pW",
     "per-cycle A-weighted sound power (ISO 3744:2010, lw_low_hz ... lw_high_hz: K1 per band, K2, C1, C2), hemisphere "
     "of radius_m",
     [](auto& m) { return m.lwa_measured_db; }},
    {"lwa_predicted_db", "dB(A) re 1 pW", "the block model's per-cycle sound power",
     [](auto& m) { return m.lwa_predicted_db; }},
    {"radius_m", "m", "measurement hemisphere radius", [](auto& m) { return m.radius_m; }},
    {"k2_db", "dB", "ISO 3744 environmental correction K2 in lwa_*", [](auto& m) { return m.k2_db; }},
    {"c1_db", "dB", "ISO 3744:2010 reference quantity correction C1 in lwa_*", [](auto& m) { return m.c1_db; }},
    {"c2_db", "dB", "ISO 3744:2010 radiation impedance correction C2 in lwa_*", [](auto& m) { return m.c2_db; }},
    {"lw_low_hz", "Hz", "lowest nominal band of lwa_*", [](auto& m) { return static_cast<double>(m.lw_low_hz); }},
    {"lw_high_hz", "Hz", "highest nominal band of lwa_* (inf: all)",
     [](auto& m) { return static_cast<double>(m.lw_high_hz); }},
    {"processing_ms", "ms", "CPU time the processing spent on the cycle",
     [](auto& m) { return static_cast<double>(m.processing_ms); }},
    {"peak_pressure_bar", "bar", "peak cylinder pressure", [](auto& m) { return m.peak_pressure_bar; }},
    {"peak_pressure_deg", "deg", "crank angle of the peak pressure after firing TDC",
     [](auto& m) { return m.peak_pressure_deg; }},
    {"max_rise_bar_per_deg", "bar/deg",
     "maximum rate of pressure rise in the combustion window (from the start of injection)",
     [](auto& m) { return m.max_rise_bar_per_deg; }},
    {"max_rise_deg", "deg", "crank angle of the maximum rate of pressure rise", [](auto& m) { return m.max_rise_deg; }},
    {"imep_gross_bar", "bar", "gross indicated mean effective pressure", [](auto& m) { return m.imep_gross_bar; }},
    {"imep_net_bar", "bar", "net indicated mean effective pressure", [](auto& m) { return m.imep_net_bar; }},
    {"heat_release_j", "J", "apparent heat release, -60 ... 90 deg", [](auto& m) { return m.heat_release_j; }},
    {"ca10_deg", "deg", "crank angle of 10 % of the heat release", [](auto& m) { return m.ca10_deg; }},
    {"ca50_deg", "deg", "crank angle of 50 % of the heat release", [](auto& m) { return m.ca50_deg; }},
    {"ca90_deg", "deg", "crank angle of 90 % of the heat release", [](auto& m) { return m.ca90_deg; }},
    {"ringing_intensity_MW_per_m2", "MW/m^2", "ringing intensity (Eng, SAE 2002-01-2859)",
     [](auto& m) { return m.ringing_intensity_MW_per_m2; }},
    {"max_rise_motored_bar_per_deg", "bar/deg",
     "the motored-equivalent slope at max_rise_deg (the compression's polytropic)",
     [](auto& m) { return m.max_rise_motored_bar_per_deg; }},
    {"pmep_bar", "bar", "pumping mean effective pressure (net - gross IMEP)", [](auto& m) { return m.pmep_bar; }},
    {"n_compression", "1", "polytropic exponent of the compression (-90 ... -40 deg)",
     [](auto& m) { return m.n_compression; }},
    {"n_expansion", "1", "polytropic exponent of the expansion (60 ... 110 deg)",
     [](auto& m) { return m.n_expansion; }},
    {"ca05_deg", "deg", "crank angle of 5 % of the heat release", [](auto& m) { return m.ca05_deg; }},
    {"burn_duration_deg", "deg", "CA10 to CA90", [](auto& m) { return m.burn_duration_deg; }},
    {"tdc_deg", "deg", "the encoder's angle of firing TDC the combustion metrics used ([combustion] tdc_deg)",
     [](auto& m) { return m.tdc_deg; }},
    {"pegging_offset_bar", "bar", "pegging offset added to the whole cycle ([combustion] pegging; 0: none)",
     [](auto& m) { return m.pegging_offset_bar; }},
    {"mapo_bar", "bar",
     "MAPO: largest |pressure| band-passed to [combustion] mapo_low_hz ... mapo_high_hz, in its window",
     [](auto& m) { return m.mapo_bar; }},
    {"combustion_noise_db", "dB(A)", "CPL through the thesis's fixed eq. 4.1 structure attenuation, A-weighted",
     [](auto& m) { return m.combustion_noise_db; }},
};
const BandColumn kBandColumns[] = {
    {"spl_a_measured_db", "dB(A) re 20 uPa", "A-weighted band level, energy mean over the microphones",
     [](auto& m, int b) { return m.spl_a_measured_db[b]; }},
    {"spl_a_predicted_db", "dB(A) re 20 uPa", "A-weighted band level of the block model",
     [](auto& m, int b) { return m.spl_a_predicted_db[b]; }},
    {"cpl_db", "dB re 20 uPa", "cylinder pressure level", [](auto& m, int b) { return m.cpl_db[b]; }},
    {"att_measured_db", "dB", "attenuation CPL - SPL(A), measured",
     [](auto& m, int b) { return m.att_measured_db[b]; }},
    {"att_predicted_db", "dB", "attenuation CPL - SPL(A), predicted",
     [](auto& m, int b) { return m.att_predicted_db[b]; }},
    {"band_flags", "1", "BAND_* bits of cycle_report_t",
     [](auto& m, int b) { return static_cast<float>(m.band_flags[b]); }},
    {"k1_db", "dB",
     "ISO 3744:2010 background correction K1 of the measured band (1.3 with BAND_BACKGROUND: an upper bound)",
     [](auto& m, int b) { return m.k1_db[b]; }},
    {"background_db", "dB re 20 uPa", "background band level behind K1, unweighted (NaN: none)",
     [](auto& m, int b) { return m.background_db[b]; }},
};
const BandColumn kMicColumns[] = {
    {"mic_lpa_db", "dB(A) re 20 uPa", "each microphone's own A-weighted level",
     [](auto& m, int i) { return m.mic_lpa_db[i]; }},
    {"mic_flags", "1", "MIC_* bits of cycle_report_t; 0 = in the measured levels",
     [](auto& m, int i) { return static_cast<float>(m.mic_flags[i]); }},
};

void check(herr_t status, const std::string& path, const char* what) {
  if (status < 0) throw std::runtime_error("HDF5 file " + path + ": cannot " + what);
}
hid_t checked(hid_t id, const std::string& path, const char* what) {
  if (id < 0) throw std::runtime_error("HDF5 file " + path + ": cannot " + what);
  return id;
}

void string_attribute(hid_t object, const char* name, const std::string& value, const std::string& path) {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, value.empty() ? 1 : value.size());
  const hid_t space = H5Screate(H5S_SCALAR);
  const hid_t attribute =
      checked(H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT), path, "add an attribute");
  check(H5Awrite(attribute, type, value.c_str()), path, "write an attribute");
  H5Aclose(attribute);
  H5Sclose(space);
  H5Tclose(type);
}

// A dataset of `columns` values per row (0: one value, a 1-D dataset) that grows by rows.
class Appendable {
 public:
  Appendable(hid_t group, const char* name, hid_t type, hsize_t columns, const std::string& path)
      : type_(type), columns_(columns), path_(path) {
    const int rank = columns == 0 ? 1 : 2;
    const hsize_t dims[2] = {0, columns}, max[2] = {H5S_UNLIMITED, columns}, chunk[2] = {kRowsPerWrite, columns};
    const hid_t space = H5Screate_simple(rank, dims, max);
    const hid_t properties = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(properties, rank, chunk);
    H5Pset_shuffle(properties);
    H5Pset_deflate(properties, 4);
    id_ = checked(H5Dcreate2(group, name, type, space, H5P_DEFAULT, properties, H5P_DEFAULT), path, "create a dataset");
    H5Pclose(properties);
    H5Sclose(space);
  }
  ~Appendable() { H5Dclose(id_); }
  Appendable(const Appendable&) = delete;
  Appendable& operator=(const Appendable&) = delete;

  hid_t id() const { return id_; }
  void append(const void* data, hsize_t rows) {
    if (rows == 0) return;
    const int rank = columns_ == 0 ? 1 : 2;
    const hsize_t extent[2] = {rows_ + rows, columns_}, start[2] = {rows_, 0}, count[2] = {rows, columns_};
    check(H5Dset_extent(id_, extent), path_, "extend a dataset");
    const hid_t file_space = H5Dget_space(id_);
    H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, nullptr, count, nullptr);
    const hid_t memory_space = H5Screate_simple(rank, count, nullptr);
    const herr_t status = H5Dwrite(id_, type_, memory_space, file_space, H5P_DEFAULT, data);
    H5Sclose(memory_space);
    H5Sclose(file_space);
    check(status, path_, "write rows");
    rows_ += rows;
  }

 private:
  hid_t id_ = -1;
  hid_t type_;
  hsize_t columns_;
  hsize_t rows_ = 0;
  std::string path_;
};

}  // namespace

struct Hdf5Publisher::File {
  std::string path;
  hid_t file = -1, cycles = -1, bands = -1, mics = -1, runs = -1;
  hid_t text_type = -1;  // variable-length strings (the run names)
  std::vector<std::unique_ptr<Appendable>> integer_sets, real_sets, band_sets, mic_sets;
  std::unique_ptr<Appendable> run_set, condition_set;
  std::vector<std::vector<std::int64_t>> integer_rows;
  std::vector<std::vector<double>> real_rows;
  std::vector<std::vector<float>> band_rows, mic_rows;
  std::vector<std::int64_t> run_rows;
  std::size_t buffered = 0;
  int band_count = -1, mic_count = -1;  // fixed by the first report
  std::int64_t run = -1;

  hid_t group(const char* name) {
    return checked(H5Gcreate2(file, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path, "create a group");
  }
  void describe(hid_t dataset, const char* units, const char* description) {
    string_attribute(dataset, "units", units, path);
    string_attribute(dataset, "description", description, path);
  }
  void open_per_cycle_sets();
  void open_per_band_sets(const cycle_report_t& first);
  void add(const cycle_report_t& m);
  void write_buffered();
};

void Hdf5Publisher::File::open_per_cycle_sets() {
  for (const IntegerColumn& c : kIntegerColumns) {
    integer_sets.push_back(std::make_unique<Appendable>(cycles, c.name, H5T_NATIVE_INT64, 0, path));
    describe(integer_sets.back()->id(), c.units, c.description);
  }
  for (const RealColumn& c : kRealColumns) {
    real_sets.push_back(std::make_unique<Appendable>(cycles, c.name, H5T_NATIVE_DOUBLE, 0, path));
    describe(real_sets.back()->id(), c.units, c.description);
  }
  run_set = std::make_unique<Appendable>(cycles, "run", H5T_NATIVE_INT64, 0, path);
  describe(run_set->id(), "1", "index of the cycle's run in /runs/condition");
  integer_rows.resize(std::size(kIntegerColumns));
  real_rows.resize(std::size(kRealColumns));
}

void Hdf5Publisher::File::open_per_band_sets(const cycle_report_t& first) {
  band_count = first.nbands;
  mic_count = first.nmics;
  const hsize_t bands_dims[1] = {static_cast<hsize_t>(band_count)};
  const hid_t space = H5Screate_simple(1, bands_dims, nullptr);
  const hid_t band_hz =
      checked(H5Dcreate2(bands, "band_hz", H5T_NATIVE_FLOAT, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path,
              "create band_hz");
  check(H5Dwrite(band_hz, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, first.band_hz.data()), path,
        "write band_hz");
  describe(band_hz, "Hz", "nominal mid-band frequency of the 1/3-octave bands (IEC 61260-1, base 10)");
  H5Dclose(band_hz);
  H5Sclose(space);
  for (const BandColumn& c : kBandColumns) {
    band_sets.push_back(std::make_unique<Appendable>(bands, c.name, H5T_NATIVE_FLOAT, band_count, path));
    describe(band_sets.back()->id(), c.units, c.description);
  }
  for (const BandColumn& c : kMicColumns) {
    mic_sets.push_back(std::make_unique<Appendable>(mics, c.name, H5T_NATIVE_FLOAT, mic_count, path));
    describe(mic_sets.back()->id(), c.units, c.description);
  }
  band_rows.resize(std::size(kBandColumns));
  mic_rows.resize(std::size(kMicColumns));
}

void Hdf5Publisher::File::add(const cycle_report_t& m) {
  if (m.nbands > band_count || m.nmics > mic_count)
    throw std::runtime_error("HDF5 file " + path + ": cycle " + std::to_string(m.cycle) + " has " +
                             std::to_string(m.nbands) + " bands and " + std::to_string(m.nmics) +
                             " microphones, more than the file's first report (" + std::to_string(band_count) + ", " +
                             std::to_string(mic_count) + ")");
  for (std::size_t c = 0; c < std::size(kIntegerColumns); ++c) integer_rows[c].push_back(kIntegerColumns[c].get(m));
  for (std::size_t c = 0; c < std::size(kRealColumns); ++c) real_rows[c].push_back(kRealColumns[c].get(m));
  run_rows.push_back(run);
  for (std::size_t c = 0; c < std::size(kBandColumns); ++c)
    for (int b = 0; b < band_count; ++b) band_rows[c].push_back(b < m.nbands ? kBandColumns[c].get(m, b) : NAN);
  for (std::size_t c = 0; c < std::size(kMicColumns); ++c)
    for (int i = 0; i < mic_count; ++i) mic_rows[c].push_back(i < m.nmics ? kMicColumns[c].get(m, i) : NAN);
  if (++buffered == kRowsPerWrite) write_buffered();
}

void Hdf5Publisher::File::write_buffered() {
  if (buffered == 0) return;
  for (std::size_t c = 0; c < integer_sets.size(); ++c) integer_sets[c]->append(integer_rows[c].data(), buffered);
  for (std::size_t c = 0; c < real_sets.size(); ++c) real_sets[c]->append(real_rows[c].data(), buffered);
  run_set->append(run_rows.data(), buffered);
  for (std::size_t c = 0; c < band_sets.size(); ++c) band_sets[c]->append(band_rows[c].data(), buffered);
  for (std::size_t c = 0; c < mic_sets.size(); ++c) mic_sets[c]->append(mic_rows[c].data(), buffered);
  for (auto& r : integer_rows) r.clear();
  for (auto& r : real_rows) r.clear();
  for (auto& r : band_rows) r.clear();
  for (auto& r : mic_rows) r.clear();
  run_rows.clear();
  buffered = 0;
  H5Fflush(file, H5F_SCOPE_LOCAL);
}

Hdf5Publisher::Hdf5Publisher(const std::string& path) : file_(std::make_unique<File>()) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // errors become exceptions naming the file, not stderr dumps
  File& f = *file_;
  f.path = path;
  f.file = checked(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT), path, "be created");
  string_attribute(f.file, "created_by", "noisemon", path);
  string_attribute(f.file, "layout", "one row per engine cycle; docs/sources-and-formats.md, HDF5 export", path);
  f.cycles = f.group("/cycles");
  f.bands = f.group("/bands");
  f.mics = f.group("/mics");
  f.runs = f.group("/runs");
  f.text_type = H5Tcopy(H5T_C_S1);
  H5Tset_size(f.text_type, H5T_VARIABLE);
  f.condition_set = std::make_unique<Appendable>(f.runs, "condition", f.text_type, 0, path);
  f.describe(f.condition_set->id(), "", "condition name of each run (\"\" when the recording names none)");
  f.open_per_cycle_sets();
}

Hdf5Publisher::~Hdf5Publisher() {
  try {
    flush();
  } catch (...) {  // a destructor must not throw; flush() is the call that reports
  }
  File& f = *file_;
  f.integer_sets.clear(), f.real_sets.clear(), f.band_sets.clear(), f.mic_sets.clear();
  f.run_set.reset(), f.condition_set.reset();
  for (hid_t g : {f.cycles, f.bands, f.mics, f.runs}) H5Gclose(g);
  H5Tclose(f.text_type);
  H5Fclose(f.file);
}

void Hdf5Publisher::begin_run(const std::string& condition) {
  File& f = *file_;
  const char* name = condition.c_str();  // a variable-length string is a char pointer in memory
  f.write_buffered();
  f.condition_set->append(&name, 1);
  ++f.run;
}

void Hdf5Publisher::publish_bytes(const std::string&, const std::uint8_t* data, std::size_t size, std::int64_t) {
  const auto report = daemon::decode_as<noisemon::cycle_report_t>(data, size);
  if (!report) return;  // the cycle reports alone are kept
  const noisemon::cycle_report_t& m = *report;
  File& f = *file_;
  if (f.run < 0) begin_run("");
  if (f.band_count < 0) f.open_per_band_sets(m);
  f.add(m);
}

void Hdf5Publisher::flush() { file_->write_buffered(); }

}  // namespace noisemon::cli
