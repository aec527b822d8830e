#pragma once
// What `sim` and `fly --scenario` share: the simulator's view of the one
// World the command opened, and a scenario made into a Simulation and its
// terrain edits, lon/lat through the database's CRS. Opens no database.
// Problems are printed; nullopt means exit 2.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/formats/edit.h"
#include "sandtable/paging/world.h"
#include "sandtable/sim/simulation.h"

namespace sandtable::cli {

struct SimSetup {
  std::shared_ptr<sim::SimWorld> world;
  std::unique_ptr<sim::Simulation> sim;
  std::string crsName;
  /// The scenario's crater, berm, ditch and flatten lines in the database
  /// frame (sim::makeTerrainEdits: origin 0, ids 1.. in file order, time 0),
  /// to apply before the first step.
  std::vector<edit::Edit> terrainEdits;
};

/// Reads `scenario` (and its scripts and aircraft files), places its
/// entities in `world` and converts its terrain edits with the same
/// transformer. `seed` overrides the scenario's. An empty
/// `scenario` makes a simulation with no entities (`fly --dis` watching).
std::optional<SimSetup> setUpSimulation(const std::string& cmd, const paging::World& world,
                                        const std::string& scenario, std::optional<std::uint64_t> seed,
                                        sim::SimOptions options = {});

}  // namespace sandtable::cli
