#pragma once
// `sandtable bench modules`: the full build (culture + load modules)
// against the elevation-only build of the same synthetic square.
#include "commands.h"

namespace sandtable::cli {

/// Adds `modules` under the `bench` group.
void registerBenchModules(CLI::App& bench, Commands& c);

}  // namespace sandtable::cli
