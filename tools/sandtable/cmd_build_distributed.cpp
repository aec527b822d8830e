// sandtable build --plan / --task / --merge / --executor: the build split
// into tasks (docs/DISTRIBUTED.md). The library does the work
// (sandtable/converters/distributed.h); this file maps flags, runs the
// executor (tasks here, or a Slurm job array) and prints what happened.
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "build_distributed.h"
#include "progress.h"
#include "sandtable/converters/distributed.h"

namespace sandtable::cli {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string selfExe() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("sandtable") : p.string();
}

/// Tasks whose part is missing or bad, as "0-3,7" for sbatch --array.
std::string arrayList(const std::vector<std::uint32_t>& tasks) {
  std::string s;
  for (std::size_t k = 0; k < tasks.size();) {
    std::size_t e = k;
    while (e + 1 < tasks.size() && tasks[e + 1] == tasks[e] + 1) ++e;
    s += (s.empty() ? "" : ",") + std::to_string(tasks[k]) + (e > k ? "-" + std::to_string(tasks[e]) : "");
    k = e + 1;
  }
  return s;
}

std::vector<std::uint32_t> missingTasks(const convert::Plan& plan) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t t = 0; t < plan.tasks.size(); ++t) {
    if (!convert::checkPart(plan, t)) out.push_back(t);
  }
  return out;
}

std::string planPathOf(const convert::Plan& plan) { return plan.parts + "/plan.json"; }

/// The batch script: one array task per build task, run where the plan was
/// written (a shared directory), logs under PARTS/logs.
std::string sbatchScript(const convert::Plan& plan, const DistributedArgs& d) {
  std::string s = "#!/bin/bash\n# sandtable build: one array task per build task (docs/DISTRIBUTED.md)\n";
  s += "#SBATCH --job-name=sandtable-build\n";
  s += "#SBATCH --array=0-" + std::to_string(plan.tasks.size() - 1) + "\n";
  s += "#SBATCH --cpus-per-task=" + std::to_string(d.cpusPerTask) + "\n";
  s += "#SBATCH --output=" + plan.parts + "/logs/task-%a.out\n";
  s += "#SBATCH --chdir=" + plan.directory + "\n";
  if (!d.partition.empty()) s += "#SBATCH --partition=" + d.partition + "\n";
  s += "exec " + selfExe() + " build --task " + planPathOf(plan) +
       " \"$SLURM_ARRAY_TASK_ID\" --threads \"${SLURM_CPUS_PER_TASK:-1}\"\n";
  return s;
}

volatile std::sig_atomic_t gStop = 0;
void onStop(int) { gStop = 1; convert::requestCancel(); }

/// Submits the missing tasks as one job array and waits for it (sbatch
/// --wait), printing each part as it lands. Ctrl-C cancels the job.
int runSlurm(const convert::Plan& plan, const DistributedArgs& d, const std::vector<std::uint32_t>& todo, bool quiet) {
  const std::string script = plan.parts + "/build.sbatch";
  {
    std::ofstream f(script);
    f << sbatchScript(plan, d);
    if (!f) return usageError("build", "cannot write " + script);
  }
  fs::create_directories(plan.parts + "/logs");
  std::string cmd = "sbatch --parsable --wait --array=" + arrayList(todo) + " " + script + " 2>&1";
  if (!quiet) std::fprintf(stderr, "slurm: %s\n", cmd.c_str());
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return usageError("build", "cannot run sbatch; is Slurm installed and SLURM_CONF set?");
  std::atomic<bool> finished{false};
  std::string jobId;
  char line[512];
  if (std::fgets(line, sizeof line, p)) jobId = std::string(line).substr(0, std::string(line).find_first_of(";\n"));
  if (!quiet) std::fprintf(stderr, "slurm: job %s, %zu array tasks\n", jobId.c_str(), todo.size());
  std::thread follow([&] {
    std::size_t shown = 0;
    for (int tick = 0; !finished; ++tick) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      if (gStop && !jobId.empty()) {
        const int rc = std::system(("scancel " + jobId).c_str());
        (void)rc;
        jobId.clear();
      }
      if (tick % 10 != 0 || quiet) continue;
      // Parts that have landed (a part appears whole, by rename); checked
      // byte by byte only once the array has ended.
      std::size_t landed = 0;
      for (const std::uint32_t t : todo) landed += fs::exists(convert::partPath(plan, t)) ? 1 : 0;
      if (landed != shown) {
        shown = landed;
        std::fprintf(stderr, "slurm: %zu of %zu tasks built\n", shown, todo.size());
      }
    }
  });
  std::string rest;
  while (std::fgets(line, sizeof line, p)) rest += line;
  const int status = ::pclose(p);
  finished = true;
  follow.join();
  if (!rest.empty() && !quiet) std::fprintf(stderr, "slurm: %s", rest.c_str());
  const std::vector<std::uint32_t> left = missingTasks(plan);
  if (gStop) {
    std::fprintf(stderr, "sandtable build: cancelled; job %s cancelled, %zu tasks left\n", jobId.c_str(), left.size());
    return 130;
  }
  if (!left.empty()) {
    std::fprintf(stderr,
                 "sandtable build: the job array ended (sbatch status %d) with %zu tasks unbuilt (%s); their logs "
                 "are %s/logs/task-N.out; run the same command again to build only those\n",
                 WIFEXITED(status) ? WEXITSTATUS(status) : status, left.size(), arrayList(left).c_str(),
                 plan.parts.c_str());
    return kProblems;
  }
  return kOk;
}

int runLocal(const convert::Plan& plan, const std::vector<std::uint32_t>& todo, int threads, bool quiet) {
  Progress progress(quiet);
  for (std::size_t k = 0; k < todo.size(); ++k) {
    const std::uint32_t t = todo[k];
    auto r = convert::buildTask(plan, t, threads, [&](double f, const std::string& s) {
      progress.update((double(k) + f) / double(todo.size()), "task " + std::to_string(t) + ": " + s);
    });
    if (!r) {
      progress.done();
      if (gStop) return 130;
      return reportProblems("build", r.problems());
    }
  }
  progress.done();
  return kOk;
}

int printTask(const convert::TaskReport& r, bool asJson) {
  if (asJson) {
    std::printf("%s\n", json({{"task", r.task}, {"skipped", r.skipped}, {"modules", r.modules}, {"blocks", r.blocks},
                              {"bytes", r.bytes}, {"seconds", r.seconds}})
                            .dump(2)
                            .c_str());
  } else if (r.skipped) {
    std::printf("task %u: its part is already built and whole; nothing to do\n", r.task);
  } else {
    std::printf("task %u: %llu modules, %llu grid blocks, %.1f MB part in %.2f s\n", r.task,
                static_cast<unsigned long long>(r.modules), static_cast<unsigned long long>(r.blocks),
                double(r.bytes) / 1e6, r.seconds);
  }
  return kOk;
}

Result<convert::Plan> readPlanHere(const std::string& path) {
  auto plan = convert::readPlan(path);
  if (!plan) return plan;
  // Relative paths in the plan are the planning directory's.
  std::error_code ec;
  fs::current_path(plan->directory, ec);
  if (ec) return Problem{path, 0, "plan: cannot enter its directory " + plan->directory + ": " + ec.message()};
  return plan;
}

}  // namespace

int runTask(const DistributedArgs& d, int threads, bool asJson) {
  if (d.task.size() != 2) return usageError("build", "--task takes PLAN.json and a task number");
  auto plan = readPlanHere(d.task[0]);
  if (!plan) return reportProblems("build", plan.problems());
  char* end = nullptr;
  const unsigned long t = std::strtoul(d.task[1].c_str(), &end, 10);
  if (d.task[1].empty() || *end != '\0') return usageError("build", "--task: \"" + d.task[1] + "\" is not a task number");
  std::signal(SIGINT, onStop);
  std::signal(SIGTERM, onStop);
  auto r = convert::buildTask(plan.value(), std::uint32_t(t), threads, {});
  if (!r) return gStop ? 130 : reportProblems("build", r.problems());
  return printTask(r.value(), asJson);
}

int runMerge(const DistributedArgs& d, const convert::MergeOptions& m, const PrintReport& print, bool asJson) {
  auto plan = readPlanHere(d.merge);
  if (!plan) return reportProblems("build", plan.problems());
  std::signal(SIGINT, onStop);
  std::signal(SIGTERM, onStop);
  Progress progress(asJson);
  auto r = convert::mergeParts(plan.value(), m, [&](double f, const std::string& s) { progress.update(f, s); });
  progress.done();
  if (!r) return gStop ? 130 : reportProblems("build", r.problems());
  return print(r.value(), m.output.empty() ? plan->options.output : m.output);
}

int runPlanned(const convert::PlanOptions& po, const DistributedArgs& d, const PrintReport& print, bool asJson) {
  std::signal(SIGINT, onStop);
  std::signal(SIGTERM, onStop);
  if (d.executor != "local" && d.executor != "slurm") {
    return usageError("build", "--executor takes local or slurm, not \"" + d.executor + "\"");
  }
  auto plan = convert::makePlan(po, {});
  if (!plan) return reportProblems("build", plan.problems());
  std::error_code ec;
  fs::create_directories(plan->parts, ec);
  if (ec) return usageError("build", "cannot create the parts directory " + plan->parts + ": " + ec.message());
  const std::string planPath = d.planOnly.empty() ? planPathOf(plan.value()) : d.planOnly;
  if (Status st = convert::writePlan(plan.value(), planPath); !st) return reportProblems("build", st.problems());
  if (!d.planOnly.empty() || d.emitSbatch) {
    if (d.emitSbatch) {
      std::printf("%s", sbatchScript(plan.value(), d).c_str());
    } else if (asJson) {
      std::printf("%s\n", json({{"plan", planPath}, {"tasks", plan->tasks.size()}, {"parts", plan->parts}}).dump(2).c_str());
    } else {
      std::printf("plan %s: %zu tasks, parts in %s\n  run: sandtable build --task %s I   (I = 0..%zu)\n  then: "
                  "sandtable build --merge %s\n",
                  planPath.c_str(), plan->tasks.size(), plan->parts.c_str(), planPath.c_str(), plan->tasks.size() - 1,
                  planPath.c_str());
    }
    return kOk;
  }
  const std::vector<std::uint32_t> todo = missingTasks(plan.value());
  if (!asJson) {
    std::fprintf(stderr, "plan %s: %zu tasks, %zu to build (%zu already built), executor %s\n", planPath.c_str(),
                 plan->tasks.size(), todo.size(), plan->tasks.size() - todo.size(), d.executor.c_str());
  }
  if (!todo.empty()) {
    const int rc = d.executor == "slurm" ? runSlurm(plan.value(), d, todo, asJson)
                                         : runLocal(plan.value(), todo, po.build.threads, asJson);
    if (rc != kOk) return rc;
  }
  Progress progress(asJson);
  auto r = convert::mergeParts(plan.value(), {po.build.output, po.build.force, po.build.threads},
                               [&](double f, const std::string& s) { progress.update(f, s); });
  progress.done();
  if (!r) return gStop ? 130 : reportProblems("build", r.problems());
  return print(r.value(), po.build.output);
}

}  // namespace sandtable::cli
