#pragma once
// The build beyond one machine (issue 38; docs/DISTRIBUTED.md): a plan
// splits a build into tasks, each task builds its rows of grid blocks and
// load modules into a part (docs/FORMAT.md, "part"), and the merge streams
// the parts into the database. The merged database is byte-identical to the
// one-machine buildElevation of the same inputs and options, apart from the
// manifest's timings (kVolatileManifestKeys).
//
// A task resamples its own rows (and a halo), so tasks share nothing but
// the plan, the inputs and the parts directory; the one-machine build's
// stages (build_stages.h) do the work in both.
//
// Thread safety: each function may run concurrently with others on
// distinct tasks or plans; cancelRequested() stops them.
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/converters/elevation.h"

namespace sandtable::convert {

/// Module rows per task when PlanOptions::tasks is 0 (the seed's 1 km
/// modules: an 8 km strip of the database's width).
inline constexpr std::uint32_t kDefaultTaskModuleRows = 8;
/// Manifest keys (JSON pointers) that hold timings or the time of writing,
/// and the manifest's own checksum over them: the only bytes in which a
/// merged database may differ from a one-machine build.
inline constexpr const char* kVolatileManifestKeys[] = {
    "/checksum",              "/created_utc",           "/build/seconds",
    "/build/resample_seconds", "/build/posts_per_second",
    "/build/modules/seconds",  "/build/modules/modules_per_second",
    "/build/modules/stage_cpu_seconds", "/build/culture/load_seconds"};

struct PlanOptions {
  /// The build: inputs and parameters; output is the database the merge
  /// writes. threads and onEstimate do not enter the plan.
  ElevationOptions build;
  std::uint32_t tasks = 0;  ///< 0: one per kDefaultTaskModuleRows module rows; at most the module rows
  std::string parts;        ///< shared directory for the parts; "" = OUTPUT.parts
};

/// One task: the load-module rows it builds and the grid block rows it
/// writes. Rows partition the database: every module row and block row
/// belongs to exactly one task.
struct PlanTask {
  std::uint32_t index = 0;
  std::uint32_t moduleRow0 = 0, moduleRows = 0;
  std::uint32_t blockRow0 = 0, blockRows = 0;
  /// Block rows it resamples and fills: its own and those its modules read.
  std::uint32_t fillRow0 = 0, fillRows = 0;
};

/// One input as planned: its size and CRC-32.
struct PlanInput {
  std::string path, kind;  ///< kind: elevation | culture | materials | icons | objects
  std::uint64_t bytes = 0;
  std::uint32_t crc = 0;
};

struct Plan {
  ElevationOptions options;  ///< as planned (output: the merged database)
  std::string directory;     ///< working directory the paths are relative to
  std::string parts;         ///< absolute
  std::vector<PlanInput> inputs;
  std::uint32_t postsX = 0, postsZ = 0, blocksX = 0, blocksZ = 0;
  std::uint32_t modulesX = 0, modulesZ = 0, moduleSquares = 0;
  std::vector<PlanTask> tasks;
  std::string text;        ///< the plan file's bytes (JSON)
  std::uint32_t crc = 0;   ///< CRC-32 of text: every part names it
};

/// Opens the inputs (their CRCs), plans the frame and tiles the rows into
/// tasks. Deterministic: the same inputs and options give the same bytes.
/// Refuses what a distributed build cannot reproduce byte for byte: grid
/// only builds (ElevationOptions::modules) and the cubic and average
/// kernels (ElevationOptions::resample; GDALWarp chunks by the rows asked).
Result<Plan> makePlan(const PlanOptions& options, const ProgressFn& progress);
/// Writes the plan file atomically.
Status writePlan(const Plan& plan, const std::string& path);
/// Reads and checks a plan file (format, version, tasks that tile the rows).
Result<Plan> readPlan(const std::string& path);

/// The part file of task `task`: PARTS/part-NNNNN.stp.
std::string partPath(const Plan& plan, std::uint32_t task);
/// Whether task `task`'s part is there, of this plan and task, and whole
/// (every byte against its CRC). The problem says which.
Status checkPart(const Plan& plan, std::uint32_t task);

struct TaskReport {
  std::uint32_t task = 0;
  bool skipped = false;  ///< its part was already there and whole
  std::uint64_t modules = 0, blocks = 0, bytes = 0;
  double seconds = 0;
};

/// Builds task `task` into its part, atomically (a killed task leaves no
/// part); skipped when a whole part is there. Refuses inputs that changed
/// since the plan and rows that resample to voids (void fill looks at the
/// whole grid; build such sources on one machine).
Result<TaskReport> buildTask(const Plan& plan, std::uint32_t task, int threads, const ProgressFn& progress);

struct MergeOptions {
  std::string output;  ///< "" = the plan's output
  bool force = false;  ///< replace an existing output
  int threads = 0;
};

/// Streams every part into the database (grid.stg, modules.pack and .idx,
/// materials.txt, icons.pack, manifest.json) and publishes it atomically.
/// Every part is checked first (plan, task, CRC): a missing, foreign or
/// damaged part is refused, naming the task and the file. Memory is bounded
/// by a block, a module record and the pack index, whatever the size.
Result<ElevationReport> mergeParts(const Plan& plan, const MergeOptions& options, const ProgressFn& progress);

}  // namespace sandtable::convert
