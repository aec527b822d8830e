// A parsed scenario made into a running simulation, and its terrain edits.
#include "sandtable/sim/scenario_load.h"

#include <cstdio>
#include <map>

#include "sandtable/edits/profile.h"

namespace sandtable::sim {

VehicleParams defaultVehicle(Mobility m, Domain d) {
  VehicleParams v;  // a 40 t tank
  if (m == Mobility::wheeled) {
    v.massKg = 10000;
    v.maxForceN = 60000;
    v.powerW = 250000;
    v.maxSpeedMs = 25;
    v.turnRateDegS = 25;
  } else if (d == Domain::sea || m == Mobility::ship) {
    v.massKg = 200000;
    v.maxSpeedMs = 15;
    v.turnRateDegS = 3;
  } else if (d == Domain::air) {
    v.maxSpeedMs = 300;
    v.turnRateDegS = 10;
  }
  return v;
}

namespace {

/// World (x, z) of A,B as a scenario writes it (lon/lat through
/// `toProjected`, or easting,northing): the one rule for entities and
/// terrain edits. "" or why it cannot be placed.
std::string toWorld(double a, double b, bool lonLat, const world::ToProjectedFn& toProjected, double originEasting,
                    double originNorthing, double& x, double& z) {
  double e = a, n = b;
  if (lonLat) {
    if (!toProjected) return "lon/lat positions need the database's CRS";
    if (std::string why = toProjected(a, b, e, n); !why.empty()) return why;
  }
  x = e - originEasting;
  z = originNorthing - n;
  return {};
}

Domain domainOf(ScenarioDomain d) {
  switch (d) {
    case ScenarioDomain::land: return Domain::land;
    case ScenarioDomain::sea: return Domain::sea;
    case ScenarioDomain::air: return Domain::air;
    case ScenarioDomain::munition: return Domain::munition;
  }
  return Domain::land;
}

Mobility mobilityOf(ScenarioMobility m) {
  switch (m) {
    case ScenarioMobility::simple: return Mobility::simple;
    case ScenarioMobility::tracked: return Mobility::tracked;
    case ScenarioMobility::wheeled: return Mobility::wheeled;
    case ScenarioMobility::ship: return Mobility::ship;
    case ScenarioMobility::aircraft: return Mobility::aircraft;
  }
  return Mobility::simple;
}

/// Builds a simulation from a scenario, one entity at a time.
class Loader {
 public:
  Loader(std::shared_ptr<SimWorld> world, const Scenario& s, const world::ToProjectedFn& toProjected,
         SimOptions options)
      : world_(world), scenario_(s), toProjected_(toProjected) {
    sim_ = std::make_unique<Simulation>(std::move(world), std::move(options));
  }

  Result<std::unique_ptr<Simulation>> run() {
    for (std::size_t k = 0; k < scenario_.entities.size(); ++k) {
      const EntitySpec& spec = scenario_.entities[k];
      if (!addEntity(spec, scenario_.driven && *scenario_.driven == k)) return std::move(problems_);
    }
    for (const GroupSpec& g : scenario_.groups) {
      for (const EntitySpec& spec : expandGroup(g, sim_->options().seed)) {
        if (!addEntity(spec, false)) return std::move(problems_);
      }
    }
    for (auto& [file, script] : scripts_) sim_->addScript(std::move(script.lines), std::move(script.map));
    return std::move(sim_);
  }

 private:
  struct ScriptFile {
    std::vector<ScriptLine> lines;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> map;
  };

  bool fail(const EntitySpec& spec, const std::string& message) {
    std::string m = "scenario: line ";
    m += std::to_string(spec.line);
    m += ": entity ";
    m += spec.name;
    m += ": ";
    m += message;
    problems_.push_back({scenario_.source, 0, m});
    return false;
  }

  /// The script lines of `spec` (its file read once), or null.
  ScriptFile* scriptOf(const EntitySpec& spec) {
    auto it = scripts_.find(spec.script);
    if (it != scripts_.end()) return &it->second;
    auto lines = readScriptFile(spec.script);
    if (!lines) {
      fail(spec, "script " + spec.script + ": " + lines.error());
      return nullptr;
    }
    return &scripts_.emplace(spec.script, ScriptFile{std::move(lines.value()), {}}).first->second;
  }

  /// World (x, z) of the spec's position, or of its script's first line.
  bool position(const EntitySpec& spec, const ScriptFile* script, double& x, double& z) {
    if (spec.a && spec.b) {
      const std::string why =
          toWorld(*spec.a, *spec.b, spec.lonLat, toProjected_, world_->originEasting(), world_->originNorthing(), x, z);
      return why.empty() || fail(spec, why);
    }
    if (script) {
      for (const ScriptLine& l : script->lines) {
        if (spec.scriptEntity && l.entity == *spec.scriptEntity) {
          x = l.x;
          z = l.z;
          return true;
        }
      }
    }
    return fail(spec, "has no position: give at=, or a script whose lines name its script-entity");
  }

  bool aircraftOf(const EntitySpec& spec, std::uint32_t& type) {
    if (auto it = aircraft_.find(spec.aircraft); it != aircraft_.end()) {
      type = it->second;
      return true;
    }
    auto p = readAircraftFile(spec.aircraft);
    if (!p) return fail(spec, "aircraft " + spec.aircraft + ": " + p.error());
    type = sim_->addAircraftType(std::move(p.value()));
    aircraft_.emplace(spec.aircraft, type);
    return true;
  }

  bool addEntity(const EntitySpec& spec, bool driven) {
    Entity e;
    e.name = spec.name;
    e.iconName = spec.icon;
    const auto icon = world_->iconIndex(spec.icon);
    if (!icon) {
      return fail(spec, "icon \"" + spec.icon +
                            "\" is not in the database's icons.pack; build the database with --icons DEFS that "
                            "define it (samples/icons.txt defines tank, truck, jeep, boat, jet, missile)");
    }
    e.icon = *icon;
    e.force = spec.force;
    e.domain = domainOf(spec.domain);
    e.mobility = mobilityOf(spec.mobility);
    e.vehicle = defaultVehicle(e.mobility, e.domain);
    e.headingDeg = spec.headingDeg;
    e.speedMs = spec.speedMs;
    e.fuel = spec.fuel;
    e.behaviours = {spec.behaviour.zigzag, spec.behaviour.environment, spec.behaviour.edge, spec.behaviour.fight,
                    spec.behaviour.engage};
    ScriptFile* script = nullptr;
    if (!spec.script.empty() && !(script = scriptOf(spec))) return false;
    double x = 0, z = 0;
    if (!position(spec, script, x, z)) return false;
    double y = 0;
    if (e.domain == Domain::air) {
      const double ground = world_->groundAt(x, z).value_or(0.0);
      y = spec.altitude ? *spec.altitude : ground + spec.agl.value_or(300.0);
      if (y <= ground) return fail(spec, "flies below the ground there; raise its altitude= or agl=");
    }
    e.position = {x, y, z};
    if (e.mobility == Mobility::aircraft && !aircraftOf(spec, e.aircraftType)) return false;
    if (driven) e.controller = Controller::driven;
    else if (e.behaviours.any()) e.controller = Controller::behaviour;
    e.autopilot = e.controller != Controller::behaviour;  // hold the initial course until told otherwise
    auto id = sim_->add(std::move(e));
    if (!id) return fail(spec, id.message());
    if (driven) sim_->driven = id.value();
    if (script && spec.scriptEntity) script->map.emplace_back(*spec.scriptEntity, id.value());
    return true;
  }

  std::shared_ptr<SimWorld> world_;
  const Scenario& scenario_;
  const world::ToProjectedFn& toProjected_;
  std::unique_ptr<Simulation> sim_;
  std::map<std::string, ScriptFile> scripts_;
  std::map<std::string, std::uint32_t> aircraft_;
  std::vector<Problem> problems_;
};

}  // namespace

Result<std::unique_ptr<Simulation>> makeSimulation(std::shared_ptr<SimWorld> world, const Scenario& scenario,
                                                   const world::ToProjectedFn& toProjected, SimOptions options) {
  return Loader(std::move(world), scenario, toProjected, std::move(options)).run();
}

Result<std::vector<edit::Edit>> makeTerrainEdits(const Scenario& scenario, const world::ToProjectedFn& toProjected,
                                                 const grid::PostLayout& layout) {
  std::vector<Problem> problems;
  auto fail = [&](const TerrainEditSpec& spec, const std::string& message) {
    problems.push_back({scenario.source, 0,
                        "scenario: line " + std::to_string(spec.line) + ": " +
                            std::string(edit::kindName(spec.kind)) + ": " + message});
  };
  const double east = layout.spacing * (layout.postsX - 1), south = layout.spacing * (layout.postsZ - 1);
  std::vector<edit::Edit> out;
  out.reserve(scenario.terrainEdits.size());
  for (std::size_t k = 0; k < scenario.terrainEdits.size(); ++k) {
    const TerrainEditSpec& spec = scenario.terrainEdits[k];
    edit::Edit e;
    e.id = k + 1;
    e.time = 0;
    e.origin = 0;
    e.kind = spec.kind;
    e.radius = spec.radius;
    e.depth = spec.depth;
    e.width = spec.width;
    e.height = spec.height;
    e.sideSlope = spec.sideSlope;
    e.points.reserve(spec.points.size());
    std::string why;
    for (const auto& p : spec.points) {
      double x = 0, z = 0;
      why = toWorld(p[0], p[1], spec.lonLat, toProjected, layout.originEasting, layout.originNorthing, x, z);
      if (!why.empty()) break;
      e.points.push_back({x, z});
    }
    if (!why.empty()) {
      fail(spec, why);
      continue;
    }
    if (std::string bad = edit::checkEdit(e); !bad.empty()) {
      fail(spec, bad);
      continue;
    }
    const edits::Box box = edits::support(e);
    if (box.x1 < 0 || box.x0 > east || box.z1 < 0 || box.z0 > south) {
      char where[200];
      std::snprintf(where, sizeof where,
                    "lies wholly outside the database: it reaches X %.1f .. %.1f, Z %.1f .. %.1f m, the grid "
                    "covers X 0 .. %.1f, Z 0 .. %.1f m (east and south of its north-west post)",
                    box.x0, box.x1, box.z0, box.z1, east, south);
      fail(spec, where);
      continue;
    }
    out.push_back(std::move(e));
  }
  if (!problems.empty()) return problems;
  return out;
}

}  // namespace sandtable::sim
