// The fixed-step simulation: entities, scripts, behaviours, munitions and
// collisions (seed chapters VII and VIII).
#include "sandtable/sim/simulation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "sandtable/edits/profile.h"
#include "sandtable/sim/motion.h"
#include "sandtable/sim/step_host.h"

namespace sandtable::sim {

const char* eventKindName(EventKind k) {
  switch (k) {
    case EventKind::fire: return "fire";
    case EventKind::detonation: return "detonation";
    case EventKind::kill: return "kill";
    case EventKind::objectCollision: return "object-collision";
    case EventKind::entityCollision: return "entity-collision";
    case EventKind::crash: return "crash";
    case EventKind::aground: return "aground";
    case EventKind::removed: return "removed";
    case EventKind::terrainEdit: return "terrain-edit";
  }
  return "?";
}

namespace {

/// Sizes and capabilities from the icon definition.
void sizeFromIcon(Entity& e, const iconpack::Icon& icon) {
  const auto& b = icon.bounds;
  e.halfLength = std::max({std::abs(double(b[2])), std::abs(double(b[5])), 0.5});
  e.halfWidth = std::max({std::abs(double(b[0])), std::abs(double(b[3])), 0.5});
  e.radius = icon.cylinderRadius > 0 ? icon.cylinderRadius : std::max(e.halfLength, e.halfWidth);
  e.height = icon.cylinderHeight > 0 ? icon.cylinderHeight : 2.0;
  double s = 0;
  for (float v : b) s = std::max(s, std::abs(double(v)));
  e.sphereRadius = std::max(s, 0.5);
  e.armed = icon.armed;
  e.resupply = icon.resupply;
}

std::uint64_t cellKey(double x, double z, double cell) {
  const auto cx = static_cast<std::int64_t>(std::floor(x / cell)) + (1 << 30);
  const auto cz = static_cast<std::int64_t>(std::floor(z / cell)) + (1 << 30);
  return (std::uint64_t(cx) << 32) | std::uint64_t(cz);
}

bool isMunition(const Entity& e) { return e.domain == Domain::munition; }

}  // namespace

Simulation::Simulation(std::shared_ptr<SimWorld> world, SimOptions options)
    : world_(std::move(world)), options_(std::move(options)), munitionTypes_(builtinMunitions()) {
  triangles_.resize(world_->icons().icons.size());
  trianglesBuilt_.assign(world_->icons().icons.size(), false);
}

std::uint32_t Simulation::addAircraftType(AircraftParams params) {
  aircraftTypes_.push_back(std::move(params));
  return static_cast<std::uint32_t>(aircraftTypes_.size() - 1);
}

Simulation::Record* Simulation::recordOf(std::uint32_t id) {
  return id < slots_.size() && slots_[id] != kGone ? &records_[slots_[id]] : nullptr;
}

const Simulation::Record* Simulation::recordOf(std::uint32_t id) const {
  return id < slots_.size() && slots_[id] != kGone ? &records_[slots_[id]] : nullptr;
}

Entity* Simulation::find(std::uint32_t id) {
  Record* r = recordOf(id);
  return r ? &r->entity : nullptr;
}

const Entity* Simulation::find(std::uint32_t id) const {
  const Record* r = recordOf(id);
  return r ? &r->entity : nullptr;
}

AirState* Simulation::airState(std::uint32_t id) {
  Record* r = recordOf(id);
  return r ? &r->air : nullptr;
}

AirControls* Simulation::airControls(std::uint32_t id) {
  Record* r = recordOf(id);
  return r ? &r->airControls : nullptr;
}

const std::string* Simulation::nameOf(std::uint32_t id) const {
  if (const Entity* e = find(id)) return &e->name;
  const auto it = removedNames_.find(id);
  return it != removedNames_.end() ? &it->second : nullptr;
}

Simulation::Record& Simulation::append(Entity e) {
  e.id = nextId_++;
  slots_.push_back(static_cast<std::uint32_t>(records_.size()));
  Record& r = records_.emplace_back();
  r.entity = std::move(e);
  return r;
}

bool Simulation::remove(std::uint32_t id) {
  Record* r = recordOf(id);
  if (!r) return false;
  Entity& e = r->entity;
  emit({0, EventKind::removed, id, UINT32_MAX, UINT32_MAX, e.position, {}, {}});
  removedNames_.emplace(id, std::move(e.name));
  const std::uint32_t slot = slots_[id];
  records_.erase(records_.begin() + slot);
  slots_[id] = kGone;
  for (std::size_t k = slot; k < records_.size(); ++k) --slots_[records_[k].entity.id];
  // What named it by id: the cells are rebuilt at the next step, the
  // rest looks the id up (find) and lets go of an id that is gone.
  cells_.clear();
  std::erase_if(pendingFire_, [&](const PendingFire& f) { return f.shooter == id; });
  if (driven == id) driven.reset();
  return true;
}

Result<std::uint32_t> Simulation::add(Entity e) {
  const std::uint32_t id = nextId_;
  if (e.icon < world_->icons().icons.size() && !isMunition(e)) sizeFromIcon(e, world_->icons().icons[e.icon]);
  if (e.behaviours.edge) placeOutsideBuffer(*world_, e, options_.behaviour);
  const std::string where = "entity " + std::to_string(id) + " (" + e.name + ")";
  if (!world_->onGrid(e.position.x(), e.position.z())) {
    return Problem{"", 0, "simulation: " + where + " stands off the database; place it inside the grid"};
  }
  if (e.domain == Domain::sea && e.controller != Controller::remote && !world_->navigable(e.position.x(), e.position.z())) {
    return Problem{"", 0, "simulation: ship " + where + " is not on water; place it on the sea or a lake"};
  }
  e.commands.speedMs = e.speedMs;
  e.commands.headingDeg = e.headingDeg;
  if (e.domain == Domain::land || e.domain == Domain::sea) {
    const double ground = world_->groundAt(e.position.x(), e.position.z()).value_or(0.0);
    e.position.y() = e.domain == Domain::sea ? std::max(0.0, ground) : ground;
    if (e.domain == Domain::land) {
      if (auto a = projectedPointAttitude(*world_, e.position.x(), e.position.z(), e.headingDeg, e.halfLength,
                                          e.halfWidth)) {
        e.pitchDeg = a->pitchDeg;
        e.rollDeg = a->rollDeg;
      }
    }
    e.velocity = headingVector(e.headingDeg) * e.speedMs;
  }
  AirState air;
  if (e.domain == Domain::air) {
    e.commands.altitudeM = e.position.y();
    if (e.mobility == Mobility::aircraft) {
      if (e.aircraftType >= aircraftTypes_.size()) {
        return Problem{"", 0, "simulation: aircraft " + where + " has no aircraft type; give it an aircraft file"};
      }
      air = levelFlight(aircraftTypes_[e.aircraftType], e.position, e.headingDeg, e.speedMs);
      const Euler eu = eulerFromOrientation(air.orientation);
      e.headingDeg = eu.headingDeg;
      e.pitchDeg = eu.pitchDeg;
      e.rollDeg = eu.rollDeg;
      e.velocity = air.velocity;
    } else {
      e.pitchDeg = e.rollDeg = 0;
      e.velocity = headingVector(e.headingDeg) * e.speedMs;
    }
  }
  append(std::move(e)).air = air;
  return id;
}

void Simulation::addScript(std::vector<ScriptLine> lines,
                           std::vector<std::pair<std::uint32_t, std::uint32_t>> entityToId) {
  std::sort(entityToId.begin(), entityToId.end());
  for (const auto& [scriptEntity, id] : entityToId) {
    if (Record* r = recordOf(id)) {
      r->scripted = true;
      r->entity.controller = Controller::script;
    }
  }
  scripts_.push_back({ScriptPlayer(std::move(lines)), std::move(entityToId)});
}

void Simulation::record(std::uint32_t id, std::uint32_t scriptEntity, std::uint32_t scriptType, RecorderOptions o) {
  recorder_.emplace(o);
  recordId_ = id;
  recordEntity_ = scriptEntity;
  recordType_ = scriptType;
}

std::vector<std::vector<ScriptLine>> Simulation::playedScripts() const {
  std::vector<std::vector<ScriptLine>> out;
  for (const Script& s : scripts_) out.push_back(s.player.lines());
  return out;
}

void Simulation::finishRecording() {
  if (recorder_) recorder_->finish();
}

void Simulation::emit(Event ev) {
  ev.timeS = timeS();
  switch (ev.kind) {
    case EventKind::fire: ++counters_.fired; break;
    case EventKind::detonation: ++counters_.detonations; break;
    case EventKind::kill: ++counters_.kills; break;
    default: break;
  }
  events_.push_back(std::move(ev));
}

void Simulation::kill(std::uint32_t id, std::uint32_t by, const std::string& detail) {
  Entity* found = find(id);
  if (!found || !found->alive) return;
  Entity& e = *found;
  if (e.controller == Controller::remote) return;  // its owner decides (a Detonation PDU names it)
  e.alive = false;
  e.speedMs = 0;
  e.velocity.setZero();
  e.commands.speedMs = 0;
  e.controls = {};
  if (!isMunition(e)) emit({0, EventKind::kill, id, by, UINT32_MAX, e.position, {}, detail});
}

bool Simulation::destroy(std::uint32_t id, std::uint32_t by, const std::string& detail) {
  const Entity* e = find(id);
  if (!e || !e->alive || e->controller == Controller::remote) return false;
  kill(id, by, detail);
  return true;
}

std::uint32_t Simulation::fire(std::uint32_t shooter, double azimuthDeg, double elevationDeg, std::uint16_t type,
                               std::uint32_t target) {
  const Entity* shooterEntity = find(shooter);
  if (!shooterEntity) return UINT32_MAX;
  const Entity& s = *shooterEntity;
  const MunitionType& t = munitionTypes_[type];
  Entity m;
  m.name = t.name;
  m.domain = Domain::munition;
  m.mobility = t.guided ? Mobility::guided : Mobility::ballistic;
  m.force = s.force;
  m.iconName = t.name;
  m.icon = world_->iconIndex(t.name).value_or(UINT16_MAX);
  const Eigen::Vector3d dir = orientationOf(azimuthDeg, elevationDeg, 0) * Eigen::Vector3d(0, 0, -1);
  m.position = s.position + Eigen::Vector3d(0, s.height * 0.7, 0) +
               headingVector(azimuthDeg) * (std::max(s.halfLength, s.radius) + 1.0);
  m.velocity = dir * t.speedMs;
  m.speedMs = t.speedMs;
  m.headingDeg = wrapDeg(azimuthDeg);
  m.pitchDeg = elevationDeg;
  m.radius = m.sphereRadius = t.radius;
  m.height = 0;
  m.launcher = shooter;
  m.target = target;
  m.fuseS = t.lifeS;
  m.munitionType = type;
  const std::uint32_t id = nextId_;
  emit({0, EventKind::fire, id, shooter, UINT32_MAX, m.position, t.name, {}});
  append(std::move(m));
  return id;
}

void Simulation::applyScripts() {
  const double now = timeS();
  for (Script& s : scripts_) {
    auto idOf = [&](std::uint32_t scriptEntity) -> std::uint32_t {
      auto it = std::lower_bound(s.map.begin(), s.map.end(), std::make_pair(scriptEntity, 0u));
      return it != s.map.end() && it->first == scriptEntity ? it->second : UINT32_MAX;
    };
    s.player.advance(
        now,
        [&](std::uint32_t scriptEntity) {
          const Entity* e = find(idOf(scriptEntity));
          return e && e->alive;
        },
        [&](const ScriptLine& line) {
          const std::uint32_t id = idOf(line.entity);
          Record* r = recordOf(id);
          if (!r) return;  // not mapped, or removed: the line is consumed and ignored
          r->lastLine = line;
          r->lineApplied = true;
          Entity& e = r->entity;
          e.headingDeg = e.commands.headingDeg = wrapDeg(line.directionDeg);
          e.speedMs = e.commands.speedMs = line.speed;
          e.gunAzimuthDeg = line.viewDirectionDeg;
          if (line.fire) pendingFire_.push_back({id, line.viewDirectionDeg, line.gunElevation * kRadToDeg});
          if (!line.alive) kill(id, UINT32_MAX, "script");
        });
  }
}

void Simulation::behave(Record& r) {
  Entity& e = r.entity;
  const BehaviourOptions& o = options_.behaviour;
  if (e.controller == Controller::behaviour) {
    if (e.behaviours.zigzag) zigzag(e, timeS(), options_.seed, draws_, o);
    if (e.behaviours.environment) {
      environmentLimit(*world_, e, o);
      avoidObjects(*world_, e, o, &counters_.search);
    }
    if (e.behaviours.edge) edgeOfWorld(*world_, e, o);
    if (e.behaviours.engage && e.armed) engage(e);
  }
  const bool steered = e.controller == Controller::behaviour || e.controller == Controller::script || e.autopilot;
  if (steered && (e.mobility == Mobility::tracked || e.mobility == Mobility::wheeled)) landAutopilot(e);
  if (steered && e.mobility == Mobility::aircraft && e.aircraftType < aircraftTypes_.size()) {
    r.airControls = holdAttitude(aircraftTypes_[e.aircraftType], r.air, e.commands.headingDeg, e.commands.altitudeM,
                                 e.commands.speedMs);
  }
}

void Simulation::engage(Entity& e) {
  const BehaviourOptions& o = options_.behaviour;
  const double now = timeS();
  if (e.nextShotS == 0) e.nextShotS = now + behaviourRandom(options_.seed ^ 0xe17a, e.id, 0) * o.engageReloadS;
  if (now < e.nextShotS) return;
  e.nextShotS = now + o.engageReloadS;
  // The nearest enemy in range and in sight; neutrals are nobody's enemy.
  const Eigen::Vector3d eye = e.position + Eigen::Vector3d(0, e.height * 0.7, 0);
  const Entity* best = nullptr;
  double bestD = o.engageRangeM * o.engageRangeM;
  for (const Record& r : records_) {
    const Entity& t = r.entity;
    if (!t.alive || t.domain == Domain::munition || t.force == e.force || t.force == 0 || e.force == 0) continue;
    const double d = (t.position - e.position).squaredNorm();
    if (d >= bestD) continue;
    if (!lineOfSight(*world_, eye, t.position + Eigen::Vector3d(0, t.height * 0.5, 0))) continue;
    best = &t;
    bestD = d;
  }
  if (!best) return;
  const Eigen::Vector3d to = best->position - e.position;
  const double elevation = std::atan2(to.y(), std::hypot(to.x(), to.z())) * kRadToDeg;
  e.gunAzimuthDeg = headingOf(to.x(), to.z());
  pendingFire_.push_back({e.id, e.gunAzimuthDeg, elevation + 1.0, 0, best->id});
}

void Simulation::moveAir(Record& r) {
  Entity& e = r.entity;
  const double dt = options_.stepS;
  if (e.mobility == Mobility::aircraft && e.aircraftType < aircraftTypes_.size()) {
    AirState& s = r.air;
    stepAircraft(aircraftTypes_[e.aircraftType], r.airControls, s, dt);
    e.position = s.position;
    e.velocity = s.velocity;
    e.angularVelocity = s.angularVelocity;
    e.throttle = s.throttle;
    const Euler eu = eulerFromOrientation(s.orientation);
    e.headingDeg = eu.headingDeg;
    e.pitchDeg = eu.pitchDeg;
    e.rollDeg = eu.rollDeg;
    e.speedMs = s.velocity.norm();
    const double full = aircraftTypes_[e.aircraftType].fuelCapacity;
    e.fuel = full > 0 ? s.fuelKg / full : 1.0;
  } else {
    // Table 5: first-order speed, heading and climb.
    const double before = e.headingDeg;
    e.speedMs = e.commands.speedMs;
    const double turn = std::clamp(turnBetween(e.headingDeg, e.commands.headingDeg),
                                   -e.vehicle.turnRateDegS * dt, e.vehicle.turnRateDegS * dt);
    e.headingDeg = wrapDeg(e.headingDeg + turn);
    const double climb = std::clamp(e.commands.altitudeM - e.position.y(), -10 * dt, 10 * dt);
    const Eigen::Vector3d old = e.position;
    e.position += headingVector(e.headingDeg) * (e.speedMs * dt) + Eigen::Vector3d(0, climb, 0);
    e.pitchDeg = e.speedMs > 0 ? std::atan2(climb / dt, e.speedMs) * kRadToDeg : 0;
    e.rollDeg = 0;
    e.velocity = (e.position - old) / dt;
    e.angularVelocity = {0, -turnBetween(before, e.headingDeg) * kDegToRad / dt, 0};
  }
  const auto ground = world_->groundAt(e.position.x(), e.position.z());
  if (!ground) {
    e.position = r.before;
    return;
  }
  e.heightAgl = e.position.y() - *ground;
  if (e.heightAgl < 0) {
    e.position.y() = *ground;
    emit({0, EventKind::crash, e.id, UINT32_MAX, UINT32_MAX, e.position, {}, "terrain"});
    kill(e.id, UINT32_MAX, "crash");
  }
}

void Simulation::move(Record& r) {
  Entity& e = r.entity;
  const double dt = options_.stepS;
  if (r.scripted) {
    // Between lines a scripted entity is dead reckoned from its last line;
    // before its first it waits where the scenario put it.
    if (!r.lineApplied) return;
    const ScriptLine& line = r.lastLine;
    const Eigen::Vector2d p = deadReckon(line, timeS() + dt);
    const auto a = projectedPointAttitude(*world_, p.x(), p.y(), e.headingDeg, e.halfLength, e.halfWidth);
    if (!a) return;
    const Eigen::Vector3d old = e.position;
    const bool flying = e.domain == Domain::air && line.y != 0;
    e.position = {p.x(), flying ? line.y : a->groundY, p.y()};
    e.pitchDeg = flying ? 0 : a->pitchDeg;
    e.rollDeg = flying ? 0 : a->rollDeg;
    e.velocity = (e.position - old) / dt;
    return;
  }
  if (e.domain == Domain::air) {
    moveAir(r);
    return;
  }
  const double speedBefore = e.speedMs;
  stepSurface(*world_, e, dt);
  if (e.domain == Domain::sea && speedBefore != 0 && e.speedMs == 0 && e.commands.speedMs != 0) {
    // Stopped at the shore: one event per grounding; computer-generated
    // ships turn about (the environment behaviour usually turned them before).
    emit({0, EventKind::aground, e.id, UINT32_MAX, UINT32_MAX, e.position, {}, {}});
    if (e.controller == Controller::behaviour && std::abs(turnBetween(e.headingDeg, e.commands.headingDeg)) < 90) {
      e.commands.headingDeg = wrapDeg(e.headingDeg + 180);
    }
  }
}

void Simulation::step() {
  // A module the source replaced (dynamic terrain) is read again before the
  // step; a failed read keeps the module as it was.
  static_cast<void>(world_->refresh());
  for (Record& r : records_) r.before = r.entity.position;
  applyScripts();
  if (const Entity* recorded = recorder_ ? find(recordId_) : nullptr) {
    const Entity& e = *recorded;
    ScriptLine line;
    line.setTime(timeS());
    line.entity = recordEntity_;
    line.type = recordType_;
    line.x = e.position.x();
    line.z = e.position.z();
    line.y = e.domain == Domain::air ? e.position.y() : 0.0;
    line.directionDeg = e.headingDeg;
    line.viewDirectionDeg = e.gunAzimuthDeg;
    line.gunElevation = e.gunElevationDeg * kDegToRad;
    line.aboveGroundLevel = e.heightAgl;
    line.speed = Eigen::Vector2d(e.velocity.x(), e.velocity.z()).norm() * (e.speedMs < 0 ? -1 : 1);
    line.alive = e.alive;
    recorder_->record(line);
  }
  bucketEntities();
  // Nothing adds or removes a record until the launches below.
  for (Record& r : records_) {
    Entity& e = r.entity;
    if (!e.alive) continue;
    ++counters_.entitySteps;
    if (e.controller == Controller::remote) {  // placed by the network before the step
      if (isMunition(e)) senseRemoteMunition(e);
      continue;
    }
    if (isMunition(e)) {
      flyMunition(e);
      continue;
    }
    behave(r);
    move(r);
    if (options_.collisions && e.alive) collideStatic(r);
  }
  if (options_.collisions) collideMoving();
  for (const PendingFire& f : pendingFire_) {
    const Entity* shooter = find(f.shooter);
    if (shooter && shooter->alive) fire(f.shooter, f.azimuthDeg, f.elevationDeg, f.type, f.target);
  }
  pendingFire_.clear();
  ++steps_;
  ++counters_.steps;
}

void Simulation::runFor(double seconds) { StepHost(*this).runFor(seconds); }

std::string Simulation::entityClass(const Entity& e) const {
  switch (e.domain) {
    case Domain::munition: return "missile";
    case Domain::air: return "airplane";
    case Domain::sea: return "ship";
    case Domain::land: return "tank";
  }
  return "tank";
}

void Simulation::applyObjectResult(std::uint32_t object, ObjectResult r) {
  switch (r) {
    case ObjectResult::none: return;
    case ObjectResult::knockedOver: world_->setObjectState(object, ObjectState::knockedOver); return;
    case ObjectResult::stump: world_->setObjectState(object, ObjectState::stump); return;
    case ObjectResult::ruins: world_->setObjectState(object, ObjectState::ruins); return;
    case ObjectResult::destroyed: world_->setObjectState(object, ObjectState::destroyed); return;
  }
}

void Simulation::collideStatic(Record& r) {
  Entity& e = r.entity;
  const Eigen::Vector3d& before = r.before;
  if (e.position == before) return;  // objects do not move: nothing new can touch
  auto near = [&](const Eigen::Vector3d& p, std::vector<std::uint32_t>& out) {
    out.clear();
    if (options_.bruteForce) world_->objectsNearBruteForce(p.x(), p.z(), e.radius, p.y(), out);
    else world_->objectsNear(p.x(), p.z(), e.radius, p.y(), out, &counters_.search);
  };
  near(e.position, scratch_);
  if (e.pressing != UINT32_MAX && !std::binary_search(scratch_.begin(), scratch_.end(), e.pressing)) {
    // It stood clear of the object that stopped it last; a new touch is a new collision.
    near(before, touched_);
    if (!std::binary_search(touched_.begin(), touched_.end(), e.pressing)) e.pressing = UINT32_MAX;
  }
  if (scratch_.empty()) return;
  // A collision is moving into an object: one already touched where the
  // step began (an entity placed over a tree) is left alone.
  near(before, touched_);
  std::uint32_t o = UINT32_MAX;
  for (std::uint32_t k : scratch_) {
    if (!std::binary_search(touched_.begin(), touched_.end(), k)) {
      o = k;
      break;
    }
  }
  if (o == UINT32_MAX) return;
  const StaticObject& obj = world_->objects()[o];
  const double speed = std::abs(e.speedMs);
  const StaticOutcome out = lookup(options_.table, entityClass(e), objectKindName(obj.kind), speed);
  if (o == e.pressing && out.entity == EntityResult::stop && out.object == ObjectResult::none) {
    e.position = before;  // still pushing against what stopped it: held, no new event
    e.speedMs = 0;
    e.velocity.setZero();
    return;
  }
  e.pressing = out.entity == EntityResult::stop ? o : UINT32_MAX;
  ++counters_.collisions.objects;
  std::string detail(resultName(out.entity));
  detail += "/";
  detail += resultName(out.object);
  emit({0, EventKind::objectCollision, e.id, UINT32_MAX, o, e.position, {}, detail});
  applyObjectResult(o, out.object);
  if (out.entity == EntityResult::destroyed) {
    kill(e.id, UINT32_MAX, "object");
  } else if (out.entity == EntityResult::stop) {
    e.position = before;
    e.speedMs = 0;
    e.velocity.setZero();
    if (e.domain == Domain::air) r.air.velocity.setZero();
    if (e.controller == Controller::behaviour) {
      e.commands.headingDeg = wrapDeg(e.headingDeg + 180);  // back away from it
    } else {
      e.commands.speedMs = 0;
    }
  }
}

void Simulation::bucketEntities() {
  cells_.clear();
  for (std::uint32_t k = 0; k < records_.size(); ++k) {
    const Entity& e = records_[k].entity;
    if (!e.alive || isMunition(e)) continue;
    cells_.emplace_back(cellKey(e.position.x(), e.position.z(), options_.entityBoxM), k);
  }
  std::sort(cells_.begin(), cells_.end());
}

const std::vector<Triangle>& Simulation::trianglesOf(std::uint16_t icon) {
  static const std::vector<Triangle> none;
  if (icon >= triangles_.size()) return none;
  if (!trianglesBuilt_[icon]) {
    trianglesBuilt_[icon] = true;
    const iconpack::Icon& ic = world_->icons().icons[icon];
    const float mid = ic.cylinderHeight * 0.5f;  // body frame origin at mid-height (see collidePair)
    for (std::size_t p = 0; p < ic.parts.size(); ++p) {
      const iconpack::Part& part = ic.parts[p];
      if (part.state != iconpack::State::alive) continue;
      const auto o = iconpack::partOrigin(ic, p);
      for (const iconpack::Mesh& m : part.meshes) {
        if (m.levels.empty()) continue;
        const std::vector<std::uint32_t>& idx = m.levels.front();
        auto at = [&](std::uint32_t v) {
          return Eigen::Vector3f(m.positions[3 * v] + o[0], m.positions[3 * v + 1] + o[1] - mid,
                                 m.positions[3 * v + 2] + o[2]);
        };
        for (std::size_t k = 0; k + 2 < idx.size(); k += 3) {
          triangles_[icon].push_back({at(idx[k]), at(idx[k + 1]), at(idx[k + 2])});
        }
      }
    }
  }
  return triangles_[icon];
}

void Simulation::collideMoving() {
  const double box = options_.entityBoxM;
  if (options_.bruteForce) {
    for (std::size_t i = 0; i < records_.size(); ++i) {
      for (std::size_t j = i + 1; j < records_.size(); ++j) {
        const Entity& a = records_[i].entity;
        const Entity& b = records_[j].entity;
        if (!a.alive || !b.alive || isMunition(a) || isMunition(b)) continue;
        if (std::abs(a.position.x() - b.position.x()) >= box || std::abs(a.position.z() - b.position.z()) >= box) {
          continue;
        }
        collidePair(records_[i], records_[j]);
      }
    }
    return;
  }
  // Figure 60 through a grid of box-sized cells: every pair within the box
  // lies in neighbouring cells.
  for (const auto& [key, ia] : cells_) {
    const auto cx = std::int64_t(key >> 32), cz = std::int64_t(key & 0xffffffffu);
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const std::uint64_t k = (std::uint64_t(cx + dx) << 32) | std::uint64_t(cz + dz);
        auto it = std::lower_bound(cells_.begin(), cells_.end(), std::make_pair(k, ia + 1));
        for (; it != cells_.end() && it->first == k; ++it) {
          Record& ra = records_[ia];
          Record& rb = records_[it->second];
          const Entity& a = ra.entity;
          const Entity& b = rb.entity;
          if (!a.alive || !b.alive) continue;
          if (std::abs(a.position.x() - b.position.x()) >= box ||
              std::abs(a.position.z() - b.position.z()) >= box) {
            continue;
          }
          collidePair(ra, rb);
        }
      }
    }
  }
}

void Simulation::collidePair(Record& ra, Record& rb) {
  Entity& a = ra.entity;
  Entity& b = rb.entity;
  ++counters_.pairsBoxed;
  const Eigen::Vector3d ca = a.position + a.orientation() * Eigen::Vector3d(0, a.height * 0.5, 0);
  const Eigen::Vector3d cb = b.position + b.orientation() * Eigen::Vector3d(0, b.height * 0.5, 0);
  const Eigen::Vector3d d = cb - ca;
  const double reach = a.sphereRadius + b.sphereRadius;
  if (d.squaredNorm() >= reach * reach) return;  // Figure 61
  // Already parting (a bounce last step), or both at rest: nothing new.
  const Eigen::Vector3d closing = a.velocity - b.velocity;
  if (closing.dot(d) <= 0) return;
  ++counters_.pairsSphered;
  Eigen::Vector3d contact = (ca + cb) * 0.5;
  Contact ray;
  if (options_.contactRay) {
    const auto& ta = trianglesOf(a.icon);
    const auto& tb = trianglesOf(b.icon);
    if (!ta.empty() && !tb.empty()) {
      ++counters_.raysCast;
      const Eigen::Affine3d wa = Eigen::Translation3d(ca) * a.orientation();
      const Eigen::Affine3d wb = Eigen::Translation3d(cb) * b.orientation();
      ray = contactPoint(ta, wa, tb, wb);  // Figures 62-63
      if (!ray.hit) return;
      contact = ray.worldPoint;
    }
  }
  ++counters_.collisions.entities;
  MovingState sa{{a.position.x(), a.position.z()}, {a.velocity.x(), a.velocity.z()}, a.headingDeg};
  MovingState sb{{b.position.x(), b.position.z()}, {b.velocity.x(), b.velocity.z()}, b.headingDeg};
  const MovingOutcome out = resolveMoving(sa, sb, options_.killSpeedMs, options_.bounceKeep);
  const char* kinds[] = {"front", "right", "rear", "left", "glancing"};
  std::string detail = kinds[int(out.kindA)];
  detail += out.killA ? "/kill" : out.stopA ? "/stop" : "/bounce";
  Event ev{0, EventKind::entityCollision, a.id, b.id, UINT32_MAX, contact, {}, detail};
  ev.contact = ray.hit;
  ev.bodyA = ray.bodyPointA;
  ev.bodyB = ray.bodyPointB;
  emit(std::move(ev));
  auto apply = [&](Record& r, bool killed, bool stopped, const Eigen::Vector2d& v, double heading) {
    Entity& e = r.entity;
    if (e.controller == Controller::remote) return;  // its owner answers the collision
    if (killed) {
      kill(e.id, e.id == a.id ? b.id : a.id, "collision");
      return;
    }
    e.position = r.before;
    if (stopped) {
      e.speedMs = 0;
      e.velocity.setZero();
      if (e.controller != Controller::behaviour) e.commands.speedMs = 0;
      else e.commands.headingDeg = wrapDeg(e.headingDeg + 180);
      if (e.domain == Domain::air) r.air.velocity.setZero();
      return;
    }
    e.headingDeg = e.commands.headingDeg = heading;
    e.speedMs = v.norm();
    if (e.controller == Controller::behaviour) e.commands.speedMs = e.speedMs;
    e.velocity = {v.x(), 0, v.y()};
    if (e.domain == Domain::air) {
      r.air.velocity.x() = v.x();
      r.air.velocity.z() = v.y();
    }
  };
  apply(ra, out.killA, out.stopA, out.newVelocityA, out.newHeadingA);
  apply(rb, out.killB, out.stopB, out.newVelocityB, out.newHeadingB);
}

void Simulation::sense(Entity& e, const Entity& m, const Eigen::Vector3d& at) {
  const BehaviourOptions& o = options_.behaviour;
  if (!e.behaviours.fight || e.lastSensed == m.id || !inBox(e, at, o.nearMissBoxM)) return;
  if (e.controller == Controller::remote) return;  // its owner's behaviours react
  e.lastSensed = m.id;
  const Reaction r = fightOrFlight(e, m.velocity, o);
  // Fire back at an enemy launcher, when reloaded (a volley of replies to
  // replies would never end).
  const Entity* launcher = find(m.launcher);  // removed or unknown: nobody to fire back at
  const bool enemy = launcher && launcher->force != e.force;
  if (r.fire && enemy && timeS() >= e.nextShotS) {
    e.nextShotS = timeS() + o.engageReloadS;
    pendingFire_.push_back({e.id, r.fireAzimuthDeg, 2.0, 0, m.launcher});
  }
}

template <typename Visit>
void Simulation::forEntitiesNear(const Eigen::Vector3d& p, Visit&& visit) {
  // The 3 x 3 cells of entityBoxM around p: every entity within a box of
  // it (bucketEntities filled the cells at the start of the step).
  const auto key = cellKey(p.x(), p.z(), options_.entityBoxM);
  const auto cx = std::int64_t(key >> 32), cz = std::int64_t(key & 0xffffffffu);
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dz = -1; dz <= 1; ++dz) {
      const std::uint64_t k = (std::uint64_t(cx + dx) << 32) | std::uint64_t(cz + dz);
      for (auto it = std::lower_bound(cells_.begin(), cells_.end(), std::make_pair(k, 0u));
           it != cells_.end() && it->first == k; ++it) {
        visit(records_[it->second].entity);
      }
    }
  }
}

void Simulation::senseRemoteMunition(const Entity& m) {
  // A round another simulation flies: its owner decides what it hits (a
  // Detonation PDU), but our entities see it go by (Figure 70's near miss).
  forEntitiesNear(m.position, [&](Entity& e) {
    if (e.alive && e.id != m.launcher) sense(e, m, m.position);
  });
}

void Simulation::flyMunition(Entity& m) {
  const MunitionType& type = munitionTypes_[m.munitionType];
  std::optional<Eigen::Vector3d> target;
  if (const Entity* t = find(m.target); t && t->alive) {  // a target removed or dead: straight on
    target = t->position + Eigen::Vector3d(0, t->height * 0.5, 0);
  }
  const Eigen::Vector3d a = m.position;
  stepMunition(m, type, target, options_.stepS);
  const Eigen::Vector3d b = m.position;
  double best = 2;
  std::uint32_t hitEntity = UINT32_MAX, hitObject = UINT32_MAX;
  std::string detail = "air";
  if (auto p = terrainImpact(*world_, a, b)) {
    const double len = (b - a).norm();
    best = len > 0 ? (*p - a).norm() / len : 0;
    detail = "terrain";
  }
  if (!world_->onGrid(b.x(), b.z())) {
    kill(m.id, UINT32_MAX, "left the database");
    return;
  }
  // Figure 59: the volume the munition swept this step, against objects...
  if (options_.collisions) {
    scratch_.clear();
    const Eigen::Vector3d mid = (a + b) * 0.5;
    const double reach = (b - a).norm() * 0.5 + type.radius;
    const double bottom = std::min(a.y(), b.y()) - type.radius;
    if (options_.bruteForce) world_->objectsNearBruteForce(mid.x(), mid.z(), reach, bottom, scratch_);
    else world_->objectsNear(mid.x(), mid.z(), reach, bottom, scratch_, &counters_.search);
    for (std::uint32_t o : scratch_) {
      const StaticObject& ob = world_->objects()[o];
      if (auto t = sweptHitsCylinder(a, b, type.radius, ob.x, ob.z, ob.radius, ob.baseY, ob.height); t && *t < best) {
        best = *t;
        hitObject = o;
        hitEntity = UINT32_MAX;
        detail = "object";
      }
    }
  }
  // ...and entities, through the same 100 m cells as the moving pairs.
  forEntitiesNear(b, [&](Entity& e) {
    if (!e.alive || e.id == m.launcher) return;
    const Eigen::Vector3d centre = e.position + Eigen::Vector3d(0, e.height * 0.5, 0);
    if (auto t = sweptHitsSphere(a, b, e.sphereRadius + type.radius, centre); t && *t < best) {
      best = *t;
      hitEntity = e.id;
      hitObject = UINT32_MAX;
      detail = "entity";
    }
    // Figure 70: the kill box kills; the near-miss box is sensed.
    if (inBox(e, b, options_.behaviour.killBoxM) && hitEntity == UINT32_MAX) {
      hitEntity = e.id;
      best = std::min(best, 1.0);
      detail = "kill box";
    } else {
      sense(e, m, b);
    }
  });
  if (best <= 1) {
    detonate(m, a + (b - a) * best, hitEntity, hitObject, detail);
  } else if (m.fuseS <= 0) {
    detonate(m, b, UINT32_MAX, UINT32_MAX, "air");
  }
}

void Simulation::detonate(Entity& m, const Eigen::Vector3d& at, std::uint32_t hitEntity, std::uint32_t hitObject,
                          const std::string& detail) {
  m.position = at;
  kill(m.id, UINT32_MAX, detail);
  Event ev{0, EventKind::detonation, m.id, hitEntity, hitObject, at, munitionTypes_[m.munitionType].name, detail};
  emit(ev);
  if (hitEntity != UINT32_MAX) {
    ++counters_.collisions.munitionEntities;
    kill(hitEntity, m.launcher, "munition");
  }
  if (hitObject != UINT32_MAX) {
    ++counters_.collisions.munitionObjects;
    const StaticObject& ob = world_->objects()[hitObject];
    const StaticOutcome out = lookup(options_.table, "missile", objectKindName(ob.kind), m.speedMs);
    applyObjectResult(hitObject, out.object);
  }
  if (detail == "terrain") {
    ++counters_.collisions.terrain;
    leaveCrater(m, at);
  }
}

void Simulation::leaveCrater(const Entity& m, const Eigen::Vector3d& at) {
  const CraterSize size = munitionTypes_[m.munitionType].crater;
  if (!options_.craters || size == CraterSize::none) return;
  const edits::CraterSize c = size == CraterSize::small    ? edits::kCraterSmall
                              : size == CraterSize::medium ? edits::kCraterMedium
                                                           : edits::kCraterLarge;
  edit::Edit e;
  e.kind = edit::Kind::crater;
  e.id = newEditId();
  e.time = timeS();
  e.origin = options_.editOrigin;
  e.points = {{at.x(), at.z()}};
  e.radius = c.radius;
  e.depth = c.depth;
  e.munition = std::uint16_t(m.munitionType + 1);
  pendingEdits_.push_back(e);
  emit(Event{0, EventKind::terrainEdit, m.id, UINT32_MAX, UINT32_MAX, at, munitionTypes_[m.munitionType].name,
             std::string("crater ") + craterSizeName(size)});
}

std::uint32_t Simulation::objectsInCrater(const edit::Edit& crater) {
  if (crater.kind != edit::Kind::crater || crater.points.empty()) return 0;
  const double x = crater.points[0][0], z = crater.points[0][1];
  scratch_.clear();
  world_->objectsNear(x, z, crater.radius, -std::numeric_limits<double>::infinity(), scratch_, nullptr);
  std::uint32_t changed = 0;
  for (const std::uint32_t o : scratch_) {
    const StaticObject& ob = world_->objects()[o];
    if (!ob.current || ob.kind != ObjectKind::tree || ob.state != ObjectState::standing) continue;
    if (std::hypot(ob.x - x, ob.z - z) > crater.radius) continue;
    world_->setObjectState(o, ObjectState::knockedOver);
    emit(Event{0, EventKind::objectCollision, UINT32_MAX, UINT32_MAX, o, Eigen::Vector3d(ob.x, ob.baseY, ob.z),
               "", "crater/knocked-over"});
    ++changed;
  }
  return changed;
}

}  // namespace sandtable::sim
