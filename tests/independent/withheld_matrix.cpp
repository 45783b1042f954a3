// The whole withheld-effect family on the independent cell (withheld.hpp), every case at every seed, run through the
// real `noisemon diagnose` and printed as the Markdown table the README carries. A proof run by hand (about 30 s of
// one core per case), not part of the test suite, whose tests/independent test runs a few of these cases.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "withheld.hpp"

namespace {

namespace fs = std::filesystem;

constexpr const char* kUsage =
    "usage: indep_withheld_matrix [--cell 1|2] [--seeds 1,2] [--jobs 2] [--only TEXT] [--out TABLE.md]\n"
    "                             [--dir SCRATCH] [--data REAL_DATA_DIR] [--noisemon PATH]\n"
    "Runs every withheld-effect case of the independent cell (tests/independent/withheld.hpp) at every seed through\n"
    "`noisemon diagnose` and prints the results as a Markdown table (also written to --out).\n"
    "  --cell    1: the first cell's catalogue (default); 2: the second cell's (three speeds, two loads each)\n"
    "  --seeds   noise seeds of the cell, comma-separated (default 1,2)\n"
    "  --jobs    diagnoses run at once (default 2)\n"
    "  --only    only the cases whose label contains TEXT\n"
    "  --dir     scratch directory (default: a fresh one under the system's temp dir, removed at the end)\n";

struct Args {
  std::vector<std::uint64_t> seeds{1, 2};
  unsigned jobs = 2;
  int cell = 1;
  std::string only, out, dir, data = std::string(NOISEMON_SHARED_DIR) + "/data/real", noisemon = NOISEMON_PATH;
};

std::vector<std::uint64_t> parse_seeds(const std::string& text) {
  std::vector<std::uint64_t> s;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t end = std::min(text.find(',', at), text.size());
    s.push_back(std::stoull(text.substr(at, end - at)));
    at = end + 1;
  }
  return s;
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--help" || k == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "indep_withheld_matrix: %s needs a value\n%s", k.c_str(), kUsage);
      std::exit(2);
    }
    const std::string v = argv[++i];
    if (k == "--seeds")
      a.seeds = parse_seeds(v);
    else if (k == "--cell" && (v == "1" || v == "2"))
      a.cell = std::stoi(v);
    else if (k == "--jobs")
      a.jobs = static_cast<unsigned>(std::max(1, std::stoi(v)));
    else if (k == "--only")
      a.only = v;
    else if (k == "--out")
      a.out = v;
    else if (k == "--dir")
      a.dir = v;
    else if (k == "--data")
      a.data = v;
    else if (k == "--noisemon")
      a.noisemon = v;
    else {
      std::fprintf(stderr, "indep_withheld_matrix: unknown option %s\n%s", k.c_str(), kUsage);
      std::exit(2);
    }
  }
  return a;
}

struct Job {
  indep::Case c;
  std::uint64_t seed;
  indep::Outcome o;
};

}  // namespace

int main(int argc, char** argv) try {
  const Args args = parse(argc, argv);
  const indep::Sources src = indep::load_sources(args.data);
  const indep::Chain chain = args.cell == 2 ? indep::second_cell_chain(1) : indep::Chain{};
  const double engine = indep::engine_level_dba(src, chain);
  std::printf("the independent cell %d's engine: %.1f dB(A) array average at 1800 rpm\n", args.cell, engine);
  std::vector<Job> jobs;
  for (const indep::Case& c : indep::cell_catalogue(src, args.cell))
    if (c.label.find(args.only) != std::string::npos)
      for (std::uint64_t s : args.seeds) jobs.push_back({c, s, {}});
  const bool own_dir = args.dir.empty();
  const fs::path root =
      own_dir ? fs::temp_directory_path() / ("indep-matrix-" + std::to_string(::getpid())) : fs::path(args.dir);
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex print;
  auto worker = [&] {
    for (std::size_t i; (i = next++) < jobs.size();) {
      Job& j = jobs[i];
      j.o = indep::diagnose_case(src, j.c, j.seed, root / (j.c.label + "-" + std::to_string(j.seed)), args.noisemon);
      const std::lock_guard<std::mutex> lock(print);
      std::printf("[%zu/%zu] %.0f s %s%s", ++done, jobs.size(), j.o.seconds, indep::table_row(j.c, j.seed, j.o).c_str(),
                  j.o.error.empty() ? "" : (j.o.error + "\n").c_str());
      std::fflush(stdout);
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < args.jobs; ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();
  std::string table = indep::table_header();
  int right = 0, params_right = 0, params_checked = 0;
  for (const Job& j : jobs) {
    table += indep::table_row(j.c, j.seed, j.o);
    right += j.o.verdict_right ? 1 : 0;
    params_checked += j.o.params_checked ? 1 : 0;
    params_right += j.o.params_checked && j.o.params_right ? 1 : 0;
  }
  table += "\nPrimary verdict right in " + std::to_string(right) + " of " + std::to_string(jobs.size()) +
           " runs; fitted parameters within tolerance in " + std::to_string(params_right) + " of " +
           std::to_string(params_checked) + " checked.\n";
  std::fputs(("\n" + table).c_str(), stdout);
  if (!args.out.empty()) std::ofstream(args.out) << table;
  if (own_dir) fs::remove_all(root);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "indep_withheld_matrix: %s\n", e.what());
  return 1;
}
