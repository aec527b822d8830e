#pragma once
// A scenario file (scenario.h, docs/SCRIPTS.md) made into a Simulation: its
// entities placed, sized from their icons, given their vehicle, aircraft,
// behaviours and scripts, and the driven one chosen.
//
// The runtime has no PROJ: lon/lat positions reach the database's CRS
// through the caller's ToProjectedFn (the CLI passes one built on geodesy).
//
// Thread safety: pure functions; the Simulation returned belongs to the caller.
#include <memory>
#include <string>

#include "sandtable/base/result.h"
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

}  // namespace sandtable::sim
