// Issue 28's whole-process goal: `shapeid describe --local --spec rphsd FILE` on a 10^6-point
// binary PCD beside bench/plain_rphsd.cc (a plain -O2 program that freads the file and computes
// the same descriptor with scalar loops), each run as a fresh process, medians of --runs runs
// taken alternately in one run of this program. Checks that both print the same descriptor
// within float tolerance, so that the comparison is fair. Then where shapeid's time goes: the
// process start-up (the same command on a 4-point file), the same command on one core (--threads
// 1), and in this process the reading (ReadPointCloud) and the descriptor (Compute, validation
// included). Run from a release build:
//   build/release/bench/describe_file_bench [--points 1000000] [--runs 9]

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "CLI/CLI.hpp"
#include "absl/strings/str_format.h"
#include "bench/host_info.h"
#include "core/descriptor_registry.h"
#include "core/io/pcd_writer.h"
#include "core/io/point_cloud_reader.h"
#include "core/random.h"

extern char** environ;

namespace shapeid {
namespace {

double Now() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// A torus surface (radii 3 and 1) in a scanner's coordinates, points uniform in its
// parameters: a real-looking, non-convex surface without the symmetry of a sphere.
PointCloud Torus(size_t n) {
  SplitMix64 random(28);
  PointCloud cloud;
  cloud.Reserve(n);
  constexpr double kTwoPi = 6.283185307179586;
  for (size_t i = 0; i < n; ++i) {
    const double u = kTwoPi * random.Uniform(), v = kTwoPi * random.Uniform();
    const double r = 3 + std::cos(v);
    cloud.Add(static_cast<float>(12.5 + r * std::cos(u)), static_cast<float>(-4 + r * std::sin(u)),
              static_cast<float>(1.5 + std::sin(v)));
  }
  return cloud;
}

// Runs `argv` with its standard output in `out` (a file) and returns the wall time from the
// spawn to the end of the process, or a negative number when it failed.
double TimeProcess(const std::vector<std::string>& args, const std::string& out) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  const double start = Now();
  const int spawned = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  const double seconds = Now() - start;
  return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? seconds : -1;
}

// The numbers after the file name on the first line of `path`.
std::vector<double> Values(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "r");
  std::vector<double> values;
  if (f == nullptr) return values;
  char name[4096];
  if (std::fscanf(f, "%4095s", name) == 1) {
    for (double v; std::fscanf(f, "%lf", &v) == 1;) values.push_back(v);
  }
  std::fclose(f);
  return values;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace
}  // namespace shapeid

int main(int argc, char** argv) {
  using namespace shapeid;
  size_t points = 1000000;
  int runs = 9;
  std::string dir = "/tmp/shapeid_describe_file_bench";
  std::string shapeid = SHAPEID_CLI_PATH;
  std::string plain = PLAIN_RPHSD_PATH;
  CLI::App app("The whole `shapeid describe --local --spec rphsd` process beside a plain program");
  app.add_option("--points", points, "Points in the file")->capture_default_str();
  app.add_option("--runs", runs, "Runs of each program (the median is printed)")
      ->capture_default_str();
  app.add_option("--dir", dir, "Where the file and outputs are written")->capture_default_str();
  app.add_option("--shapeid", shapeid, "The shapeid CLI")->capture_default_str();
  app.add_option("--plain", plain, "The plain scalar program")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::filesystem::create_directories(dir);
  const std::string file = dir + "/torus.pcd";
  if (absl::Status written = WritePcd(file, Torus(points), PcdEncoding::kBinary); !written.ok()) {
    std::fprintf(stderr, "%s\n", written.ToString().c_str());
    return 1;
  }
  const std::vector<std::string> shapeid_args = {shapeid,  "describe", "--local",
                                                 "--spec", "rphsd",    file};
  // The same on one core: describe --local uses every core for a large cloud by default.
  const std::vector<std::string> one_core_args = {shapeid, "describe", "--local", "--threads",
                                                  "1",     "--spec",   "rphsd",   file};
  const std::vector<std::string> plain_args = {plain, file};
  const std::string shapeid_out = dir + "/shapeid.txt", plain_out = dir + "/plain.txt";
  // One run each first: the page cache holds the file and both binaries from then on.
  if (TimeProcess(shapeid_args, shapeid_out) < 0 || TimeProcess(plain_args, plain_out) < 0) {
    std::fprintf(stderr, "a program failed; see %s and %s\n", shapeid_out.c_str(),
                 plain_out.c_str());
    return 1;
  }
  const std::vector<double> a = Values(shapeid_out), b = Values(plain_out);
  double worst = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) {
    worst = std::max(worst, std::fabs(a[i] - b[i]) / std::max(1e-3, std::fabs(b[i])));
  }
  if (a.size() != 81 || b.size() != 81 || worst > 1e-4) {
    std::fprintf(stderr, "the descriptors differ (%zu and %zu values, relative difference %g)\n",
                 a.size(), b.size(), worst);
    return 1;
  }
  std::vector<double> shapeid_s, one_core_s, plain_s;
  for (int r = 0; r < runs; ++r) {  // alternating, so that the machine's load hits all alike
    shapeid_s.push_back(TimeProcess(shapeid_args, shapeid_out));
    one_core_s.push_back(TimeProcess(one_core_args, shapeid_out));
    plain_s.push_back(TimeProcess(plain_args, plain_out));
  }
  if (*std::min_element(shapeid_s.begin(), shapeid_s.end()) < 0 ||
      *std::min_element(one_core_s.begin(), one_core_s.end()) < 0 ||
      *std::min_element(plain_s.begin(), plain_s.end()) < 0) {
    std::fprintf(stderr, "a program failed during the timed runs\n");
    return 1;
  }
  // The floors: start-up, then reading and describing in this process.
  const std::string tiny = dir + "/tiny.xyz";
  std::FILE* t = std::fopen(tiny.c_str(), "w");
  std::fputs("0 0 0\n1 0 0\n0 1 0\n0 0 1\n", t);
  std::fclose(t);
  std::vector<std::string> tiny_args = shapeid_args;
  tiny_args.back() = tiny;
  std::vector<double> startup_s, read_s, compute_s;
  const std::unique_ptr<Descriptor> rphsd = CreateDescriptor("rphsd").value();
  std::vector<float> values;
  for (int r = 0; r < runs; ++r) {
    startup_s.push_back(TimeProcess(tiny_args, dir + "/tiny.txt"));
    const double start = Now();
    absl::StatusOr<ReadResult> read = ReadPointCloud(file);
    const double read_end = Now();
    if (!read.ok() || !rphsd->Compute(read->cloud, &values).ok()) {
      std::fprintf(stderr, "reading or describing in process failed\n");
      return 1;
    }
    read_s.push_back(read_end - start);
    compute_s.push_back(Now() - read_end);
  }
  const double s = Median(shapeid_s), p = Median(plain_s);
  std::printf("CPU: %s; load average %s\n", bench::CpuModel().c_str(),
              bench::LoadAverages().c_str());
  std::printf("file: %s, %zu points, %.1f MB\n", file.c_str(), points,
              static_cast<double>(std::filesystem::file_size(file)) / 1e6);
  std::printf("descriptors agree: largest relative difference %.2g over 81 values\n", worst);
  std::printf("| program | median ms (%d runs) | min ms |\n|---|---:|---:|\n", runs);
  std::printf("| shapeid describe --local --spec rphsd | %.1f | %.1f |\n", 1e3 * s,
              1e3 * *std::min_element(shapeid_s.begin(), shapeid_s.end()));
  std::printf("| the same with --threads 1 | %.1f | %.1f |\n", 1e3 * Median(one_core_s),
              1e3 * *std::min_element(one_core_s.begin(), one_core_s.end()));
  std::printf("| plain scalar program (-O2) | %.1f | %.1f |\n", 1e3 * p,
              1e3 * *std::min_element(plain_s.begin(), plain_s.end()));
  std::printf("| shapeid describe on a 4-point file (start-up) | %.1f | %.1f |\n",
              1e3 * Median(startup_s), 1e3 * *std::min_element(startup_s.begin(), startup_s.end()));
  std::printf("| in process: ReadPointCloud | %.1f | %.1f |\n", 1e3 * Median(read_s),
              1e3 * *std::min_element(read_s.begin(), read_s.end()));
  std::printf("| in process: rphsd Compute (with ValidateCloud), one thread | %.1f | %.1f |\n",
              1e3 * Median(compute_s), 1e3 * *std::min_element(compute_s.begin(), compute_s.end()));
  std::printf("ratio shapeid / plain: %.3fx (one core: %.3fx)\n", s / p, Median(one_core_s) / p);
  return 0;
}
