#pragma once
// bench paging's plot: holes and degraded frames (% of frames) against
// speed (log), one line per mode, as SVG or PNG. Private to sandtable_bench.
#include <string>

#include <nlohmann/json.hpp>

namespace sandtable::bench {

/// Writes the plot of `modes` (the report's "modes" object) to `file`,
/// PNG when it ends in .png, SVG otherwise. "" or what went wrong.
std::string writePlot(const std::string& file, const nlohmann::json& modes, const std::string& title);

}  // namespace sandtable::bench
