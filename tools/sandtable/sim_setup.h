#pragma once
// What `sim` and `fly --scenario` share: a database opened for the
// simulator and a scenario made into a Simulation, lon/lat through the
// database's CRS. Problems are printed; nullptr means exit 2.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "sandtable/sim/simulation.h"

namespace sandtable::cli {

struct SimSetup {
  std::shared_ptr<sim::SimWorld> world;
  std::unique_ptr<sim::Simulation> sim;
  std::string crsName;
};

/// Opens `db`, reads `scenario` (and its scripts and aircraft files), and
/// places its entities. `seed` overrides the scenario's.
std::optional<SimSetup> setUpSimulation(const std::string& cmd, const std::string& db, const std::string& scenario,
                                        std::optional<std::uint64_t> seed, sim::SimOptions options = {});

}  // namespace sandtable::cli
