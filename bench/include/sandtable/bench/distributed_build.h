#pragma once
// bench build --distributed (issue 38; docs/DISTRIBUTED.md): the one-machine
// build against the distributed one on the same arguments (plan, tasks one
// and several at a time, merge), every step the sandtable executable run as
// a child process, so tasks can run at once and each child's peak RSS and
// CPU time come from wait4; then the databases compared byte for byte.
//
// Thread safety: one run at a time per process (it waits for any child).
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/base/stats.h"
#include "sandtable/bench/build.h"
#include "sandtable/bench/notes.h"

namespace sandtable::bench {

struct DistributedBuildOptions {
  std::string executable;             ///< the sandtable CLI every step runs
  BuildBenchOptions o;                ///< input, sizeKm, spacing, repeat, threads (the one-machine build's), keep
  std::uint32_t tasks = 8;
  int concurrent = 2;                 ///< tasks at once in the second pass (threads 1 each)
  std::vector<std::string> buildArgs; ///< the build's own arguments; empty: a synth square (o.input / o.sizeKm)
};

/// Flags the bench sets itself, refused among DistributedBuildOptions::buildArgs.
extern const std::vector<std::string> kDistributedOwnFlags;
inline constexpr double kMergeGoalPercent = 10;

/// One child process as it ended.
struct ChildRun {
  double wallS = 0, cpuS = 0;
  std::uint64_t peakRssBytes = 0;   ///< ru_maxrss: heap and mapped file pages (a mapped grid counts whole)
  std::uint64_t peakAnonBytes = 0;  ///< largest RssAnon seen, sampled every few milliseconds
};

struct DistributedInput {
  std::vector<std::string> args;  ///< the build's arguments (sources, extent, spacing, ...)
  std::string description;
};

/// Samples of one measured step, in seconds, and the largest peak RSS.
struct DistributedStep {
  std::vector<double> samples;
  std::uint64_t peakRssBytes = 0, peakAnonBytes = 0;
  double cpuS = 0;  ///< median user + system seconds
  std::vector<double> cpuSamples;
  double median() const { return stats::median(samples); }
  void add(double wallS, const ChildRun& r) {
    samples.push_back(wallS);
    cpuSamples.push_back(r.cpuS);
    cpuS = stats::median(cpuSamples);
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

struct DistributedBuildReport {
  DistributedInput input;
  std::string work;
  std::uint32_t tasks = 0, postsX = 0, postsZ = 0;
  std::uint64_t modules = 0, partsBytes = 0, dbBytes = 0, gridBytes = 0, packBytes = 0;
  int repeat = 0, threads = 0, concurrent = 0;
  unsigned cpus = 0;
  double loadStart = 0, loadEnd = 0;
  DistributedStep oneAll, one1, plan, serial, concurrentStep, merge;
  std::vector<std::vector<double>> perTask;  ///< [task][repeat] seconds, 1 at a time
  std::vector<std::pair<std::string, bool>> identical;
  std::vector<std::string> manifestDiffs;
  double posts() const { return double(postsX) * double(postsZ); }
};

/// Runs it; problems say which step failed and where its log is.
Result<DistributedBuildReport> runDistributedBuildBench(const DistributedBuildOptions& options, const Notes& notes);
nlohmann::json distributedBuildJson(const DistributedBuildReport& r);

}  // namespace sandtable::bench
