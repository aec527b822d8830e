#pragma once
// `sandtable bench render DB`: the stealth viewer's frame rate and frame
// times for seed-style range-ring LoD, screen-space-error LoD and the full
// resolution, over the same flight in one run.
#include "commands.h"

namespace sandtable::cli {

/// Adds `render` under the `bench` group.
void registerBenchRender(CLI::App& bench, Commands& c);

}  // namespace sandtable::cli
