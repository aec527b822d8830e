// Scenario loading for the CLI: the database's CRS turns lon/lat into the
// grid's easting and northing, for entities and terrain edits alike.
#include "sim_setup.h"

#include <cstdio>

#include "commands.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/sim/scenario_load.h"

namespace sandtable::cli {

std::optional<SimSetup> setUpSimulation(const std::string& cmd, const paging::World& w,
                                        const std::string& scenario, std::optional<std::uint64_t> seed,
                                        sim::SimOptions options) {
  // No scenario: a simulation with no entities of its own (a DIS watcher).
  auto scen = scenario.empty() ? Result<sim::Scenario>(sim::Scenario{}) : sim::readScenarioFile(scenario);
  if (!scen) {
    reportProblems(cmd, scen.problems());
    return std::nullopt;
  }
  auto geo = geodesy::Projection::create(w.manifest().crsWkt);
  if (!geo) {
    reportProblems(cmd, geo.problems());
    return std::nullopt;
  }
  auto world = sim::SimWorld::open(w);
  if (!world) {
    reportProblems(cmd, world.problems());
    return std::nullopt;
  }
  const geodesy::Projection& g = geo.value();
  const std::string crs = w.manifest().crsName;
  world::ToProjectedFn toProjected = [&](double lon, double lat, double& e, double& n) -> std::string {
    char where[64];
    std::snprintf(where, sizeof where, "%.6f %.6f", lon, lat);
    const auto en = g.toProjected({lon, lat});
    if (!en) return std::string(where) + " cannot be projected into " + crs;
    e = en->easting, n = en->northing;
    return {};
  };
  if (seed) options.seed = *seed;
  else if (scen->seed) options.seed = *scen->seed;
  auto made = sim::makeSimulation(world.value(), scen.value(), toProjected, std::move(options));
  if (!made) {
    reportProblems(cmd, made.problems());
    return std::nullopt;
  }
  auto edits = sim::makeTerrainEdits(scen.value(), toProjected, world.value()->heights().layout());
  if (!edits) {
    reportProblems(cmd, edits.problems());
    return std::nullopt;
  }
  return SimSetup{world.value(), std::move(made.value()), crs, std::move(edits.value())};
}

}  // namespace sandtable::cli
