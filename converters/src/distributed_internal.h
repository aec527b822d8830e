#pragma once
// What the plan, the tasks and the merge of a distributed build share
// (distributed_plan.cpp).
#include <array>
#include <functional>
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
/// `checksums` false: the sources are not read whole (their CRCs come from
/// checkSources).
Result<PlanFrame> openPlanned(const ElevationOptions& o, int threads, const ProgressFn& progress,
                              bool checksums = true);

/// Checks the sources against the plan's elevation inputs: every path and
/// size, and the CRC-32 (read whole here) of those `checksum` picks; then
/// gives every source the plan's CRC (the manifest's). A task checksums
/// the sources under its rows; the merge none (the tasks did).
Status checkSources(const Plan& p, std::vector<Source>& sources,
                    const std::function<bool(const Source&)>& checksum, int threads);
/// The lon/lat box (west, south, east, north) of grid rows [j0, j1) of
/// the frame, with a margin for the resampling kernels' reach.
std::array<double, 4> rowsLonLat(const Frame& f, std::uint32_t j0, std::uint32_t j1);

/// Size and CRC-32 of a file GDAL's VSI can read (local or /vsicurl/...).
Result<PlanInput> fingerprint(const std::string& path, const std::string& kind);
/// The culture, materials, icons and objects files' fingerprints.
Result<std::vector<PlanInput>> fingerprintOthers(const ElevationOptions& o);
std::vector<PlanInput> elevationInputs(const std::vector<Source>& sources);
/// Refuses culture, materials, icons and objects inputs that differ from the plan's.
Status sameOtherInputs(const Plan& p, const std::vector<PlanInput>& now);
/// Refuses a frame of another size than the plan's.
Status sameFrame(const Plan& p, const Frame& f);

}  // namespace sandtable::convert::detail
