#pragma once
// The distributed modes of `sandtable build` (cmd_build_distributed.cpp).
#include <functional>
#include <string>
#include <vector>

#include "commands.h"
#include "sandtable/converters/distributed.h"

namespace sandtable::cli {

struct DistributedArgs {
  std::string planOnly;           ///< --plan FILE: write the plan, build nothing
  std::vector<std::string> task;  ///< --task PLAN I
  std::string merge;              ///< --merge PLAN
  std::string executor;           ///< --executor local | slurm ("" = not distributed)
  std::string partition;          ///< --partition P
  int cpusPerTask = 1;            ///< --cpus-per-task (slurm)
  bool emitSbatch = false;        ///< --emit-sbatch
};

/// Prints a finished build's report (the one-machine build's own output).
using PrintReport = std::function<int(const convert::ElevationReport&, const std::string& output)>;

int runTask(const DistributedArgs& d, int threads, bool asJson);
int runMerge(const DistributedArgs& d, const convert::MergeOptions& m, const PrintReport& print, bool asJson);
/// Plans, runs the missing tasks on the executor, merges (or, with --plan
/// or --emit-sbatch, writes the plan and stops).
int runPlanned(const convert::PlanOptions& po, const DistributedArgs& d, const PrintReport& print, bool asJson);

}  // namespace sandtable::cli
