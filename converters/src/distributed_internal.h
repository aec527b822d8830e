#pragma once
// What the plan, the tasks and the merge of a distributed build share
// (distributed_plan.cpp).
#include <string>
#include <vector>

#include "elevation_internal.h"
#include "sandtable/converters/distributed.h"

namespace sandtable::convert::detail {

/// The opened sources, the frame and the kernel, as buildElevation finds them.
struct PlanFrame {
  std::vector<Source> sources;
  Frame frame;
  KernelChoice kernel;
};
Result<PlanFrame> openPlanned(const ElevationOptions& o, int threads, const ProgressFn& progress);

/// Size and CRC-32 of a file GDAL's VSI can read (local or /vsicurl/...).
Result<PlanInput> fingerprint(const std::string& path, const std::string& kind);
/// The culture, materials, icons and objects files' fingerprints.
Result<std::vector<PlanInput>> fingerprintOthers(const ElevationOptions& o);
std::vector<PlanInput> elevationInputs(const std::vector<Source>& sources);
/// Refuses inputs of `kind` (elevation, or any other) that differ from the plan's.
Status sameInputs(const Plan& p, const std::vector<PlanInput>& now, const std::string& kind);
/// Refuses a frame of another size than the plan's.
Status sameFrame(const Plan& p, const Frame& f);

}  // namespace sandtable::convert::detail
