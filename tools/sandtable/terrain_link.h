#pragma once
// What `sim` and `fly --scenario` share for dynamic terrain (docs/
// DYNAMIC.md, "Who decides"): the simulation's edits and the DIS network's
// go through the run's editor after every step, local ones published on the
// network first; the scenario's pre-placed edits before the first step.
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dis_link.h"
#include "sandtable/edits/editor.h"
#include "sandtable/sim/terrain_edits.h"

namespace sandtable::cli {

/// A TerrainEditing on `s` and `editor` (with the gateway's publish and
/// receive when `link`), with the scenario's `preplaced` edits applied.
std::unique_ptr<sim::TerrainEditing> linkTerrain(sim::Simulation& s, edits::Editor& editor, DisLink* link,
                                                 const std::vector<edit::Edit>& preplaced);
/// The summary line: "terrain edits: 12 applied (9 craters, ...)".
std::string terrainSummary(const sim::TerrainEditing& t, const edits::Editor& editor, const std::string& journal);
nlohmann::json terrainJson(const sim::TerrainEditing& t, const edits::Editor& editor, const std::string& journal);
/// The viewer panel's line: "EDITS 12  CRATERS 9  MODULES 14".
std::string terrainPanelLine(const edits::Editor& editor);

}  // namespace sandtable::cli
