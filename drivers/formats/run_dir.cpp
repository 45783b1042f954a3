#include "drivers/formats/run_dir.hpp"

#include <fcntl.h>
#include <sndfile.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>

#include "drivers/formats/run_both.hpp"
#include "drivers/formats/text_lines.hpp"
#include "drivers/source.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers {
namespace {

using nlohmann::json;

constexpr const char* kCsvHeader = "time_s,crank_deg,pressure";
constexpr double kMinMicRateHz = 40000.0;
constexpr std::size_t kMaxMics = SampleBlock::kMaxChannels;

std::string read_text_file(const std::filesystem::path& file, const char* what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw RunDirError(file.string() + ": cannot open " + what + " (" + std::strerror(errno) + ")");
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) throw RunDirError(file.string() + ": read error");
  return std::move(s).str();
}

// Asks for huge pages for the storage a vector has reserved: filling a large one then takes a few page faults
// instead of one per 4 KiB (where the kernel offers them only on request; elsewhere this changes nothing).
template <class T>
void prefer_huge_pages(const std::vector<T>& v) {
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  const auto from = (reinterpret_cast<std::uintptr_t>(v.data()) + kHugePage - 1) / kHugePage * kHugePage;
  const auto to = reinterpret_cast<std::uintptr_t>(v.data() + v.capacity()) / kHugePage * kHugePage;
  if (to > from) ::madvise(reinterpret_cast<void*>(from), to - from, MADV_HUGEPAGE);
}

// A regular file mapped read-only (no copy of its bytes); empty when it cannot be mapped, the caller then reads
// it with read_text_file (which names the problem). release() gives pages already parsed back to the kernel.
class MappedFile {
 public:
  explicit MappedFile(const std::filesystem::path& file) {
    const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
      void* p = ::mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
      if (p != MAP_FAILED) {
        data_ = static_cast<const char*>(p);
        size_ = static_cast<std::size_t>(st.st_size);
        ::madvise(p, size_, MADV_SEQUENTIAL);
      }
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (data_) ::munmap(const_cast<char*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  bool mapped() const { return data_ != nullptr; }
  std::string_view text() const { return {data_, size_}; }
  // Drops the whole pages of [from, to) from this process (they stay in the page cache: reading them again is
  // still correct, only slower).
  void release(const char* from, const char* to) const {
    const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
    const std::uintptr_t a = (reinterpret_cast<std::uintptr_t>(from) + page - 1) / page * page;
    const std::uintptr_t b = reinterpret_cast<std::uintptr_t>(to) / page * page;
    if (b > a) ::madvise(reinterpret_cast<void*>(a), b - a, MADV_DONTNEED);
  }

 private:
  const char* data_ = nullptr;
  std::size_t size_ = 0;
};

// ------------------------------------------------------------------------------------------------ run.json

const char* json_type_name(const json& v) {
  switch (v.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return "a boolean";
    case json::value_t::string:
      return "a string";
    case json::value_t::array:
      return "an array";
    case json::value_t::object:
      return "an object";
    case json::value_t::discarded:
      return "nothing";
    default:
      return "a number";
  }
}

// Typed access to run.json with errors naming the file, the key path and what was expected.
class JsonFields {
 public:
  explicit JsonFields(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw RunDirError(file_ + ": key \"" + key + "\": " + what);
  }
  const json* find(const json& obj, const std::string& parent, const char* key, bool required,
                   const char* expected) const {
    const auto it = obj.find(key);
    if (it == obj.end()) {
      if (required) throw RunDirError(file_ + ": missing key \"" + join(parent, key) + "\" (" + expected + ")");
      return nullptr;
    }
    return &*it;
  }
  const json& object(const json& obj, const std::string& parent, const char* key) const {
    const json* v = find(obj, parent, key, true, "an object");
    if (!v->is_object()) fail(join(parent, key), std::string("expected an object, found ") + json_type_name(*v));
    return *v;
  }
  std::string string(const json& obj, const std::string& parent, const char* key, const char* meaning) const {
    const json* v = find(obj, parent, key, true, meaning);
    if (!v->is_string())
      fail(join(parent, key), std::string("expected a string (") + meaning + "), found " + json_type_name(*v));
    return v->get<std::string>();
  }
  double number(const json& v, const std::string& key, const char* meaning) const {
    if (!v.is_number()) fail(key, std::string("expected a number (") + meaning + "), found " + json_type_name(v));
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(key, std::string("expected a finite number (") + meaning + ")");
    return x;
  }
  double number(const json& obj, const std::string& parent, const char* key, const char* meaning) const {
    return number(*find(obj, parent, key, true, meaning), join(parent, key), meaning);
  }
  // A required key whose value may be null (unknown, not applicable): NaN then.
  double number_or_null(const json& obj, const std::string& parent, const char* key, const char* meaning) const {
    const json* v = find(obj, parent, key, true, meaning);
    if (v->is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!v->is_number())
      fail(join(parent, key), std::string("expected a number or null (") + meaning + "), found " + json_type_name(*v));
    return number(*v, join(parent, key), meaning);
  }
  std::optional<bool> boolean_or_null(const json& obj, const std::string& parent, const char* key,
                                      const char* meaning) const {
    const json* v = find(obj, parent, key, true, meaning);
    if (v->is_null()) return std::nullopt;
    if (!v->is_boolean())
      fail(join(parent, key),
           std::string("expected true, false or null (") + meaning + "), found " + json_type_name(*v));
    return v->get<bool>();
  }
  static std::string join(const std::string& parent, const char* key) {
    return parent.empty() ? key : parent + "." + key;
  }

 private:
  std::string file_;
};

// ------------------------------------------------------------------------------------------------ CSV

// One field of a CSV row as a finite number; blanks around it are allowed, nothing else.
bool parse_number(std::string_view field, double& out) {
  while (!field.empty() && (field.front() == ' ' || field.front() == '\t')) field.remove_prefix(1);
  while (!field.empty() && (field.back() == ' ' || field.back() == '\t')) field.remove_suffix(1);
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  if (field.empty()) return false;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), out);
  return ec == std::errc() && end == field.data() + field.size() && std::isfinite(out);
}

std::string quoted(std::string_view s) {
  if (s.size() > 40) return "\"" + std::string(s.substr(0, 40)) + "...\"";
  return "\"" + std::string(s) + "\"";
}

// ------------------------------------------------------------------------------------------------ WAV

struct MemoryFile {
  const std::uint8_t* data;
  sf_count_t size;
  sf_count_t pos;
};

sf_count_t mem_length(void* user) { return static_cast<MemoryFile*>(user)->size; }
sf_count_t mem_seek(sf_count_t offset, int whence, void* user) {
  auto* m = static_cast<MemoryFile*>(user);
  sf_count_t to = whence == SEEK_SET ? offset : whence == SEEK_CUR ? m->pos + offset : m->size + offset;
  if (to < 0 || to > m->size) return -1;
  m->pos = to;
  return to;
}
sf_count_t mem_read(void* ptr, sf_count_t count, void* user) {
  auto* m = static_cast<MemoryFile*>(user);
  const sf_count_t n = std::max<sf_count_t>(0, std::min(count, m->size - m->pos));
  if (n > 0) std::memcpy(ptr, m->data + m->pos, static_cast<std::size_t>(n));
  m->pos += n;
  return n;
}
sf_count_t mem_write(const void*, sf_count_t, void*) { return 0; }
sf_count_t mem_tell(void* user) { return static_cast<MemoryFile*>(user)->pos; }

const char* subtype_name(int subtype) {
  switch (subtype) {
    case SF_FORMAT_PCM_S8:
      return "8-bit signed PCM";
    case SF_FORMAT_PCM_U8:
      return "8-bit unsigned PCM";
    case SF_FORMAT_PCM_16:
      return "16-bit PCM";
    case SF_FORMAT_PCM_24:
      return "24-bit PCM";
    case SF_FORMAT_PCM_32:
      return "32-bit PCM";
    case SF_FORMAT_FLOAT:
      return "32-bit IEEE float";
    case SF_FORMAT_DOUBLE:
      return "64-bit IEEE float";
    case SF_FORMAT_ULAW:
      return "u-law";
    case SF_FORMAT_ALAW:
      return "A-law";
    default:
      return "a compressed or unusual encoding";
  }
}

// Scales samples [from, to) of mic by `scale` while they are still in the cache; the index of the first that is not
// finite, or `to`.
std::size_t scale_finite(std::vector<float>& mic, std::size_t from, std::size_t to, double scale) {
  for (std::size_t i = from; i < to; ++i)
    if (!std::isfinite(mic[i])) return i;
  if (scale != 1.0)  // v * 1.0 is v: float samples keep their bits
    for (std::size_t i = from; i < to; ++i) mic[i] = static_cast<float>(mic[i] * scale);
  return to;
}

// The sound file's frames straight into mic, block by block, each block checked and scaled as it arrives. A
// file that ends early is named before a non-finite sample (as when every sample was read first).
void read_samples(SNDFILE* sf, sf_count_t frames, const std::string& file, std::uint32_t channels, double scale,
                  std::vector<float>& mic) {
  mic.reserve(static_cast<std::size_t>(frames) * channels);
  prefer_huge_pages(mic);
  mic.resize(static_cast<std::size_t>(frames) * channels);
  constexpr sf_count_t kBlockFrames = 16384;
  sf_count_t done = 0;
  std::size_t bad = mic.size();  // the first non-finite sample
  while (done < frames) {
    const std::size_t at = static_cast<std::size_t>(done) * channels;
    const sf_count_t n = sf_readf_float(sf, mic.data() + at, std::min(kBlockFrames, frames - done));
    if (n <= 0) break;
    done += n;
    if (bad == mic.size()) {
      const std::size_t to = static_cast<std::size_t>(done) * channels;
      if (const std::size_t i = scale_finite(mic, at, to, scale); i < to) bad = i;
    }
  }
  if (done != frames)
    throw RunDirError(file + ": ends after frame " + std::to_string(done) + " of " + std::to_string(frames) +
                      " (truncated or damaged)");
  if (bad < mic.size())
    throw RunDirError(file + ": frame " + std::to_string(bad / channels) + ", channel " +
                      std::to_string(bad % channels + 1) + ": not a finite number");
}

// Checks and reads an opened sound file into run (closes it).
void read_sound(SNDFILE* sf, const SF_INFO& info, const std::string& file, std::uint32_t channels,
                std::optional<double> full_scale_pa, RunDir& run) {
  struct Closer {
    SNDFILE* f;
    ~Closer() { sf_close(f); }
  } closer{sf};
  if (info.channels != static_cast<int>(channels))
    throw RunDirError(file + ": " + std::to_string(info.channels) + " channels, expected " + std::to_string(channels) +
                      " (one per entry of mics.positions_m in run.json)");
  const int subtype = info.format & SF_FORMAT_SUBMASK;
  const bool is_float = subtype == SF_FORMAT_FLOAT || subtype == SF_FORMAT_DOUBLE;
  const bool is_pcm = subtype == SF_FORMAT_PCM_S8 || subtype == SF_FORMAT_PCM_U8 || subtype == SF_FORMAT_PCM_16 ||
                      subtype == SF_FORMAT_PCM_24 || subtype == SF_FORMAT_PCM_32;
  double scale = 1.0;
  if (is_pcm && full_scale_pa) {
    scale = *full_scale_pa;
  } else if (is_pcm) {
    throw RunDirError(file + ": samples are " + subtype_name(subtype) +
                      ", expected IEEE float in Pa (PCM has no physical scale: convert it to float Pa, or give "
                      "mics.full_scale_pa in run.json)");
  } else if (!is_float) {
    throw RunDirError(file + ": samples are " + subtype_name(subtype) + ", expected IEEE float in Pa");
  }
  const double rate = static_cast<double>(info.samplerate);
  if (rate < kMinMicRateHz)
    throw RunDirError(file + ": sample rate " + std::to_string(info.samplerate) +
                      " Hz, expected at least 40000 Hz (the 1/3-octave bands reach 20 kHz)");
  if (rate != kPipelineRateHz) {
    try {
      dsp::RationalResampler probe(rate, kPipelineRateHz, 1);
    } catch (const std::invalid_argument&) {
      throw RunDirError(
          file + ": sample rate " + std::to_string(info.samplerate) +
          " Hz cannot be resampled to 40000 Hz (the ratio needs more than 4096 filter phases or decimates by "
          "more than 4096); "
          "expected a common rate such as 44100, 48000, 51200 or 96000 Hz");
    }
  }
  if (info.frames <= 0) throw RunDirError(file + ": no samples");
  // libsndfile quietly reads a WAV cut short as a shorter one; its log says so ("data : 8000 (should be 7200)").
  char log[4096] = {};
  sf_command(sf, SFC_GET_LOG_INFO, log, sizeof log);
  if (const char* d = std::strstr(log, "\ndata : ")) {
    long long claimed = 0, actual = 0;
    if (std::sscanf(d, "\ndata : %lld (should be %lld)", &claimed, &actual) == 2 && actual < claimed)
      throw RunDirError(file + ": truncated: the header promises " + std::to_string(claimed) +
                        " bytes of samples, the file holds " + std::to_string(actual));
  }
  run.mic_rate_hz = rate;
  run.mic_count = channels;
  read_samples(sf, info.frames, file, channels, scale, run.mic_pa);
}

}  // namespace

namespace {

RunCondition parse_condition(const JsonFields& f, const json& c) {
  RunCondition r;
  r.name = f.string(c, "condition", "name", "the condition's name");
  r.speed_rpm = f.number_or_null(c, "condition", "speed_rpm", "engine speed, rpm");
  if (!std::isnan(r.speed_rpm) && !(r.speed_rpm > 0))
    f.fail("condition.speed_rpm", "expected a speed above 0 rpm (or null: measured from the encoder)");
  r.load_nm = f.number_or_null(c, "condition", "load_nm", "brake torque, N m");
  r.soi_deg_btdc = f.number_or_null(c, "condition", "soi_deg_btdc", "start of injection, degrees before firing TDC");
  if (const json* v = f.find(c, "condition", "rail_pressure_bar", false, ""); v && !v->is_null()) {
    r.rail_pressure_bar = f.number(*v, "condition.rail_pressure_bar", "rail pressure in bar, or null");
    if (*r.rail_pressure_bar < 0) f.fail("condition.rail_pressure_bar", "expected a pressure >= 0 bar or null");
  }
  const std::optional<bool> motored =
      f.boolean_or_null(c, "condition", "motored", "true when the engine was motored, without combustion");
  r.motored = motored.value_or(false);
  r.motored_known = motored.has_value();
  return r;
}

// An optional number above 0 (null or absent: not known).
std::optional<double> optional_positive(const JsonFields& f, const json& object, const std::string& where,
                                        const char* key, const std::string& what) {
  const json* v = f.find(object, where, key, false, "");
  if (!v || v->is_null()) return std::nullopt;
  const double x = f.number(*v, where + "." + key, (what + ", or null").c_str());
  if (!(x > 0)) f.fail(where + "." + key, "expected a value above 0 (" + what + "), or null (unknown)");
  return x;
}

void parse_pressure_entry(const JsonFields& f, const json& p, RunManifest& m) {
  m.pressure_file = f.string(p, "pressure", "file", "the pressure CSV's file name");
  const std::string units = f.string(p, "pressure", "units", "\"bar\" or \"Pa\"");
  if (units == "bar")
    m.pressure_to_pa = 1e5;
  else if (units == "Pa")
    m.pressure_to_pa = 1.0;
  else
    f.fail("pressure.units", "\"" + units + "\", expected \"bar\" or \"Pa\"");
  if (const json* v = f.find(p, "pressure", "noise_floor_bar", false, ""); v && !v->is_null()) {
    const double floor = f.number(*v, "pressure.noise_floor_bar", "noise floor, bar rms per encoder sample, or null");
    if (!(floor >= 0))
      f.fail("pressure.noise_floor_bar", "expected a noise floor >= 0 bar rms per encoder sample, or null (unknown)");
    m.pressure_noise_floor_bar = floor;
  }
  m.pressure_edges_per_rev =
      optional_positive(f, p, "pressure", "encoder_edges_per_rev", "encoder edges per revolution");
}

void parse_mics_entry(const JsonFields& f, const json& mics, RunManifest& m) {
  if (!mics.is_object()) f.fail("mics", std::string("expected an object, found ") + json_type_name(mics));
  m.has_mics = true;
  m.mics_file = f.string(mics, "mics", "file", "the microphones' WAV file name");
  if (const json* u = f.find(mics, "mics", "units", false, "")) {
    if (!u->is_string() || u->get<std::string>() != "Pa") f.fail("mics.units", "expected \"Pa\"");
  }
  const json* pos = f.find(mics, "mics", "positions_m", true, "one [x, y, z] per microphone, m");
  if (!pos->is_array() || pos->empty() || pos->size() > kMaxMics)
    f.fail("mics.positions_m", "expected an array of 1.." + std::to_string(kMaxMics) + " [x, y, z] positions in m");
  for (std::size_t i = 0; i < pos->size(); ++i) {
    const json& xyz = (*pos)[i];
    const std::string key = "mics.positions_m[" + std::to_string(i) + "]";
    if (!xyz.is_array() || xyz.size() != 3) f.fail(key, "expected [x, y, z] in m");
    m.mic_positions_m.push_back(
        {f.number(xyz[0], key, "x, m"), f.number(xyz[1], key, "y, m"), f.number(xyz[2], key, "z, m")});
  }
  if (const json* r = f.find(mics, "mics", "radius_m", false, "")) {
    m.radius_m = f.number(*r, "mics.radius_m", "measurement radius, m");
    if (!(m.radius_m > 0)) f.fail("mics.radius_m", "expected a radius above 0 m");
  }
  if (const json* d = f.find(mics, "mics", "acoustic_delay_s", false, "")) {
    m.acoustic_delay_s = f.number(*d, "mics.acoustic_delay_s", "engine-to-microphone delay, s");
    if (m.acoustic_delay_s < 0 || m.acoustic_delay_s > 1) f.fail("mics.acoustic_delay_s", "expected 0..1 s");
  }
  if (const json* fs = f.find(mics, "mics", "full_scale_pa", false, ""); fs && !fs->is_null()) {
    m.full_scale_pa = f.number(*fs, "mics.full_scale_pa", "Pa at PCM full scale");
    if (!(*m.full_scale_pa > 0)) f.fail("mics.full_scale_pa", "expected a value above 0 Pa");
  }
  m.mic_passband_hz = optional_positive(f, mics, "mics", "passband_hz", "upper edge of the converter's passband, Hz");
}

}  // namespace

RunManifest parse_run_json(std::string_view text, const std::string& file) {
  json root;
  try {
    root = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number beyond double (1e999)
    throw RunDirError(file + ": not valid JSON: " + e.what());
  }
  const JsonFields f(file);
  if (!root.is_object()) throw RunDirError(file + ": expected a JSON object at the top, found " + json_type_name(root));
  RunManifest m;
  m.condition = parse_condition(f, f.object(root, "", "condition"));
  parse_pressure_entry(f, f.object(root, "", "pressure"), m);
  if (const json* mics = f.find(root, "", "mics", false, ""); mics && !mics->is_null()) parse_mics_entry(f, *mics, m);
  return m;
}

namespace {

std::string at_line(const std::string& file, std::uint32_t line) {
  return file + ": line " + std::to_string(line) + ": ";
}

// The three numbers of the data row on line line_no.
void parse_csv_row(std::string_view line, const std::string& file, std::uint32_t line_no, double (&v)[3]) {
  std::size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const std::size_t comma = i < 2 ? line.find(',', start) : line.size();
    if (comma == std::string_view::npos)
      throw RunDirError(at_line(file, line_no) + std::to_string(i + 1) +
                        " field(s), expected 3 (time_s,crank_deg,pressure)");
    const std::string_view field = line.substr(start, comma - start);
    if (i == 2 && field.find(',') != std::string_view::npos)
      throw RunDirError(at_line(file, line_no) + "more than 3 fields, expected 3 (time_s,crank_deg,pressure)");
    if (!parse_number(field, v[i])) {
      static const char* names[3] = {"time_s", "crank_deg", "pressure"};
      throw RunDirError(at_line(file, line_no) + "field " + names[i] + " is " + quoted(field) +
                        ", expected a finite number");
    }
    start = comma + 1;
  }
}

// Appends a row (pressure converted to Pa) after checking it against the previous one and the plausible range.
// The rules every row meets, shared by the line-by-line reading and the fast path: time and crank angle increase
// from row to row, and the pressure is within +-1e5 bar (beyond any cylinder: a corrupted field, which would also
// overflow once converted to Pa).
bool time_increases(double t, double previous_t) { return t > previous_t; }
bool crank_increases(double crank, double previous_crank) { return crank > previous_crank; }
bool pressure_in_range(double pa) { return std::abs(pa) <= 1e10; }

void append_row(RunDir& run, const double (&v)[3], double to_pa, std::string_view line, const std::string& file,
                std::uint32_t line_no) {
  if (!run.time_s.empty()) {
    if (!time_increases(v[0], run.time_s.back()))
      throw RunDirError(at_line(file, line_no) + "time_s " + std::to_string(v[0]) +
                        " s does not increase (previous row " + std::to_string(run.time_s.back()) +
                        " s): rows out of order or repeated");
    if (!crank_increases(v[1], run.crank_deg.back()))
      throw RunDirError(at_line(file, line_no) + "crank_deg " + std::to_string(v[1]) +
                        " does not increase (previous row " + std::to_string(run.crank_deg.back()) +
                        "): crank_deg must be unwrapped and increasing");
  }
  if (!pressure_in_range(v[2] * to_pa))
    throw RunDirError(at_line(file, line_no) + "field pressure is " + quoted(line.substr(line.rfind(',') + 1)) +
                      ", expected a cylinder pressure within +-1e5 bar");
  run.time_s.push_back(v[0]);
  run.crank_deg.push_back(v[1]);
  run.pressure_pa.push_back(v[2] * to_pa);
}

// Gaps: a crank step far above the encoder's (the median step) means lost samples; so does a sudden change of the
// speed the rows imply (time jumping while the crank does not). Row i is on line i + 2: the header is line 1, and a
// blank line is only allowed after the last row.
void check_crank_gaps(const RunDir& run, const std::string& file) {
  const std::size_t n = run.time_s.size();
  const auto line_of = [](std::size_t row) { return static_cast<std::uint32_t>(row + 2); };
  const double step = crank_step_deg(run.crank_deg);
  double before = 0;  // the previous row's speed
  for (std::size_t i = 1; i < n; ++i) {
    const double d = run.crank_deg[i] - run.crank_deg[i - 1];
    if (d > (kMaxCrankGapSteps + 0.5) * step) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "crank_deg jumps by %.6g deg from %.6g to %.6g (%.1f encoder steps of %.6g deg); at most %.0f "
                    "steps expected (a few missing encoder samples are interpolated, more are lost data)",
                    d, run.crank_deg[i - 1], run.crank_deg[i], d / step, step, kMaxCrankGapSteps);
      throw RunDirError(at_line(file, line_of(i)) + buf);
    }
    const double speed = d / (run.time_s[i] - run.time_s[i - 1]);
    if (i >= 2 && (speed < before / kMaxCrankGapSteps || speed > before * kMaxCrankGapSteps)) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "time_s jumps from %.9g to %.9g s while crank_deg moves %.6g deg: the speed changes %.1f-fold "
                    "from the previous row (at most %.0f-fold expected: lost samples or a time error)",
                    run.time_s[i - 1], run.time_s[i], d, std::max(speed / before, before / speed), kMaxCrankGapSteps);
      throw RunDirError(at_line(file, line_of(i)) + buf);
    }
    before = speed;
  }
}

// The file line by line: every problem is reported at the first line that has one. The fast path below hands
// every file it does not take as it is to this.
void parse_rows_sequential(std::string_view text, const std::string& file, double to_pa, RunDir& run) {
  run.time_s.clear();
  run.crank_deg.clear();
  run.pressure_pa.clear();
  std::uint32_t line_no = 0;
  std::uint32_t blank_line = 0;  // first blank line seen (only trailing blank lines are allowed)
  TextLines lines(text);
  for (std::string_view line; lines.next(line);) {
    line_no = static_cast<std::uint32_t>(lines.number());
    if (line_no == 1) {
      if (line != kCsvHeader)
        throw RunDirError(at_line(file, 1) + "header " + quoted(line) + ", expected \"" + kCsvHeader + "\"");
      continue;
    }
    if (line.find_first_not_of(" \t") == std::string_view::npos) {
      if (blank_line == 0) blank_line = line_no;
      continue;
    }
    if (blank_line != 0) throw RunDirError(at_line(file, blank_line) + "empty line inside the data");
    double v[3];
    parse_csv_row(line, file, line_no, v);
    append_row(run, v, to_pa, line, file, line_no);
  }
  if (line_no == 0) throw RunDirError(file + ": empty file, expected the header \"" + kCsvHeader + "\" and rows");
  if (run.time_s.size() < 2)
    throw RunDirError(file + ": " + std::to_string(run.time_s.size()) + " data rows, expected at least 2");
}

// ------------------------------------------------------------------------------------------------ CSV fast path
// Most files are plain: three numbers a line, no blanks, no '+'. Their rows are parsed without per-line work
// beyond the numbers, the two halves of a large file on two threads, each into its own columns. A line that is
// not plain (a problem, or only unusual) makes parse_rows_fast give up: the file is then read sequentially,
// which reports the first problem exactly as it always has. What the fast path accepts, it reads to the same
// numbers as the sequential reading.

constexpr std::size_t kParallelCsvBytes = std::size_t{1} << 20;  // smaller files: one thread
constexpr std::size_t kReleaseBytes = std::size_t{8} << 20;      // mapped pages handed back every this many bytes

struct CsvPart {
  std::string_view text;  // whole lines of the data
  std::vector<double> t, crank, p;
  bool plain = true;       // every line was a plain row, or only blank lines follow the last row
  bool blank_end = false;  // stopped at a blank line (only blank lines follow in this part)

  void reserve(std::size_t rows) {
    for (std::vector<double>* column : {&t, &crank, &p}) {
      column->reserve(rows);
      prefer_huge_pages(*column);
    }
  }
};

// Every line of text blank as the sequential reading sees it (one trailing '\r' dropped, then only ' ' and '\t').
bool only_blank_lines(std::string_view text) {
  TextLines lines(text);
  for (std::string_view line; lines.next(line);)
    if (line.find_first_not_of(" \t") != std::string_view::npos) return false;
  return true;
}

// A plain row at p: "a,b,c" ending at '\n', "\r\n" or the end, each number finite and nothing else in the line.
// Moves p past the line; false (p anywhere) for any other line.
bool plain_row(const char*& p, const char* end, double (&v)[3]) {
  for (int i = 0; i < 3; ++i) {
    const auto [q, ec] = std::from_chars(p, end, v[i]);
    if (ec != std::errc() || !std::isfinite(v[i])) return false;
    p = q;
    if (i < 2) {
      if (p == end || *p != ',') return false;
      ++p;
    }
  }
  if (p != end && *p == '\r') ++p;
  if (p == end) return true;
  if (*p != '\n') return false;
  ++p;
  return true;
}

// The part's rows, checked as append_row checks them; stops at the first line the fast path does not take.
void parse_part(CsvPart& part, double to_pa, const MappedFile* map) {
  const char* p = part.text.data();
  const char* const end = p + part.text.size();
  const char* released = p;
  double v[3];
  while (p < end) {
    const char* const line = p;
    if (!plain_row(p, end, v)) {
      part.blank_end = only_blank_lines(std::string_view(line, static_cast<std::size_t>(end - line)));
      part.plain = part.blank_end;
      return;
    }
    const double pa = v[2] * to_pa;
    const bool follows =
        part.t.empty() || (time_increases(v[0], part.t.back()) && crank_increases(v[1], part.crank.back()));
    if (!follows || !pressure_in_range(pa)) {
      part.plain = false;
      return;
    }
    part.t.push_back(v[0]);
    part.crank.push_back(v[1]);
    part.p.push_back(pa);
    if (map && static_cast<std::size_t>(p - released) >= kReleaseBytes) {
      map->release(released, p);
      released = p;
    }
  }
}

// Rows a stretch of data holds: its length over the shortest mean line length of windows of 64 lines spread
// across it, and a little more (an estimate that falls short costs a reallocation, nothing else).
std::size_t estimated_rows(std::string_view data) {
  double bytes_per_row = 0;
  for (std::size_t w = 0; w < 4; ++w) {
    std::size_t pos = w == 0 ? 0 : data.find('\n', data.size() / 4 * w);
    if (pos == std::string_view::npos) break;
    pos += w == 0 ? 0 : 1;
    const std::size_t start = pos;
    std::size_t lines = 0;
    for (std::size_t nl; lines < 64 && (nl = data.find('\n', pos)) != std::string_view::npos; ++lines) pos = nl + 1;
    const double b = lines > 0 ? static_cast<double>(pos - start) / static_cast<double>(lines) : 0.0;
    if (b > 0 && (bytes_per_row == 0 || b < bytes_per_row)) bytes_per_row = b;
  }
  if (bytes_per_row == 0) return 16;
  return static_cast<std::size_t>(static_cast<double>(data.size()) / bytes_per_row * 1.05) + 64;
}

// Appends b's rows to a's: false when the two do not join into plain rows (b's first row must follow a's last,
// and nothing but blank lines may follow a blank line).
bool join_parts(CsvPart& a, const CsvPart& b) {
  if (!a.plain || !b.plain) return false;
  if (b.t.empty()) return true;
  if (a.blank_end) return false;
  if (!a.t.empty() && !(time_increases(b.t.front(), a.t.back()) && crank_increases(b.crank.front(), a.crank.back())))
    return false;
  a.t.insert(a.t.end(), b.t.begin(), b.t.end());
  a.crank.insert(a.crank.end(), b.crank.begin(), b.crank.end());
  a.p.insert(a.p.end(), b.p.begin(), b.p.end());
  return true;
}

// The fast path (text without its byte-order mark): fills run's columns and returns true when the header is
// right and every line is a plain row or a trailing blank line; false otherwise (run's columns unspecified).
bool parse_rows_fast(std::string_view text, double to_pa, RunDir& run, const MappedFile* map) {
  const std::size_t nl = text.find('\n');
  std::string_view header = text.substr(0, nl);
  if (!header.empty() && header.back() == '\r') header.remove_suffix(1);
  if (nl == std::string_view::npos || header != kCsvHeader) return false;
  const std::string_view data = text.substr(nl + 1);
  CsvPart first, second;
  first.text = data;
  const std::size_t cut = data.size() >= kParallelCsvBytes ? data.find('\n', data.size() / 2) : std::string_view::npos;
  if (cut == std::string_view::npos || cut + 1 >= data.size()) {
    first.reserve(estimated_rows(data));
    parse_part(first, to_pa, map);
  } else {
    first.text = data.substr(0, cut + 1);
    second.text = data.substr(cut + 1);
    run_both(
        [&] {
          first.reserve(estimated_rows(data));  // room for both parts: joining them moves no row twice
          parse_part(first, to_pa, map);
        },
        [&] {
          second.reserve(estimated_rows(second.text));
          parse_part(second, to_pa, map);
        });
  }
  if (!join_parts(first, second) || first.t.size() < 2) return false;
  run.time_s = std::move(first.t);
  run.crank_deg = std::move(first.crank);
  run.pressure_pa = std::move(first.p);
  return true;
}

// pressure.csv's text; map: the file it is mapped from, whose pages are released as they are parsed (or null).
void parse_pressure_text(std::string_view text, const std::string& file, double to_pa, RunDir& run,
                         const MappedFile* map) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 byte-order mark
  if (!parse_rows_fast(text, to_pa, run, map)) parse_rows_sequential(text, file, to_pa, run);
  check_crank_gaps(run, file);
}

}  // namespace

double crank_step_deg(const std::vector<double>& crank_deg) {
  if (crank_deg.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t n = crank_deg.size() - 1;  // steps
  const std::size_t k = n / 2;
  const auto step = [&crank_deg](std::size_t i) { return crank_deg[i + 1] - crank_deg[i]; };
  // A sorted sample of the steps brackets the median; one pass counts the steps below and within the bracket.
  constexpr std::size_t kSample = 4096, kMargin = 128;  // the median is within +-4 sigma of the sample's
  if (n >= 16 * kSample) {
    std::vector<double> sample(kSample);
    for (std::size_t j = 0; j < kSample; ++j) sample[j] = step(j * n / kSample);
    std::sort(sample.begin(), sample.end());
    const double lo = sample[kSample / 2 - kMargin], hi = sample[kSample / 2 + kMargin];
    std::size_t below = 0, within = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double d = step(i);
      below += d < lo;
      within += d <= hi;
    }
    within -= below;
    if (below <= k && k < below + within) {
      if (lo == hi) return lo;
      std::vector<double> mid;
      mid.reserve(within);
      for (std::size_t i = 0; i < n; ++i)
        if (const double d = step(i); d >= lo && d <= hi) mid.push_back(d);
      std::nth_element(mid.begin(), mid.begin() + static_cast<std::ptrdiff_t>(k - below), mid.end());
      return mid[k - below];
    }
  }
  std::vector<double> steps(n);  // small, or a bracket that missed: every step
  for (std::size_t i = 0; i < n; ++i) steps[i] = step(i);
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(k), steps.end());
  return steps[k];
}

void parse_pressure_csv(std::string_view text, const std::string& file, double to_pa, RunDir& run) {
  parse_pressure_text(text, file, to_pa, run, nullptr);
}

void read_mics_wav(const std::filesystem::path& file, std::uint32_t channels, std::optional<double> full_scale_pa,
                   RunDir& run) {
  SF_INFO info{};
  SNDFILE* sf = sf_open(file.c_str(), SFM_READ, &info);
  if (!sf)
    throw RunDirError(file.string() + ": cannot read as a sound file (" + sf_strerror(nullptr) +
                      "); expected a WAV of IEEE float samples in Pa");
  read_sound(sf, info, file.string(), channels, full_scale_pa, run);
}

void parse_mics_wav(const std::uint8_t* data, std::size_t size, const std::string& file, std::uint32_t channels,
                    std::optional<double> full_scale_pa, RunDir& run) {
  SF_VIRTUAL_IO io{mem_length, mem_seek, mem_read, mem_write, mem_tell};
  MemoryFile mem{data, static_cast<sf_count_t>(size), 0};
  SF_INFO info{};
  SNDFILE* sf = sf_open_virtual(&io, SFM_READ, &info, &mem);
  if (!sf)
    throw RunDirError(file + ": cannot read as a sound file (" + sf_strerror(nullptr) +
                      "); expected a WAV of IEEE float samples in Pa");
  read_sound(sf, info, file, channels, full_scale_pa, run);
}

RunManifest read_run_manifest(const std::filesystem::path& dir) {
  const std::filesystem::path json_path = dir / "run.json";
  return parse_run_json(read_text_file(json_path, "run.json (is this a run directory?)"), json_path.string());
}

namespace {

// DIR's pressure file into run, its rows' mean speed checked against run.json's.
void read_pressure(const std::filesystem::path& dir, const RunManifest& m, RunDir& run) {
  const std::filesystem::path csv = dir / m.pressure_file;
  if (const MappedFile map(csv); map.mapped())
    parse_pressure_text(map.text(), csv.string(), m.pressure_to_pa, run, &map);
  else  // not a regular file, empty, or not there: the reader names the problem
    parse_pressure_csv(read_text_file(csv, "the pressure file named by pressure.file in run.json"), csv.string(),
                       m.pressure_to_pa, run);
  // The rows' mean speed must be the declared one: otherwise time_s or crank_deg is in other units (ms, rad)
  // or rows are missing, and every frequency downstream would be silently wrong. (A null speed is unknown: the
  // rows' speed is then the run's.)
  const double mean_rpm = encoder_speed_rpm(run);
  if (!std::isnan(m.condition.speed_rpm) &&
      !(std::abs(mean_rpm - m.condition.speed_rpm) <= kSpeedTolerance * m.condition.speed_rpm)) {
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  ": the rows imply %.6g rpm (crank_deg %.6g..%.6g over time_s %.9g..%.9g s), run.json's "
                  "condition.speed_rpm is %.6g (expected within %.0f %%: time in s, crank angle in deg)",
                  mean_rpm, run.crank_deg.front(), run.crank_deg.back(), run.time_s.front(), run.time_s.back(),
                  m.condition.speed_rpm, 100 * kSpeedTolerance);
    throw RunDirError(csv.string() + buf);
  }
}

}  // namespace

RunDir read_run_dir(const std::filesystem::path& dir) {
  const RunManifest m = read_run_manifest(dir);
  RunDir run;
  run.condition = m.condition;
  // The microphones are read on another thread while the pressure is parsed (each fills its own members of run);
  // a problem with the pressure file is still reported before one with the microphones'.
  run_both([&] { read_pressure(dir, m, run); },
           [&] {
             if (m.has_mics)
               read_mics_wav(dir / m.mics_file, static_cast<std::uint32_t>(m.mic_positions_m.size()), m.full_scale_pa,
                             run);
           });
  if (m.has_mics) {
    run.mic_positions_m = m.mic_positions_m;
    run.radius_m = m.radius_m;
    run.acoustic_delay_s = m.acoustic_delay_s;
    run.mic_passband_hz = m.mic_passband_hz;
  }
  run.pressure_noise_floor_bar = m.pressure_noise_floor_bar;
  run.pressure_edges_per_rev = m.pressure_edges_per_rev;
  return run;
}

double encoder_speed_rpm(const RunDir& run) {
  const std::size_t n = std::min(run.time_s.size(), run.crank_deg.size());
  if (n < 2) return std::numeric_limits<double>::quiet_NaN();
  return (run.crank_deg[n - 1] - run.crank_deg.front()) / (run.time_s[n - 1] - run.time_s.front()) / 6.0;
}

namespace {

// Unknown (NaN) as null, as run.json spells it.
json number_or_null(double v) { return std::isnan(v) ? json(nullptr) : json(v); }

json run_json(const RunDir& run, const std::string& pressure_units) {
  const RunCondition& c = run.condition;
  json root;
  root["condition"] = {{"name", c.name},
                       {"speed_rpm", number_or_null(c.speed_rpm)},
                       {"load_nm", number_or_null(c.load_nm)},
                       {"soi_deg_btdc", number_or_null(c.soi_deg_btdc)},
                       {"rail_pressure_bar", c.rail_pressure_bar ? json(*c.rail_pressure_bar) : json(nullptr)},
                       {"motored", c.motored_known ? json(c.motored) : json(nullptr)}};
  root["pressure"] = {{"file", "pressure.csv"}, {"units", pressure_units}};
  if (run.pressure_noise_floor_bar) root["pressure"]["noise_floor_bar"] = *run.pressure_noise_floor_bar;
  if (run.pressure_edges_per_rev) root["pressure"]["encoder_edges_per_rev"] = *run.pressure_edges_per_rev;
  if (run.mic_count > 0) {
    json positions = json::array();
    for (const auto& p : run.mic_positions_m) positions.push_back({p[0], p[1], p[2]});
    root["mics"] = {{"file", "mics.wav"}, {"units", "Pa"}, {"positions_m", positions}, {"radius_m", run.radius_m}};
    if (run.acoustic_delay_s >= 0) root["mics"]["acoustic_delay_s"] = run.acoustic_delay_s;
    if (run.mic_passband_hz) root["mics"]["passband_hz"] = *run.mic_passband_hz;
  }
  return root;
}

}  // namespace

void write_run_dir(const std::filesystem::path& dir, const RunDir& run, const std::string& pressure_units) {
  double from_pa;
  if (pressure_units == "bar")
    from_pa = 1e-5;
  else if (pressure_units == "Pa")
    from_pa = 1.0;
  else
    throw RunDirError(dir.string() + ": pressure units \"" + pressure_units + "\", expected \"bar\" or \"Pa\"");
  const std::size_t n = run.time_s.size();
  if (run.crank_deg.size() != n || run.pressure_pa.size() != n)
    throw RunDirError(dir.string() + ": time, crank and pressure columns of different lengths");
  if (run.mic_count > 0 && (run.mic_positions_m.size() != run.mic_count || run.mic_pa.size() % run.mic_count != 0))
    throw RunDirError(dir.string() + ": microphone data does not match the " + std::to_string(run.mic_count) +
                      " positions");
  if (const auto& floor = run.pressure_noise_floor_bar; floor && !(*floor >= 0 && std::isfinite(*floor)))
    throw RunDirError(dir.string() + ": pressure noise floor " + std::to_string(*floor) +
                      " bar, expected a finite value >= 0");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw RunDirError(dir.string() + ": cannot create directory (" + ec.message() + ")");

  {
    const auto path = dir / "run.json";
    std::ofstream out(path);
    out << run_json(run, pressure_units).dump(2) << "\n";
    if (!out) throw RunDirError(path.string() + ": cannot write");
  }
  {
    const auto path = dir / "pressure.csv";
    std::ofstream out(path, std::ios::binary);
    if (!out) throw RunDirError(path.string() + ": cannot write");
    std::string buf;
    buf.reserve(1 << 20);
    buf += kCsvHeader;
    buf += '\n';
    char num[64];
    const auto put = [&](double v, char sep) {  // shortest text that reads back to the same double
      const auto r = std::to_chars(num, num + sizeof num, v);
      buf.append(num, r.ptr);
      buf += sep;
    };
    for (std::size_t i = 0; i < n; ++i) {
      put(run.time_s[i], ',');
      put(run.crank_deg[i], ',');
      put(run.pressure_pa[i] * from_pa, '\n');
      if (buf.size() > (1 << 20) - 256) {
        out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
        buf.clear();
      }
    }
    out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
    if (!out) throw RunDirError(path.string() + ": cannot write");
  }
  if (run.mic_count > 0) {
    const auto path = dir / "mics.wav";
    SF_INFO info{};
    info.samplerate = static_cast<int>(std::lround(run.mic_rate_hz));
    info.channels = static_cast<int>(run.mic_count);
    // RF64 that libsndfile writes as plain WAV when it stays below 4 GiB.
    info.format = SF_FORMAT_RF64 | SF_FORMAT_FLOAT;
    SNDFILE* sf = sf_open(path.c_str(), SFM_WRITE, &info);
    if (!sf) throw RunDirError(path.string() + ": cannot write (" + sf_strerror(nullptr) + ")");
    sf_command(sf, SFC_RF64_AUTO_DOWNGRADE, nullptr, SF_TRUE);
    const sf_count_t frames = static_cast<sf_count_t>(run.mic_pa.size() / run.mic_count);
    const sf_count_t written = sf_writef_float(sf, run.mic_pa.data(), frames);
    const int close_err = sf_close(sf);
    if (written != frames || close_err != 0) throw RunDirError(path.string() + ": cannot write (disk full?)");
  }
}

}  // namespace noisemon::drivers
