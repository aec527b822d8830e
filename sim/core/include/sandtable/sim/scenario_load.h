#pragma once
// A scenario file (scenario.h, docs/SCRIPTS.md) made into a Simulation: its
// entities placed, sized from their icons, given their vehicle, aircraft,
// behaviours and scripts, and the driven one chosen; and its terrain edit
// lines made into edits in the database frame.
//
// The runtime has no PROJ: lon/lat positions reach the database's CRS
// through the caller's ToProjectedFn (the CLI passes one built on geodesy).
//
// Thread safety: pure functions; the Simulation returned belongs to the caller.
#include <memory>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/edit.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/sim/scenario.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/world/path.h"

namespace sandtable::sim {

/// The vehicle limits of a mobility (a 40 t tank, a 10 t truck, a patrol
/// boat, a slow aircraft without a model); VehicleParams documents them.
VehicleParams defaultVehicle(Mobility m, Domain d);

/// Builds the simulation with `options` as given (the caller chooses the
/// seed: a command line's, else Scenario::seed, else SimOptions'). Problems
/// name the scenario file and the entity's line: an icon the database's
/// icons.pack lacks, a position off the database or a ship off water, an
/// unreadable script or aircraft file.
Result<std::unique_ptr<Simulation>> makeSimulation(std::shared_ptr<SimWorld> world, const Scenario& scenario,
                                                   const world::ToProjectedFn& toProjected,
                                                   SimOptions options = {});

/// The scenario's terrain edit lines (Scenario::terrainEdits) as edits
/// (edit.h) in the database frame of `layout`, each point placed as an
/// entity's at= is (lon/lat through `toProjected`, then X = easting -
/// originEasting, Z = originNorthing - northing): kind and parameters as
/// read, origin 0 (this process), ids 1, 2, ... in file order, time 0. The
/// caller applies them before the first step. Problems name the scenario
/// file and the line: a point that does not project, an edit that lies
/// wholly outside the database (its edits::support box misses the grid).
Result<std::vector<edit::Edit>> makeTerrainEdits(const Scenario& scenario, const world::ToProjectedFn& toProjected,
                                                 const grid::PostLayout& layout);

}  // namespace sandtable::sim
