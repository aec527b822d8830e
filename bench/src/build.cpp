// bench build: grid conversion speed, ours against gdalwarp.
//
// Both sides convert the same DTED2 sources onto the same target grid (CRS,
// extent, post spacing) in one run. Measurements alternate between the sides
// and every one is repeated, reporting the median, because the machine is
// shared and noisy: a burst of load then falls on both sides alike.
#include "sandtable/bench/build.h"

#include "process.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

#include "sandtable/base/stats.h"
#include "sandtable/converters/elevation.h"

extern char** environ;

namespace sandtable::bench {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// The issue asks for a target of at least this many posts a side.
constexpr std::uint32_t kMinPostsPerAxis = 5000;
/// The UTM grid is the largest rectangle inside the projected lon/lat square
/// (meridians converge and tilt), a few per cent smaller than the square.
/// This margin on the synthesized square keeps the grid >= 5000 posts
/// (measured: a 161 km square at 42.3 N gives 5265 x 5246 posts at 30 m).
constexpr double kInnerMargin = 1.04;

/// A benchmark step failed; the message is for the user as it stands.
struct BenchError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One timed run.
struct Sample {
  double wallS = 0;
  double cpuS = 0;       ///< user + system over all threads
  double resampleS = 0;  ///< ours only: ElevationReport::resampleSeconds
  /// Ours only: seconds per build stage, in order (see StageClock).
  std::vector<std::pair<std::string, double>> stages;
};

/// One of our kernels as BuildBenchOptions::kernels names it. "bilinear" keeps GDAL's
/// samples (fit "posts"): GDALWarp's bilinear kernel, as gdalwarp -r
/// bilinear, reading our in-memory source image instead of the VRT;
/// "bilinear-triangles" adds the least-squares triangle fit that
/// `sandtable build --resample bilinear` does by default.
struct OurKernel {
  std::string name, resample, fit;
};

const std::vector<std::string> kKernelNames = {"weighted", "bilinear", "bilinear-triangles", "cubic", "average"};

OurKernel ourKernel(const std::string& name) {
  if (name == "bilinear-triangles") return {name, "bilinear", "triangles"};
  return {name, name, "posts"};
}

/// The target grid, as our build chose it; gdalwarp is given the same.
struct TargetGrid {
  std::uint32_t postsX = 0, postsZ = 0;
  double spacing = 0, west = 0, north = 0, east = 0, south = 0;  ///< outer post centres
  std::string crsName, crsWkt;
  std::uint64_t posts() const { return std::uint64_t(postsX) * postsZ; }
};

/// Where the sources are and which lon/lat square to convert.
struct Input {
  fs::path sources;
  std::optional<std::array<double, 4>> extent;  ///< west, south, east, north
  std::string description;
  std::size_t files = 0;
};

/// The gdalwarp side's tools and shared inputs.
struct Gdal {
  fs::path warp, buildVrt, vrt, wkt;
  std::string version;
};

// ------------------------------------------------------------ small helpers

/// Progress lines go to the caller, so its stdout stays the report.
__attribute__((format(printf, 2, 3))) void note(const Notes& notes, const char* format, ...) {
  char line[1024];
  std::va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  notes.say(line);
}

void throwIfCancelled() {
  if (convert::cancelRequested()) throw BenchError("cancelled");
}

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double medianOf(const std::vector<Sample>& s, double Sample::*field) {
  std::vector<double> v;
  for (const auto& x : s) v.push_back(x.*field);
  return stats::median(v);
}

double cpuSeconds(const rusage& ru) {
  auto tv = [](const timeval& t) { return double(t.tv_sec) + double(t.tv_usec) * 1e-6; };
  return tv(ru.ru_utime) + tv(ru.ru_stime);
}

double processCpuSeconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return cpuSeconds(ru);
}

/// 1-minute load average: the machine is shared, so the report says how busy it was.
double loadAverage() {
  std::ifstream f("/proc/loadavg");
  double l = NAN;
  f >> l;
  return l;
}

unsigned cpuCount() { return std::max(1u, std::thread::hardware_concurrency()); }

std::string fmt(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

std::optional<fs::path> findOnPath(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::string p = path ? path : "/usr/local/bin:/usr/bin:/bin";
  for (std::size_t a = 0; a <= p.size();) {
    const std::size_t b = std::min(p.find(':', a), p.size());
    const fs::path candidate = fs::path(p.substr(a, b - a).empty() ? "." : p.substr(a, b - a)) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
    a = b + 1;
  }
  return std::nullopt;
}

std::string lastLines(const fs::path& file, std::size_t count) {
  std::ifstream f(file);
  std::deque<std::string> lines;
  for (std::string line; std::getline(f, line);) {
    lines.push_back(line);
    if (lines.size() > count) lines.pop_front();
  }
  std::string out;
  for (const auto& l : lines) out += "\n  | " + l;
  return out;
}

/// A fresh directory under $TMPDIR, removed at the end unless BuildBenchOptions::keep.
class WorkDir {
 public:
  explicit WorkDir(bool keep) : keep_(keep) {
    std::string tmpl = (fs::temp_directory_path() / "sandtable-bench-XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) throw BenchError("cannot create a work directory: " + std::string(std::strerror(errno)));
    path_ = tmpl;
  }
  ~WorkDir() {
    std::error_code ec;
    if (!keep_) fs::remove_all(path_, ec);
  }
  WorkDir(const WorkDir&) = delete;
  WorkDir& operator=(const WorkDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
  bool keep_;
};

/// Splits a build's wall time into its stages from the progress callback:
/// a stage runs from the previous stage's last report to its own last
/// report, so gaps (opening the mosaic, say) count to the stage they lead
/// into, and the stages add up to the whole build with "finishing" (grid
/// fsync, checksums, manifest, publish) after the last report.
class StageClock {
 public:
  StageClock() : start_(Clock::now()) {}
  /// Called from worker threads.
  void report(const std::string& stage) {
    std::lock_guard lock(mutex_);
    const auto now = Clock::now();
    if (stages_.empty() || stages_.back().first != stage) stages_.emplace_back(stage, now);
    stages_.back().second = now;
  }
  std::vector<std::pair<std::string, double>> finish() const {
    std::vector<std::pair<std::string, double>> out;
    auto from = start_;
    for (const auto& [name, last] : stages_) {
      out.emplace_back(name, std::chrono::duration<double>(last - from).count());
      from = last;
    }
    out.emplace_back("finishing", seconds(from));
    return out;
  }

 private:
  Clock::time_point start_;
  std::vector<std::pair<std::string, Clock::time_point>> stages_;
  std::mutex mutex_;
};

// ------------------------------------------------------------ subprocesses

/// Runs argv (argv[0] a path, no shell: no quoting issues) with stdout and
/// stderr to `log`. Throws with the log's tail unless it exits 0.
Sample runProcess(const std::vector<std::string>& argv, const fs::path& log) {
  const auto t0 = Clock::now();
  int rc = 0;
  const pid_t pid = detail::spawnLogged(argv, log, rc);
  if (rc != 0) throw BenchError("cannot run " + argv[0] + ": " + std::strerror(rc));
  int status = 0;
  rusage ru{};
  // A signal (Ctrl-C reaches the child too) interrupts the wait; keep waiting.
  while (::wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
  }
  Sample s{seconds(t0), cpuSeconds(ru), 0, {}};
  throwIfCancelled();
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw BenchError(fs::path(argv[0]).filename().string() + " failed (log " + log.string() + "):" +
                     lastLines(log, 15));
  }
  return s;
}

fs::path synthExecutable(const BuildBenchOptions& a) {
  if (!a.synthExecutable.empty()) return a.synthExecutable;
  std::error_code ec;
  fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path("/proc/self/exe") : p;
}

// ------------------------------------------------------------ input

std::array<double, 4> synthBounds(const fs::path& synthJson) {
  std::ifstream f(synthJson);
  try {
    const auto j = nlohmann::json::parse(f);
    const auto& b = j.at("bounds");
    return {b.at("west").get<double>(), b.at("south").get<double>(), b.at("east").get<double>(),
            b.at("north").get<double>()};
  } catch (const nlohmann::json::exception& e) {
    throw BenchError("cannot read the square from " + synthJson.string() + ": " + e.what());
  }
}

double autoSizeKm(double spacing) { return std::ceil(kMinPostsPerAxis * spacing * kInnerMargin / 1000.0); }

/// Uses the input (its dted2/ tree when there is one, and the square from
/// its synth.json), or synthesizes a square with this same binary.
Input prepareInput(const BuildBenchOptions& a, const fs::path& work, const Notes& notes) {
  Input in;
  fs::path dir = a.input;
  if (a.input.empty()) {
    dir = work / "synth";
    const double km = a.sizeKm > 0 ? a.sizeKm : autoSizeKm(a.spacing);
    note(notes, "synthesizing a %.0f km square into %s (not timed)", km, dir.c_str());
    const auto t0 = Clock::now();
    runProcess({synthExecutable(a).string(), "synth", "-o", dir.string(), "--size-km", fmt(km), "--threads",
                std::to_string(a.threads)},
               work / "synth.log");
    note(notes, "synthesized in %.1f s", seconds(t0));
    in.description = "synthesized " + fmt(km) + " km square, DTED2 (1 arc-second)";
  } else {
    if (!fs::is_directory(dir)) throw BenchError("BuildBenchOptions::input " + a.input + " is not a directory");
    in.description = "BuildBenchOptions::input " + a.input;
  }
  in.sources = fs::is_directory(dir / "dted2") ? dir / "dted2" : dir;
  if (fs::exists(dir / "synth.json")) in.extent = synthBounds(dir / "synth.json");
  auto files = convert::expandSources({in.sources.string()});
  if (!files || files.value().empty()) throw BenchError("no elevation sources under " + in.sources.string());
  in.files = files.value().size();
  return in;
}

// ------------------------------------------------------------ our side

/// One full in-process build (sources to published database, as
/// `sandtable build` does it), wall-clocked. The previous output is removed
/// before the clock starts so deleting it is not timed.
Sample runOurs(const BuildBenchOptions& a, const Input& in, const std::string& kernel, const fs::path& out, TargetGrid* grid) {
  std::error_code ec;
  fs::remove_all(out, ec);
  const OurKernel k = ourKernel(kernel);
  convert::ElevationOptions o;
  o.sources = {in.sources.string()};
  o.output = out.string();
  o.crs = "utm";
  o.spacing = a.spacing;
  o.resample = k.resample;
  o.fit = k.fit;
  o.extent = in.extent;
  o.threads = a.threads;
  o.modules = false;  // grid conversion only, as gdalwarp does; `bench modules` times the rest
  const double cpu0 = processCpuSeconds();
  const auto t0 = Clock::now();
  StageClock stages;
  auto r = convert::buildElevation(o, [&](double, const std::string& stage) { stages.report(stage); });
  Sample s{seconds(t0), processCpuSeconds() - cpu0, 0, stages.finish()};
  throwIfCancelled();
  if (!r) throw BenchError("our build (" + kernel + ") failed: " + r.error());
  s.resampleS = r->resampleSeconds;
  if (grid) {
    const auto& m = r->manifest;
    *grid = {m.postsX, m.postsZ, m.spacing, m.originEasting, m.originNorthing, m.eastEasting(),
             m.southNorthing(), m.crsName, m.crsWkt};
  }
  if (!a.keep) fs::remove_all(out, ec);
  return s;
}

// ------------------------------------------------------------ gdalwarp side

Gdal findGdal() {
  Gdal g;
  auto warp = findOnPath("gdalwarp");
  auto vrt = findOnPath("gdalbuildvrt");
  if (!warp || !vrt) {
    throw BenchError(std::string(warp ? "gdalbuildvrt" : "gdalwarp") +
                     " is not on PATH; install GDAL's command-line tools (Debian/Ubuntu: apt install gdal-bin)");
  }
  g.warp = *warp;
  g.buildVrt = *vrt;
  return g;
}

/// A VRT mosaic of exactly the files our build reads (same expansion, same
/// "-resolution highest" as our own mosaic), and the target CRS as a WKT
/// file, so gdalwarp sees the same sources and frame. Not timed: it is setup.
void prepareGdal(Gdal& g, const Input& in, const TargetGrid& grid, const fs::path& work) {
  const auto files = convert::expandSources({in.sources.string()});
  if (!files) throw BenchError(files.error());
  const fs::path list = work / "sources.txt";
  {
    std::ofstream f(list);
    for (const auto& p : files.value()) f << p << '\n';
  }
  g.vrt = work / "sources.vrt";
  runProcess({g.buildVrt.string(), "-q", "-resolution", "highest", "-input_file_list", list.string(), g.vrt.string()},
             work / "gdalbuildvrt.log");
  g.wkt = work / "target.wkt";
  std::ofstream(g.wkt) << grid.crsWkt;
  runProcess({g.warp.string(), "--version"}, work / "gdalwarp-version.log");
  std::ifstream v(work / "gdalwarp-version.log");
  std::getline(v, g.version);
}

/// "samples" and "lines" from an ENVI header: gdalwarp's output size.
std::pair<long, long> enviSize(const fs::path& hdr) {
  std::ifstream f(hdr);
  long samples = -1, lines = -1;
  for (std::string line; std::getline(f, line);) {
    long v = 0;
    if (std::sscanf(line.c_str(), " samples = %ld", &v) == 1) samples = v;
    if (std::sscanf(line.c_str(), " lines = %ld", &v) == 1) lines = v;
  }
  return {samples, lines};
}

/// gdalwarp onto our grid. -te is our grid in pixel-is-area terms: post
/// centres are pixel centres, so the box reaches half a post past the
/// outer posts. ENVI output is raw Float32 plus a text header, the
/// cheapest thing gdalwarp can write, so its output format costs little.
Sample runGdalwarp(const Gdal& g, const TargetGrid& grid, const std::string& kernel, bool multi, int threads,
                   const fs::path& dir) {
  std::error_code ec;
  fs::remove_all(dir, ec);  // untimed: no -overwrite inside the clock
  fs::create_directories(dir);
  const double h = grid.spacing / 2;
  std::vector<std::string> argv = {g.warp.string(), "-q", "-of", "ENVI", "-ot", "Float32", "-t_srs", g.wkt.string(),
                                   "-te", fmt(grid.west - h), fmt(grid.south - h), fmt(grid.east + h),
                                   fmt(grid.north + h), "-tr", fmt(grid.spacing), fmt(grid.spacing), "-r", kernel};
  if (multi) {
    argv.insert(argv.end(), {"-multi", "-wo", threads > 0 ? "NUM_THREADS=" + std::to_string(threads)
                                                           : std::string("NUM_THREADS=ALL_CPUS")});
  }
  argv.insert(argv.end(), {g.vrt.string(), (dir / "out.img").string()});
  const Sample s = runProcess(argv, dir / "gdalwarp.log");
  const auto [w, hgt] = enviSize(dir / "out.hdr");
  if (w != long(grid.postsX) || hgt != long(grid.postsZ)) {
    throw BenchError("gdalwarp wrote " + std::to_string(w) + " x " + std::to_string(hgt) + " pixels, not our " +
                     std::to_string(grid.postsX) + " x " + std::to_string(grid.postsZ) + " posts");
  }
  return s;
}

// ------------------------------------------------------------ the run

/// gdalwarp kernels comparable to ours: our weighted plane has no gdalwarp
/// twin; `average` reads a similar neighbourhood, `bilinear` is the usual choice.
std::vector<std::string> comparableKernels(const std::string& ours) {
  if (ours == "weighted") return {"average", "bilinear"};
  return {ourKernel(ours).resample};
}

struct Measurements {
  std::map<std::string, std::vector<Sample>> ours, warp1t, warpMt;
};

/// The untimed warm-up: one run of each side, so both read the sources from
/// the page cache in the timed runs. Ours also fixes the target grid.
TargetGrid warmUp(const BuildBenchOptions& a, const Input& in, Gdal& g, const fs::path& work, const Notes& notes) {
  TargetGrid grid;
  note(notes, "warm-up (untimed): ours, %s", a.kernels.front().c_str());
  runOurs(a, in, a.kernels.front(), work / ("ours-" + a.kernels.front()), &grid);
  prepareGdal(g, in, grid, work);
  const std::string k = comparableKernels(a.kernels.front()).front();
  note(notes, "warm-up (untimed): gdalwarp -r %s -multi", k.c_str());
  runGdalwarp(g, grid, k, true, a.threads, work / ("gdalwarp-" + k + "-mt"));
  return grid;
}

/// Repeats alternate the sides kernel by kernel; each gdalwarp kernel runs
/// once per repeat even when two of our kernels compare against it.
Measurements measure(const BuildBenchOptions& a, const Input& in, const Gdal& g, const TargetGrid& grid,
                     const fs::path& work, const Notes& notes) {
  Measurements m;
  for (int r = 1; r <= a.repeat; ++r) {
    std::vector<std::string> warped;
    for (const auto& k : a.kernels) {
      const Sample s = runOurs(a, in, k, work / ("ours-" + k), nullptr);
      m.ours[k].push_back(s);
      note(notes, "repeat %d/%d  ours      %-8s %7.2f s (resampling %.2f s)", r, a.repeat, k.c_str(), s.wallS, s.resampleS);
      for (const auto& gk : comparableKernels(k)) {
        if (std::find(warped.begin(), warped.end(), gk) != warped.end()) continue;
        warped.push_back(gk);
        const Sample s1 = runGdalwarp(g, grid, gk, false, a.threads, work / ("gdalwarp-" + gk + "-1t"));
        m.warp1t[gk].push_back(s1);
        note(notes, "repeat %d/%d  gdalwarp  %-8s %7.2f s (1 thread)", r, a.repeat, gk.c_str(), s1.wallS);
        const Sample sm = runGdalwarp(g, grid, gk, true, a.threads, work / ("gdalwarp-" + gk + "-mt"));
        m.warpMt[gk].push_back(sm);
        note(notes, "repeat %d/%d  gdalwarp  %-8s %7.2f s (-multi)", r, a.repeat, gk.c_str(), sm.wallS);
      }
    }
  }
  return m;
}

// ------------------------------------------------------------ report

/// Median of each stage over the runs, in the order the stages ran.
std::vector<std::pair<std::string, double>> medianStages(const std::vector<Sample>& runs) {
  std::vector<std::pair<std::string, double>> out;
  for (const auto& [name, unused] : runs.front().stages) {
    std::vector<double> v;
    for (const auto& r : runs) {
      for (const auto& [n, sec] : r.stages) {
        if (n == name) v.push_back(sec);
      }
    }
    out.emplace_back(name, stats::median(v));
  }
  return out;
}

std::vector<double> walls(const std::vector<Sample>& s) {
  std::vector<double> v;
  for (const auto& x : s) v.push_back(x.wallS);
  return v;
}

std::vector<BuildBenchRow> rows(const BuildBenchOptions& a, const Measurements& m) {
  std::vector<BuildBenchRow> out;
  for (const auto& k : a.kernels) {
    const auto& o = m.ours.at(k);
    for (const auto& gk : comparableKernels(k)) {
      const auto& w1 = m.warp1t.at(gk);
      const auto& wm = m.warpMt.at(gk);
      out.push_back({k, gk, medianOf(o, &Sample::wallS), medianOf(o, &Sample::resampleS), medianOf(o, &Sample::cpuS),
                     medianOf(w1, &Sample::wallS), medianOf(w1, &Sample::cpuS), medianOf(wm, &Sample::wallS),
                     medianOf(wm, &Sample::cpuS), walls(o), walls(w1), walls(wm), medianStages(o)});
    }
  }
  return out;
}

/// The report as `--json` prints it; `source` and `threads` as given.
nlohmann::json toJson(const BuildBenchOptions& a, const BuildBenchReport& rep) {
  const double posts = static_cast<double>(rep.grid.posts());
  nlohmann::json results = nlohmann::json::array();
  for (const auto& r : rep.rows) {
    results.push_back({{"kernel", r.kernel},
                       {"ours_s", r.oursS},
                       {"ours_posts_per_s", posts / r.oursS},
                       {"ours_resample_s", r.oursResampleS},
                       {"ours_cpu_s", r.oursCpuS},
                       {"gdalwarp_kernel", r.warpKernel},
                       {"gdalwarp_1t_s", r.warp1tS},
                       {"gdalwarp_1t_posts_per_s", posts / r.warp1tS},
                       {"gdalwarp_1t_cpu_s", r.warp1tCpuS},
                       {"gdalwarp_mt_s", r.warpMtS},
                       {"gdalwarp_mt_posts_per_s", posts / r.warpMtS},
                       {"gdalwarp_mt_cpu_s", r.warpMtCpuS},
                       {"ratio_vs_1t", r.warp1tS / r.oursS},
                       {"ratio_vs_mt", r.warpMtS / r.oursS},
                       {"samples_s", {{"ours", r.oursSamples}, {"gdalwarp_1t", r.warp1tSamples},
                                      {"gdalwarp_mt", r.warpMtSamples}}}});
    nlohmann::json stages = nlohmann::json::object();
    for (const auto& [name, sec] : r.oursStages) stages[name] = sec;
    results.back()["ours_stages_s"] = stages;
  }
  return {{"posts", rep.grid.posts()},
          {"posts_x", rep.grid.postsX},
          {"posts_z", rep.grid.postsZ},
          {"spacing_m", rep.grid.spacing},
          {"repeat", a.repeat},
          {"crs", rep.grid.crsName},
          {"source", rep.source},
          {"threads", a.threads},
          {"cpus", rep.cpus},
          {"warm_up", true},
          {"gdalwarp_version", rep.gdalwarpVersion},
          {"load_average_start", rep.loadAverageStart},
          {"load_average_end", rep.loadAverageEnd},
          {"results", results}};
}

// ------------------------------------------------------------ the benchmark

std::string checkOptions(const BuildBenchOptions& a) {
  if (a.kernels.empty()) return "BuildBenchOptions::kernels is empty";
  for (const auto& k : a.kernels) {
    if (std::find(kKernelNames.begin(), kKernelNames.end(), k) == kKernelNames.end()) {
      return "unknown kernel \"" + k + "\"; use weighted, bilinear, bilinear-triangles, cubic or average";
    }
    if (std::count(a.kernels.begin(), a.kernels.end(), k) > 1) return "kernel \"" + k + "\" given twice";
  }
  if (a.input.empty() && a.sizeKm <= 0 && autoSizeKm(a.spacing) > 1000) {
    return "BuildBenchOptions::spacing " + fmt(a.spacing) +
           " needs a square over synth's 1000 km limit; pass BuildBenchOptions::sizeKm or BuildBenchOptions::input";
  }
  return {};
}

void checkGridSize(const TargetGrid& g, const Notes& notes) {
  note(notes, "target grid: %u x %u = %.1f M posts at %g m, %s", g.postsX, g.postsZ,
       static_cast<double>(g.posts()) / 1e6, g.spacing, g.crsName.c_str());
  if (g.postsX < kMinPostsPerAxis || g.postsZ < kMinPostsPerAxis) {
    note(notes, "note: below the %u x %u posts the benchmark is meant for; raise BuildBenchOptions::sizeKm or lower "
         "BuildBenchOptions::spacing", kMinPostsPerAxis, kMinPostsPerAxis);
  }
}

BuildBenchReport run(const BuildBenchOptions& a, Gdal& gdal, const Notes& notes) {
  WorkDir work(a.keep);
  if (a.keep) note(notes, "work directory %s (kept)", work.path().c_str());
  BuildBenchReport rep;
  rep.loadAverageStart = loadAverage();
  const Input in = prepareInput(a, work.path(), notes);
  const TargetGrid grid = warmUp(a, in, gdal, work.path(), notes);
  checkGridSize(grid, notes);
  const Measurements m = measure(a, in, gdal, grid, work.path(), notes);
  rep.loadAverageEnd = loadAverage();
  rep.grid = {grid.postsX, grid.postsZ, grid.spacing, grid.crsName};
  rep.source = in.description;
  rep.sourceFiles = in.files;
  rep.gdalwarpVersion = gdal.version;
  rep.cpus = cpuCount();
  rep.rows = rows(a, m);
  rep.json = toJson(a, rep);
  return rep;
}

}  // namespace

Result<BuildBenchReport> runBuildBench(const BuildBenchOptions& options, const Notes& notes) {
  if (std::string e = checkOptions(options); !e.empty()) return Problem{"", 0, e};
  try {
    Gdal gdal = findGdal();
    return run(options, gdal, notes);
  } catch (const BenchError& e) {
    return Problem{"", 0, e.what()};
  } catch (const fs::filesystem_error& e) {
    return Problem{"", 0, e.what()};
  }
}

}  // namespace sandtable::bench
