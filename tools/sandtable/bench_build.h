#pragma once
// `sandtable bench build`: times our grid conversion against the gdalwarp
// binary on the same sources, target grid and a comparable kernel.
#include "commands.h"

namespace sandtable::cli {

/// Adds `build` under the `bench` group.
void registerBenchBuild(CLI::App& bench, Commands& c);

}  // namespace sandtable::cli
