// sandtable bench build: flags and printing for bench::runBuildBench, our
// grid conversion against the gdalwarp binary on the same target grid; and,
// with --distributed, the one-machine build against the distributed one
// (plan, tasks, merge; docs/DISTRIBUTED.md), every step a child process.
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>

#include <nlohmann/json.hpp>

#include "cmd_bench.h"
#include "sandtable/bench/build.h"
#include "sandtable/converters/distributed.h"

extern char** environ;

namespace sandtable::cli {
namespace {

constexpr const char* kCmd = "bench build";

struct Args {
  bench::BuildBenchOptions o;
  bool json = false;
  bool distributed = false;
  std::uint32_t tasks = 8;              ///< --tasks (distributed)
  int concurrent = 2;                   ///< --concurrent (distributed)
  std::vector<std::string> buildArgs;   ///< after --: the build's own arguments (distributed)
};

const FlagMap kFlags = {{"BuildBenchOptions::input", "--input"},     {"BuildBenchOptions::sizeKm", "--size-km"},
                        {"BuildBenchOptions::spacing", "--spacing"}, {"BuildBenchOptions::kernels", "--kernels"},
                        {"BuildBenchOptions::repeat", "--repeat"},   {"BuildBenchOptions::threads", "--threads"},
                        {"BuildBenchOptions::keep", "--keep"}};

struct Context {
  const bench::BuildBenchOptions& args;
  const bench::BuildBenchReport& report;
  const bench::BuildBenchGrid& grid;
};

std::string threadsText(int threads, unsigned cpus) {
  return threads > 0 ? std::to_string(threads) : "all (" + std::to_string(cpus) + ")";
}

void printHeader(const Context& c) {
  std::printf("sandtable bench build: %u x %u posts (%.1f M) at %g m, %s\n", c.grid.postsX, c.grid.postsZ,
              static_cast<double>(c.grid.posts()) / 1e6, c.grid.spacing, c.grid.crsName.c_str());
  std::printf("  sources   %s, %zu files\n", c.report.source.c_str(), c.report.sourceFiles);
  std::printf("  gdalwarp  %s: same sources (VRT), CRS, -te, -tr; -of ENVI -ot Float32\n",
              c.report.gdalwarpVersion.c_str());
  std::printf("  method    one untimed warm-up of each side first, so both read the sources from the page cache;\n"
              "            then the median of %d repeats, wall clock, sides alternating\n", c.args.repeat);
  std::printf("  threads   ours %s; gdalwarp 1t = default (no -multi), mt = -multi -wo NUM_THREADS=%s\n",
              threadsText(c.args.threads, c.report.cpus).c_str(),
              c.args.threads > 0 ? std::to_string(c.args.threads).c_str() : "ALL_CPUS");
  std::printf("  load      %.2f at start, %.2f at end (1-minute load average, %u CPUs)\n\n",
              c.report.loadAverageStart, c.report.loadAverageEnd, c.report.cpus);
}

int kernelWidth(const std::vector<bench::BuildBenchRow>& rs) {
  std::size_t w = 6;
  for (const auto& r : rs) w = std::max(w, r.kernel.size());
  return static_cast<int>(w);
}

void printResults(const Context& c, const std::vector<bench::BuildBenchRow>& rs) {
  const double posts = static_cast<double>(c.grid.posts());
  const int w = kernelWidth(rs);
  std::printf("%-*s %8s %9s %9s | %-8s %8s %9s %8s %9s | %7s %7s\n", w, "kernel", "ours s", "Mposts/s", "resamp s",
              "gdalwarp", "1t s", "Mposts/s", "mt s", "Mposts/s", "1t/ours", "mt/ours");
  for (const auto& r : rs) {
    std::printf("%-*s %8.2f %9.2f %9.2f | %-8s %8.2f %9.2f %8.2f %9.2f | %7.2f %7.2f\n", w, r.kernel.c_str(),
                r.oursS, posts / r.oursS / 1e6, r.oursResampleS, r.warpKernel.c_str(), r.warp1tS,
                posts / r.warp1tS / 1e6, r.warpMtS, posts / r.warpMtS / 1e6, r.warp1tS / r.oursS, r.warpMtS / r.oursS);
  }
  std::printf("\nratio = gdalwarp seconds / our seconds: above 1 we are faster. Ours is the whole build\n"
              "(read + CRC of the sources, resample, void fill, normals, grid file with CRCs, fsync);\n"
              "\"resamp s\" is its resampling stage alone. gdalwarp only resamples and writes raw floats.\n");
}

/// Where our time goes, and CPU seconds, which other users' load inflates
/// less than wall time. Once per kernel of ours.
void printBreakdown(const std::vector<bench::BuildBenchRow>& rs) {
  std::printf("\nours by stage (median s) and CPU seconds (user + system, median):\n");
  std::string last;
  for (const auto& r : rs) {
    if (r.kernel == last) continue;
    last = r.kernel;
    std::printf("  %-18s", r.kernel.c_str());
    for (const auto& [name, sec] : r.oursStages) std::printf(" %s %.2f,", name.c_str(), sec);
    std::printf(" cpu %.1f\n", r.oursCpuS);
  }
  std::vector<std::string> seen;
  for (const auto& r : rs) {
    if (std::find(seen.begin(), seen.end(), r.warpKernel) != seen.end()) continue;
    seen.push_back(r.warpKernel);
    std::printf("  gdalwarp %-9s cpu %.1f (1t), %.1f (mt)\n", r.warpKernel.c_str(), r.warp1tCpuS, r.warpMtCpuS);
  }
}

/// The goal: no slower than gdalwarp, i.e. ratio >= 1 against
/// gdalwarp's faster mode.
void printVerdict(const std::vector<bench::BuildBenchRow>& rs) {
  std::printf("\ngoal (no slower than gdalwarp, against its faster mode):\n");
  for (const auto& r : rs) {
    const double ratio = std::min(r.warp1tS, r.warpMtS) / r.oursS;
    std::printf("  %-18s vs %-8s %5.2f  %s\n", r.kernel.c_str(), r.warpKernel.c_str(), ratio,
                ratio >= 1 ? "met" : "NOT met");
  }
}

void printTable(const Context& c, const std::vector<bench::BuildBenchRow>& rs) {
  printHeader(c);
  printResults(c, rs);
  printBreakdown(rs);
  printVerdict(rs);
}

int runDistributed(const Args& a);

int run(const Args& a) {
  cancelOnSignals();
  if (a.distributed) return runDistributed(a);
  if (!a.buildArgs.empty()) {
    return usageError(kCmd, "build arguments after -- need --distributed (the gdalwarp comparison builds its own)");
  }
  auto r = bench::runBuildBench(a.o, stderrNotes("bench", false, kFlags));
  if (!r) return reportBenchProblems(kCmd, r.problems(), kFlags);
  bench::BuildBenchReport& rep = r.value();
  rep.source = withFlags(rep.source, kFlags);
  rep.json["source"] = rep.source;
  if (a.json) {
    std::printf("%s\n", rep.json.dump(2).c_str());
  } else {
    const Context c{a.o, rep, rep.grid};
    printTable(c, rep.rows);
  }
  return kOk;
}

// ------------------------------------------------------------ --distributed
//
// The one-machine build against the distributed one on the same arguments:
// every step is this executable run as a child (/proc/self/exe), so two
// tasks can run at once and each child's peak RSS and CPU time come from
// wait4. The parts and both databases lie in one work directory (one disk).

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// A step failed; the message is for the user as it stands.
struct DistFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One child process as it ended.
struct ChildRun {
  double wallS = 0, cpuS = 0;
  std::uint64_t peakRssBytes = 0;   ///< ru_maxrss: heap and mapped file pages (a mapped grid counts whole)
  std::uint64_t peakAnonBytes = 0;  ///< largest RssAnon seen, sampled every few milliseconds
};

/// RssAnon of process `pid` from /proc, 0 once it has gone.
std::uint64_t rssAnonBytes(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(f, line);) {
    if (line.rfind("RssAnon:", 0) == 0) return std::strtoull(line.c_str() + 8, nullptr, 10) * 1024;
  }
  return 0;
}

std::string selfExe() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("/proc/self/exe") : p.string();
}

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string lastLines(const fs::path& log, int n) {
  std::ifstream f(log);
  std::vector<std::string> lines;
  for (std::string l; std::getline(f, l);) lines.push_back(l);
  std::string out;
  for (std::size_t k = lines.size() > std::size_t(n) ? lines.size() - n : 0; k < lines.size(); ++k) {
    out += "\n  " + lines[k];
  }
  return out;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : " ") + x;
  return s;
}

/// Starts this executable with `argv` (argv[0] its name), stdin from
/// /dev/null, stdout and stderr to `log`.
pid_t spawnChild(const std::vector<std::string>& argv, const fs::path& log) {
  std::vector<char*> av;
  for (const auto& s : argv) av.push_back(const_cast<char*>(s.c_str()));
  av.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = 0;
  // Every child is this executable: exec'd as /proc/self/exe, so a rebuild
  // that replaces the file mid-run does not change (or break) the bench.
  const int rc = ::posix_spawn(&pid, "/proc/self/exe", &fa, nullptr, av.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw DistFailure("cannot run " + argv[0] + ": " + std::strerror(rc));
  return pid;
}

/// Runs `cmds`, at most `atOnce` at a time, in order; fills `each` and
/// returns the wall seconds from the first start to the last exit. A failed
/// child fails the pool once the running ones have ended.
double runPool(const std::vector<std::vector<std::string>>& cmds, const std::vector<fs::path>& logs, int atOnce,
               std::vector<ChildRun>& each) {
  each.assign(cmds.size(), {});
  std::map<pid_t, std::pair<std::size_t, Clock::time_point>> running;  // guarded by mu
  std::mutex mu;
  bool done = false;  // guarded by mu
  // Samples the running children's anonymous memory (the kernel keeps a
  // peak only of the whole RSS, which counts mapped files).
  std::thread sampler([&] {
    while (true) {
      {
        std::lock_guard<std::mutex> lock(mu);
        if (done) return;
        for (const auto& [pid, slot] : running) {
          each[slot.first].peakAnonBytes = std::max(each[slot.first].peakAnonBytes, rssAnonBytes(pid));
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  const auto stopSampler = [&] {
    {
      std::lock_guard<std::mutex> lock(mu);
      done = true;
    }
    sampler.join();
  };
  std::string failure;
  std::size_t next = 0;
  const auto t0 = Clock::now();
  while (next < cmds.size() || !running.empty()) {
    while (failure.empty() && !convert::cancelRequested() && next < cmds.size() &&
           running.size() < std::size_t(atOnce)) {
      pid_t child = 0;
      try {
        child = spawnChild(cmds[next], logs[next]);
      } catch (const DistFailure&) {
        if (running.empty()) {
          stopSampler();
          throw;
        }
        failure = "cannot run " + cmds[next][0];
        break;
      }
      std::lock_guard<std::mutex> lock(mu);
      running[child] = {next, Clock::now()};
      ++next;
    }
    if (running.empty()) break;
    int status = 0;
    rusage ru{};
    pid_t pid;
    // A signal (Ctrl-C reaches the children too) interrupts the wait; keep waiting.
    while ((pid = ::wait4(-1, &status, 0, &ru)) < 0 && errno == EINTR) {
    }
    if (pid < 0) {
      stopSampler();
      throw DistFailure(std::string("wait4: ") + std::strerror(errno));
    }
    std::unique_lock<std::mutex> lock(mu);
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    const auto [k, start] = it->second;
    running.erase(it);
    lock.unlock();
    each[k].wallS = secondsSince(start);
    each[k].cpuS = double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    each[k].peakRssBytes = std::uint64_t(ru.ru_maxrss) * 1024;
    if ((!WIFEXITED(status) || WEXITSTATUS(status) != 0) && failure.empty()) {
      failure = "`" + joined(cmds[k]) + "` failed (log " + logs[k].string() + "):" + lastLines(logs[k], 12);
    }
  }
  const double wall = secondsSince(t0);
  stopSampler();
  if (convert::cancelRequested()) throw DistFailure("cancelled");
  if (!failure.empty()) throw DistFailure(failure);
  return wall;
}

ChildRun runOne(const std::vector<std::string>& cmd, const fs::path& log) {
  std::vector<ChildRun> each;
  runPool({cmd}, {log}, 1, each);
  return each[0];
}

std::uint64_t bytesUnder(const fs::path& dir, const std::string& prefix = "") {
  std::uint64_t n = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.is_regular_file() && e.path().filename().string().rfind(prefix, 0) == 0) n += e.file_size();
  }
  return n;
}

void removeParts(const fs::path& parts) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(parts, ec)) {
    if (e.path().filename().string().rfind("part-", 0) == 0) fs::remove(e.path(), ec);
  }
}

bool sameBytes(const fs::path& x, const fs::path& y) {
  std::ifstream a(x, std::ios::binary), b(y, std::ios::binary);
  if (!a || !b) return false;
  std::vector<char> ba(1 << 20), bb(1 << 20);
  while (true) {
    a.read(ba.data(), std::streamsize(ba.size()));
    b.read(bb.data(), std::streamsize(bb.size()));
    if (a.gcount() != b.gcount()) return false;
    if (a.gcount() == 0) return true;
    if (std::memcmp(ba.data(), bb.data(), std::size_t(a.gcount())) != 0) return false;
  }
}

nlohmann::json readJson(const fs::path& p) {
  std::ifstream f(p);
  try {
    return nlohmann::json::parse(f);
  } catch (const nlohmann::json::exception& e) {
    throw DistFailure("cannot read " + p.string() + ": " + e.what());
  }
}

/// The manifests' differences outside kVolatileManifestKeys, as JSON
/// pointers (empty: equal apart from timings).
std::vector<std::string> manifestDifferences(const fs::path& x, const fs::path& y) {
  nlohmann::json a = readJson(x), b = readJson(y);
  for (const char* key : convert::kVolatileManifestKeys) {
    const nlohmann::json::json_pointer p(key);
    for (nlohmann::json* j : {&a, &b}) {
      if (j->contains(p)) j->at(p.parent_pointer()).erase(p.back());
    }
  }
  std::vector<std::string> out;
  for (const auto& op : nlohmann::json::diff(a, b)) out.push_back(op.value("path", std::string()));
  return out;
}

/// Flags the bench sets itself, refused among the build's arguments.
const std::vector<std::string> kOwnFlags = {"-o",       "--output",     "--threads",      "--plan",      "--task",
                                            "--merge",  "--executor",   "--tasks",        "--parts",     "--force",
                                            "--json",   "--emit-sbatch", "--partition",   "--cpus-per-task"};

std::string fmtNumber(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%.9g", v);
  return s;
}

struct DistInput {
  std::vector<std::string> args;  ///< the build's arguments (sources, extent, spacing, ...)
  std::string description;
};

/// The build's arguments: as given after --, or over a synth output (--input,
/// else one synthesized now, not timed): its DTED2, culture and square.
DistInput distInput(const Args& a, const fs::path& work) {
  DistInput in;
  if (!a.buildArgs.empty()) {
    in.args = a.buildArgs;
    in.description = "the build arguments given";
    return in;
  }
  fs::path dir = a.o.input;
  if (dir.empty()) {
    dir = work / "synth";
    const double km = a.o.sizeKm > 0 ? a.o.sizeKm : 40;
    std::fprintf(stderr, "bench: synthesizing a %g km square into %s (not timed)\n", km, dir.c_str());
    runOne({selfExe(), "synth", "-o", dir.string(), "--size-km", fmtNumber(km), "--threads",
            std::to_string(a.o.threads)},
           work / "logs" / "synth.log");
    in.description = "synthesized " + fmtNumber(km) + " km square (sandtable synth): DTED2 + culture.gpkg";
  } else {
    if (!fs::is_directory(dir)) throw DistFailure("--input " + a.o.input + " is not a directory");
    in.description = "--input " + a.o.input;
  }
  in.args = {"--elevation", (fs::is_directory(dir / "dted2") ? dir / "dted2" : dir).string()};
  if (fs::exists(dir / "culture.gpkg")) in.args.insert(in.args.end(), {"--culture", (dir / "culture.gpkg").string()});
  if (fs::exists(dir / "synth.json")) {
    const auto j = readJson(dir / "synth.json");
    try {
      const auto& b = j.at("bounds");
      in.args.insert(in.args.end(), {"--extent", fmtNumber(b.at("west").get<double>()),
                                     fmtNumber(b.at("south").get<double>()), fmtNumber(b.at("east").get<double>()),
                                     fmtNumber(b.at("north").get<double>())});
    } catch (const nlohmann::json::exception& e) {
      throw DistFailure("cannot read the square from " + (dir / "synth.json").string() + ": " + e.what());
    }
  }
  in.args.insert(in.args.end(), {"--spacing", fmtNumber(a.o.spacing)});
  return in;
}

/// Samples of one measured step, in seconds, and the largest peak RSS.
struct Step {
  std::vector<double> samples;
  std::uint64_t peakRssBytes = 0, peakAnonBytes = 0;
  double cpuS = 0;  ///< median user + system seconds
  std::vector<double> cpuSamples;
  double median() const { return sandtable::cli::median(samples); }
  void add(double wallS, const ChildRun& r) {
    samples.push_back(wallS);
    cpuSamples.push_back(r.cpuS);
    cpuS = sandtable::cli::median(cpuSamples);
    peakRssBytes = std::max(peakRssBytes, r.peakRssBytes);
    peakAnonBytes = std::max(peakAnonBytes, r.peakAnonBytes);
  }
  nlohmann::json json() const {
    return {{"seconds", median()},
            {"samples_s", samples},
            {"cpu_s", cpuS},
            {"peak_rss_bytes", peakRssBytes},
            {"peak_anon_bytes", peakAnonBytes}};
  }
};

struct DistResult {
  DistInput input;
  std::string work;
  std::uint32_t tasks = 0, postsX = 0, postsZ = 0;
  std::uint64_t modules = 0, partsBytes = 0, dbBytes = 0, gridBytes = 0, packBytes = 0;
  int repeat = 0, threads = 0, concurrent = 0;
  unsigned cpus = 0;
  double loadStart = 0, loadEnd = 0;
  Step oneAll, one1, plan, serial, concurrentStep, merge;
  std::vector<std::vector<double>> perTask;  ///< [task][repeat] seconds, 1 at a time
  std::vector<std::pair<std::string, bool>> identical;
  std::vector<std::string> manifestDiffs;
  double posts() const { return double(postsX) * double(postsZ); }
};

double loadAverage1() {
  double l[1] = {0};
  return ::getloadavg(l, 1) == 1 ? l[0] : 0;
}

constexpr double kMergeGoalPercent = 10;

nlohmann::json distJson(const DistResult& r) {
  const double oneAll = r.oneAll.median(), one1 = r.one1.median(), serial = r.serial.median(),
               conc = r.concurrentStep.median(), merge = r.merge.median();
  std::vector<double> perTask;
  for (const auto& t : r.perTask) perTask.push_back(median(t));
  const double mergeBytes = double(r.partsBytes + r.dbBytes);
  nlohmann::json identical = nlohmann::json::object();
  bool all = true;
  for (const auto& [file, same] : r.identical) {
    identical[file] = same;
    all = all && same;
  }
  identical["manifest_apart_from_volatile_keys"] = r.manifestDiffs.empty();
  identical["manifest_differences"] = r.manifestDiffs;
  identical["all"] = all && r.manifestDiffs.empty();
  return {
      {"mode", "distributed"},
      {"source", r.input.description},
      {"build_args", r.input.args},
      {"posts", std::uint64_t(r.posts())},
      {"posts_x", r.postsX},
      {"posts_z", r.postsZ},
      {"modules", r.modules},
      {"tasks", r.tasks},
      {"repeat", r.repeat},
      {"threads", r.threads},
      {"cpus", r.cpus},
      {"load_average_start", r.loadStart},
      {"load_average_end", r.loadEnd},
      {"work", r.work},
      {"one_machine", {{"threads_all", r.oneAll.json()}, {"threads_1", r.one1.json()}}},
      {"plan", r.plan.json()},
      {"tasks_one_at_a_time",
       {{"threads", 1},
        {"seconds", serial},
        {"samples_s", r.serial.samples},
        {"cpu_s", r.serial.cpuS},
        {"peak_rss_bytes", r.serial.peakRssBytes},
        {"peak_anon_bytes", r.serial.peakAnonBytes},
        {"per_task_s", perTask},
        {"tasks_per_second", r.tasks / serial},
        {"posts_per_second", r.posts() / serial}}},
      {"tasks_concurrent",
       {{"processes", r.concurrent},
        {"threads", 1},
        {"seconds", conc},
        {"samples_s", r.concurrentStep.samples},
        {"tasks_per_second", r.tasks / conc},
        {"posts_per_second", r.posts() / conc},
        {"speedup_vs_one_at_a_time", serial / conc},
        {"speedup_vs_one_machine_threads_1", one1 / conc},
        {"speedup_vs_one_machine_threads_all", oneAll / conc}}},
      {"distributed_total_s", r.plan.median() + conc + merge},
      {"merge",
       {{"seconds", merge},
        {"samples_s", r.merge.samples},
        {"cpu_s", r.merge.cpuS},
        {"parts_bytes_read", r.partsBytes},
        {"db_bytes_written", r.dbBytes},
        {"mb_per_second", mergeBytes / merge / 1e6},
        {"peak_rss_bytes", r.merge.peakRssBytes},
        {"peak_anon_bytes", r.merge.peakAnonBytes},
        {"pack_index_bytes", r.modules * 64},
        {"percent_of_one_machine_threads_all", 100 * merge / oneAll},
        {"percent_of_one_machine_threads_1", 100 * merge / one1},
        {"goal_percent", kMergeGoalPercent},
        {"goal_met", 100 * merge / oneAll < kMergeGoalPercent}}},
      {"db", {{"bytes", r.dbBytes}, {"grid_bytes", r.gridBytes}, {"pack_bytes", r.packBytes},
              {"pack_bytes_per_post", double(r.packBytes) / r.posts()}}},
      {"identical", identical}};
}

std::string mb(std::uint64_t bytes) {
  char s[32];
  std::snprintf(s, sizeof s, "%.1f MB", double(bytes) / 1e6);
  return s;
}

void printStepRow(const char* name, const Step& s) {
  std::string samples;
  for (double v : s.samples) {
    char t[32];
    std::snprintf(t, sizeof t, "%s%.2f", samples.empty() ? "" : " ", v);
    samples += t;
  }
  std::printf("  %-34s %8.2f %8.1f %8.0f %7.0f  %s\n", name, s.median(), s.cpuS, double(s.peakRssBytes) / 1e6,
              double(s.peakAnonBytes) / 1e6, samples.c_str());
}

void printDistributed(const DistResult& r) {
  const double oneAll = r.oneAll.median(), one1 = r.one1.median(), serial = r.serial.median(),
               conc = r.concurrentStep.median(), merge = r.merge.median();
  std::printf("sandtable bench build --distributed: %u x %u posts (%.2f M), %llu modules, %u tasks\n", r.postsX,
              r.postsZ, r.posts() / 1e6, static_cast<unsigned long long>(r.modules), r.tasks);
  std::printf("  build     %s\n            (%s)\n", joined(r.input.args).c_str(), r.input.description.c_str());
  std::printf("  method    every step a child process (this executable); one untimed plan first, which reads\n"
              "            every input (page cache); then the median of %d repeats, wall clock; parts and\n"
              "            databases on one disk (%s)\n", r.repeat, r.work.c_str());
  std::printf("  load      %.2f at start, %.2f at end (1-minute load average, %u CPUs)\n\n", r.loadStart, r.loadEnd,
              r.cpus);
  std::printf("  %-34s %8s %8s %8s %7s  %s\n", "step", "median s", "cpu s", "peak RSS", "anon", "samples s");
  printStepRow(("one machine, threads " + threadsText(r.threads, r.cpus)).c_str(), r.oneAll);
  printStepRow("one machine, threads 1", r.one1);
  printStepRow("plan", r.plan);
  printStepRow("tasks 1 at a time, threads 1", r.serial);
  printStepRow(("tasks " + std::to_string(r.concurrent) + " at a time, threads 1").c_str(), r.concurrentStep);
  printStepRow("merge", r.merge);
  std::printf("  (MB, the largest of the step's processes: peak RSS from wait4, mapped files included; anon: its\n"
              "  largest RssAnon, sampled every 5 ms. cpu s: user + system of all its processes)\n\n");
  std::vector<double> perTask;
  for (const auto& t : r.perTask) perTask.push_back(median(t));
  const auto [lo, hi] = std::minmax_element(perTask.begin(), perTask.end());
  std::printf("tasks     1 at a time %.2f tasks/s, %d at a time %.2f tasks/s: speed-up %.2fx\n", r.tasks / serial,
              r.concurrent, r.tasks / conc, serial / conc);
  std::printf("          %d at a time, speed-up over the one-machine build: %.2fx (threads 1), %.2fx (threads %s)\n",
              r.concurrent, one1 / conc, oneAll / conc, threadsText(r.threads, r.cpus).c_str());
  std::printf("          per task (median s, 1 at a time): min %.2f, median %.2f, max %.2f", *lo, median(perTask), *hi);
  if (perTask.size() <= 16) {
    std::printf(":");
    for (std::size_t t = 0; t < perTask.size(); ++t) std::printf(" %zu:%.2f", t, perTask[t]);
  }
  std::printf("\n          work: the tasks' seconds add up to %.2fx the one-machine threads-1 build (each task\n"
              "          loads the whole culture, re-reads every source for its CRC and resamples a halo)\n",
              serial / one1);
  std::printf("          rate: %.2f M posts/s per task process (1 thread), %.0f modules/s\n", r.posts() / serial / 1e6,
              double(r.modules) / serial);
  const double pct = 100 * merge / oneAll;
  std::printf("merge     %.2f s: %s of parts read + %s written = %.0f MB/s\n", merge, mb(r.partsBytes).c_str(),
              mb(r.dbBytes).c_str(), double(r.partsBytes + r.dbBytes) / merge / 1e6);
  std::printf("          peak RSS %.0f MB, anonymous %.0f MB (pack index %llu x 64 B = %.2f MB; grid.stg %s)\n",
              double(r.merge.peakRssBytes) / 1e6, double(r.merge.peakAnonBytes) / 1e6,
              static_cast<unsigned long long>(r.modules), double(r.modules) * 64 / 1e6, mb(r.gridBytes).c_str());
  std::printf("          %.1f%% of the one-machine build (threads %s), %.1f%% of its threads-1 time\n", pct,
              threadsText(r.threads, r.cpus).c_str(), 100 * merge / one1);
  std::printf("          distributed end to end (plan + %d at a time + merge): %.2f s\n", r.concurrent,
              r.plan.median() + conc + merge);
  std::printf("goal      merge < %.0f%% of the single-machine build: %s (%.1f%%)\n", kMergeGoalPercent,
              pct < kMergeGoalPercent ? "met" : "MISSED", pct);
  std::printf("identical");
  for (const auto& [file, same] : r.identical) std::printf(" %s %s,", file.c_str(), same ? "yes" : "NO");
  std::printf(" manifest.json apart from kVolatileManifestKeys %s\n", r.manifestDiffs.empty() ? "yes" : "NO");
  for (std::size_t k = 0; k < r.manifestDiffs.size() && k < 8; ++k) {
    std::printf("          manifest differs at %s\n", r.manifestDiffs[k].c_str());
  }
}

void distRepeat(const Args& a, DistResult& r, int rep, const fs::path& work,
                const std::function<std::vector<std::string>(std::vector<std::string>)>& build) {
  const fs::path one = work / "one", dist = work / "dist", parts = work / "parts", plan = work / "plan.json",
                 logs = work / "logs";
  const std::string exe = selfExe();
  std::error_code ec;
  const auto note = [&](const char* what, double s) {
    std::fprintf(stderr, "bench: repeat %d/%d: %s %.2f s\n", rep + 1, a.o.repeat, what, s);
  };
  // The one-machine build: threads 1, then all (its output is compared).
  fs::remove_all(one, ec);
  ChildRun c = runOne(build({"-o", one.string(), "--force", "--threads", "1"}), logs / "one-threads1.log");
  r.one1.add(c.wallS, c);
  note("one machine, threads 1:", c.wallS);
  fs::remove_all(one, ec);
  c = runOne(build({"-o", one.string(), "--force", "--threads", std::to_string(a.o.threads)}), logs / "one.log");
  r.oneAll.add(c.wallS, c);
  note("one machine, all threads:", c.wallS);
  c = runOne(build({"-o", dist.string(), "--force", "--plan", plan.string(), "--tasks", std::to_string(a.tasks),
                    "--parts", parts.string()}),
             logs / "plan.log");
  r.plan.add(c.wallS, c);
  note("plan:", c.wallS);
  std::vector<std::vector<std::string>> cmds;
  std::vector<fs::path> taskLogs;
  for (std::uint32_t t = 0; t < r.tasks; ++t) {
    cmds.push_back({exe, "build", "--task", plan.string(), std::to_string(t), "--threads", "1"});
    taskLogs.push_back(logs / ("task-" + std::to_string(t) + ".log"));
  }
  const auto sumRun = [](const std::vector<ChildRun>& each) {
    ChildRun s;
    for (const auto& e : each) {
      s.cpuS += e.cpuS;
      s.peakRssBytes = std::max(s.peakRssBytes, e.peakRssBytes);
      s.peakAnonBytes = std::max(s.peakAnonBytes, e.peakAnonBytes);
    }
    return s;
  };
  std::vector<ChildRun> each;
  removeParts(parts);
  double wall = runPool(cmds, taskLogs, 1, each);
  r.serial.add(wall, sumRun(each));
  for (std::uint32_t t = 0; t < r.tasks; ++t) r.perTask[t].push_back(each[t].wallS);
  note("tasks 1 at a time:", wall);
  removeParts(parts);
  wall = runPool(cmds, taskLogs, a.concurrent, each);
  r.concurrentStep.add(wall, sumRun(each));
  note(("tasks " + std::to_string(a.concurrent) + " at a time:").c_str(), wall);
  r.partsBytes = bytesUnder(parts, "part-");
  fs::remove_all(dist, ec);
  c = runOne({exe, "build", "--merge", plan.string(), "-o", dist.string(), "--force"}, logs / "merge.log");
  r.merge.add(c.wallS, c);
  note("merge:", c.wallS);
}

int runDistributed(const Args& a) {
  if (a.tasks < 1) return usageError(kCmd, "--tasks must be at least 1");
  if (a.concurrent < 1) return usageError(kCmd, "--concurrent must be at least 1");
  if (!a.buildArgs.empty() && (!a.o.input.empty() || a.o.sizeKm > 0)) {
    return usageError(kCmd, "--input and --size-km choose the default inputs; leave them out with build arguments "
                            "after --");
  }
  for (const auto& arg : a.buildArgs) {
    for (const auto& own : kOwnFlags) {
      if (arg == own || arg.rfind(own + "=", 0) == 0) {
        return usageError(kCmd, "the build arguments after -- must leave out " + own + ": the bench sets it");
      }
    }
  }
  const char* tmp = std::getenv("TMPDIR");
  std::string tmpl = std::string(tmp && *tmp ? tmp : "/tmp") + "/sandtable-bench-distributed-XXXXXX";
  if (!::mkdtemp(tmpl.data())) return usageError(kCmd, "cannot create a work directory " + tmpl + ": " + std::strerror(errno));
  const fs::path work = tmpl;
  std::error_code ec;
  fs::create_directories(work / "logs", ec);
  DistResult r;
  r.work = work.string();
  r.repeat = a.o.repeat;
  r.threads = a.o.threads;
  r.concurrent = a.concurrent;
  r.cpus = std::thread::hardware_concurrency();
  try {
    r.input = distInput(a, work);
    const std::string exe = selfExe();
    const auto build = [&](std::vector<std::string> extra) {
      std::vector<std::string> v{exe, "build"};
      v.insert(v.end(), r.input.args.begin(), r.input.args.end());
      v.insert(v.end(), extra.begin(), extra.end());
      return v;
    };
    // Warm-up, not timed: the plan reads every input for its CRC, so every
    // step after it reads them from the page cache.
    std::fprintf(stderr, "bench: work directory %s; planning once, not timed\n", work.c_str());
    runOne(build({"-o", (work / "dist").string(), "--force", "--plan", (work / "plan.json").string(), "--tasks",
                  std::to_string(a.tasks), "--parts", (work / "parts").string()}),
           work / "logs" / "plan.log");
    auto plan = convert::readPlan((work / "plan.json").string());
    if (!plan) throw DistFailure("cannot read the plan: " + plan.problems().front().message);
    r.tasks = std::uint32_t(plan->tasks.size());
    r.perTask.assign(r.tasks, {});
    r.loadStart = loadAverage1();
    for (int rep = 0; rep < a.o.repeat; ++rep) distRepeat(a, r, rep, work, build);
    r.loadEnd = loadAverage1();
    const auto manifest = readJson(work / "dist" / "manifest.json");
    r.postsX = manifest.at("/grid/posts_x"_json_pointer).get<std::uint32_t>();
    r.postsZ = manifest.at("/grid/posts_z"_json_pointer).get<std::uint32_t>();
    r.modules = manifest.value("/build/modules/count"_json_pointer, std::uint64_t(0));
    r.dbBytes = bytesUnder(work / "dist");
    r.gridBytes = fs::file_size(work / "dist" / "grid.stg", ec);
    r.packBytes = fs::file_size(work / "dist" / "modules.pack", ec);
    for (const char* f : {"grid.stg", "modules.pack", "modules.idx", "materials.txt", "icons.pack"}) {
      r.identical.emplace_back(f, sameBytes(work / "one" / f, work / "dist" / f));
    }
    r.manifestDiffs = manifestDifferences(work / "one" / "manifest.json", work / "dist" / "manifest.json");
  } catch (const DistFailure& e) {
    if (!a.o.keep) fs::remove_all(work, ec);
    return usageError(kCmd, e.what() + std::string(a.o.keep ? "" : " (work directory removed; --keep keeps it)"));
  } catch (const nlohmann::json::exception& e) {
    if (!a.o.keep) fs::remove_all(work, ec);
    return usageError(kCmd, std::string("the merged manifest: ") + e.what());
  }
  if (!a.o.keep) fs::remove_all(work, ec);
  if (a.json) std::printf("%s\n", distJson(r).dump(2).c_str());
  else printDistributed(r);
  bool same = r.manifestDiffs.empty();
  for (const auto& [file, ok] : r.identical) same = same && ok;
  return same ? kOk : kProblems;
}

}  // namespace

void registerBenchBuild(CLI::App& bench, Commands& c) {
  auto a = std::make_shared<Args>();
  auto& o = a->o;
  auto* sub = bench.add_subcommand("build", "Time grid conversion against gdalwarp on the same target grid");
  sub->footer(
      "Example:\n  sandtable bench build --kernels bilinear,weighted --repeat 3\n"
      "Synthesizes a square (sandtable synth) unless --input names one, converts its DTED2 tree\n"
      "with our build and with the gdalwarp binary onto the same UTM grid, and reports the\n"
      "median seconds, posts/s and gdalwarp/ours ratios (> 1: we are faster). Needs gdal-bin.\n"
      "  sandtable bench build --distributed --tasks 8 -- --elevation N49E011.hgt.zip --spacing 30\n"
      "times the one-machine build, the plan, the tasks (1 and --concurrent at a time, threads 1) and\n"
      "the merge (MB/s, peak RSS, share of the one-machine build) and compares the databases byte for\n"
      "byte (docs/DISTRIBUTED.md).");
  sub->add_option("--input", o.input, "Existing synth output (uses DIR/dted2) or a directory of sources");
  sub->add_option("--size-km", o.sizeKm,
                  "Side of the synthesized square (default: enough for 5000 x 5000 posts; with --distributed, 40)")
      ->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--spacing", o.spacing, "Target post spacing in metres")
      ->default_val(30.0)
      ->check(CLI::PositiveNumber);
  sub->add_option("--kernels", o.kernels,
                  "Our kernels: weighted, bilinear (point samples, as gdalwarp), bilinear-triangles (plus the "
                  "triangle fit, as `sandtable build --resample bilinear`), cubic, average")
      ->delimiter(',')
      ->default_str("bilinear,weighted");
  sub->add_option("--repeat", o.repeat, "Timed runs of each measurement (median reported)")
      ->default_val(3)
      ->check(CLI::Range(1, 100));
  sub->add_option("--threads", o.threads,
                  "Threads for ours and gdalwarp -multi (0 = all cores); with --distributed, the one-machine "
                  "build's")
      ->default_val(0)
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--json", a->json, "Print the results as one JSON object");
  sub->add_flag("--keep", o.keep, "Keep the work directory (synth data, outputs, logs)");
  auto* dist = "Distributed build (--distributed; docs/DISTRIBUTED.md)";
  sub->add_flag("--distributed", a->distributed,
                "Time the one-machine build against plan, tasks (1 and --concurrent at a time) and merge, and "
                "check that the databases are byte-identical")
      ->group(dist);
  sub->add_option("--tasks", a->tasks, "Tasks to split the build into")->default_val(8)->group(dist);
  sub->add_option("--concurrent", a->concurrent, "Tasks run at once in the second pass (threads 1 each)")
      ->default_val(2)
      ->check(CLI::Range(1, 1024))
      ->group(dist);
  sub->add_option("BUILD_ARGS", a->buildArgs,
                  "After --: the build's arguments (sources, extent, spacing, ...; not -o, --threads or the "
                  "distributed flags); default: a synthesized square (--size-km, default 40) at --spacing")
      ->group(dist);
  c.add(sub, [a] { return run(*a); });
}

}  // namespace sandtable::cli