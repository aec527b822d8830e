// bench build --distributed (distributed_build.h).
#include "sandtable/bench/distributed_build.h"

#include <fcntl.h>
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
#include <mutex>
#include <stdexcept>
#include <thread>

#include "process.h"
#include "sandtable/converters/distributed.h"
#include "sandtable/converters/elevation.h"

namespace sandtable::bench {

/// Flags the bench sets itself, refused among the build's arguments.
const std::vector<std::string> kDistributedOwnFlags = {"-o",       "--output",     "--threads",      "--plan",      "--task",
                                            "--merge",  "--executor",   "--tasks",        "--parts",     "--force",
                                            "--json",   "--emit-sbatch", "--partition",   "--cpus-per-task"};

namespace {

using Step = DistributedStep;
using DistResult = DistributedBuildReport;
using DistInput = DistributedInput;

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


/// RssAnon of process `pid` from /proc, 0 once it has gone.
std::uint64_t rssAnonBytes(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(f, line);) {
    if (line.rfind("RssAnon:", 0) == 0) return std::strtoull(line.c_str() + 8, nullptr, 10) * 1024;
  }
  return 0;
}

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

namespace {

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

/// Starts argv[0] (the sandtable executable) with argv, its output to `log`.
pid_t spawnChild(const std::vector<std::string>& argv, const fs::path& log) {
  int rc = 0;
  const pid_t pid = detail::spawnLogged(argv, log, rc);
  if (pid < 0) throw DistFailure("cannot run " + argv[0] + ": " + std::strerror(rc));
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


std::string fmtNumber(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%.9g", v);
  return s;
}


/// The build's arguments: as given after --, or over a synth output (--input,
/// else one synthesized now, not timed): its DTED2, culture and square.
DistInput distInput(const DistributedBuildOptions& a, const fs::path& work, const Notes& notes) {
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
    notes.say("synthesizing a " + fmtNumber(km) + " km square into " + dir.string() + " (not timed)");
    runOne({a.executable, "synth", "-o", dir.string(), "--size-km", fmtNumber(km), "--threads",
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



double loadAverage1() {
  double l[1] = {0};
  return ::getloadavg(l, 1) == 1 ? l[0] : 0;
}


}  // namespace

nlohmann::json distributedBuildJson(const DistributedBuildReport& r) {
  const double oneAll = r.oneAll.median(), one1 = r.one1.median(), serial = r.serial.median(),
               conc = r.concurrentStep.median(), merge = r.merge.median();
  std::vector<double> perTask;
  for (const auto& t : r.perTask) perTask.push_back(stats::median(t));
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

namespace {

void distRepeat(const DistributedBuildOptions& a, DistResult& r, int rep, const fs::path& work,
                const std::function<std::vector<std::string>(std::vector<std::string>)>& build, const Notes& notes) {
  const fs::path one = work / "one", dist = work / "dist", parts = work / "parts", plan = work / "plan.json",
                 logs = work / "logs";
  const std::string& exe = a.executable;
  std::error_code ec;
  const auto note = [&](const std::string& what, double s) {
    char t[32];
    std::snprintf(t, sizeof t, " %.2f s", s);
    notes.say("repeat " + std::to_string(rep + 1) + "/" + std::to_string(a.o.repeat) + ": " + what + t);
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
  note("tasks " + std::to_string(a.concurrent) + " at a time:", wall);
  r.partsBytes = bytesUnder(parts, "part-");
  fs::remove_all(dist, ec);
  c = runOne({exe, "build", "--merge", plan.string(), "-o", dist.string(), "--force"}, logs / "merge.log");
  r.merge.add(c.wallS, c);
  note("merge:", c.wallS);
}

}  // namespace

Result<DistributedBuildReport> runDistributedBuildBench(const DistributedBuildOptions& a, const Notes& notes) {
  const char* tmp = std::getenv("TMPDIR");
  std::string tmpl = std::string(tmp && *tmp ? tmp : "/tmp") + "/sandtable-bench-distributed-XXXXXX";
  if (!::mkdtemp(tmpl.data())) return Problem{tmpl, 0, std::string("bench: cannot create a work directory: ") + std::strerror(errno)};
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
    r.input = distInput(a, work, notes);
    const std::string& exe = a.executable;
    const auto build = [&](std::vector<std::string> extra) {
      std::vector<std::string> v{exe, "build"};
      v.insert(v.end(), r.input.args.begin(), r.input.args.end());
      v.insert(v.end(), extra.begin(), extra.end());
      return v;
    };
    // Warm-up, not timed: the plan reads every input for its CRC, so every
    // step after it reads them from the page cache.
    notes.say("work directory " + work.string() + "; planning once, not timed");
    runOne(build({"-o", (work / "dist").string(), "--force", "--plan", (work / "plan.json").string(), "--tasks",
                  std::to_string(a.tasks), "--parts", (work / "parts").string()}),
           work / "logs" / "plan.log");
    auto plan = convert::readPlan((work / "plan.json").string());
    if (!plan) throw DistFailure("cannot read the plan: " + plan.problems().front().message);
    r.tasks = std::uint32_t(plan->tasks.size());
    r.perTask.assign(r.tasks, {});
    r.loadStart = loadAverage1();
    for (int rep = 0; rep < a.o.repeat; ++rep) distRepeat(a, r, rep, work, build, notes);
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
    return Problem{work.string(), 0, e.what() + std::string(a.o.keep ? "" : " (work directory removed; --keep keeps it)")};
  } catch (const nlohmann::json::exception& e) {
    if (!a.o.keep) fs::remove_all(work, ec);
    return Problem{work.string(), 0, std::string("the merged manifest: ") + e.what()};
  }
  if (!a.o.keep) fs::remove_all(work, ec);
  return r;
}

}  // namespace sandtable::bench
