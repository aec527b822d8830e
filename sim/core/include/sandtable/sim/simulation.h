#pragma once
// The simulation (seed chapters VII and VIII; Figure 44's entity process):
// entities advanced on a fixed-step clock, their collisions with static
// objects and with each other, munitions and their detonations, the
// reactive behaviours, scripts, and the events all this produces.
//
// One step, in this order, each entity in id order (so a run is
// deterministic, bit for bit, for a given seed and input):
//  1. scripts apply their due lines (Figure 73); the recorder samples the
//     driven entity;
//  2. behaviours steer the computer-generated forces (zig-zag, environment,
//     edge, fight or flight) and the autopilot turns commands into controls;
//  3. every live entity moves (motion.h, aircraft.h, munition.h);
//  4. munitions: terrain impact (Figure 27), swept volumes against objects
//     and entities (Figure 59), kill and near-miss boxes (Figure 70);
//  5. moving against static objects (Figures 56-58, Table 6);
//  6. moving against moving (Figures 60-66).
//
// Thread safety: one thread drives a Simulation; readers of its entities
// must copy them between steps (the viewer does, under its own lock).
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "sandtable/formats/edit.h"
#include "sandtable/sim/aircraft.h"
#include "sandtable/sim/behaviour.h"
#include "sandtable/sim/collision_response.h"
#include "sandtable/sim/entity.h"
#include "sandtable/sim/munition.h"
#include "sandtable/sim/script.h"
#include "sandtable/sim/sim_world.h"

namespace sandtable::sim {

enum class EventKind : std::uint8_t {
  fire,             ///< a munition was launched
  detonation,       ///< a munition went off: the DIS and dynamic-terrain issues consume these
  kill,             ///< an entity died (by a munition, a collision or a crash)
  objectCollision,  ///< an entity hit a static object (Table 6)
  entityCollision,  ///< two entities collided (Figure 64)
  crash,            ///< an aircraft met the ground
  aground,          ///< a ship's step towards land was refused
  removed,          ///< Simulation::remove took the entity out of the run
  terrainEdit,      ///< the simulation made a terrain edit (a crater where a round hit the ground)
};
const char* eventKindName(EventKind k);

struct Event {
  double timeS = 0;
  EventKind kind = EventKind::fire;
  std::uint32_t entity = UINT32_MAX;  ///< the actor (the munition for fire and detonation)
  std::uint32_t other = UINT32_MAX;   ///< the other entity, the target or the launcher
  std::uint32_t object = UINT32_MAX;  ///< a static object (SimWorld::objects index)
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  std::string munition;               ///< detonation and fire: the munition type
  std::string detail;                 ///< e.g. "stop/none", "front", "terrain"
  /// Entity collisions found by the contact ray (Figures 62-63): the
  /// contact point in each entity's body frame (origin at mid-height).
  bool contact = false;
  Eigen::Vector3d bodyA = Eigen::Vector3d::Zero(), bodyB = Eigen::Vector3d::Zero();
};

/// What collided with what, counted by kind.
struct CollisionCounts {
  std::uint64_t objects = 0, entities = 0, munitionObjects = 0, munitionEntities = 0, terrain = 0;
};

struct SimOptions {
  double stepS = 1.0 / 60.0;  ///< the fixed step: 60 Hz
  std::uint64_t seed = 1;
  bool collisions = true;
  /// Test every object and every entity pair instead of the grid and the
  /// 100 m box: the benchmark's baseline.
  bool bruteForce = false;
  /// Figure 60: the first-level box, metres in X and Z.
  double entityBoxM = 100;
  /// Figure 64's constant: above this closing speed a square impact kills.
  double killSpeedMs = 5;
  double bounceKeep = kDefaultBounceKeep;
  /// Cast the contact ray (Figures 62-63) against the icons' triangles;
  /// off: the bounding spheres decide.
  bool contactRay = true;
  BehaviourOptions behaviour;
  CollisionTable table = defaultCollisionTable();
  /// Land entities stay at most this far from the drawn surface; checked
  /// by the tests.
  double groundToleranceM = 0.01;
  /// Munitions that hit the ground leave their crater (MunitionType::crater)
  /// as a terrain edit for the step host to apply (takeTerrainEdits).
  bool craters = true;
  /// The origin of the edits this simulation makes (edit.h): 0 alone, the
  /// DIS site << 16 | application on a network, so every process orders
  /// the same edits alike.
  edit::Origin editOrigin = 0;
};

/// Counters of the last steps, for the summary and the benchmark.
struct SimCounters {
  std::uint64_t steps = 0;
  std::uint64_t entitySteps = 0;
  std::uint64_t fired = 0, detonations = 0, kills = 0;
  CollisionCounts collisions;
  std::uint64_t pairsBoxed = 0, pairsSphered = 0, raysCast = 0;
  SearchStats search;  ///< what the grid searches for objects tested
};

/// What the simulation keeps of one entity: the entity and the state only
/// the stepping needs. One record per entity, so nothing is kept in step by
/// hand.
struct EntityRecord {
  Entity entity;
  AirState air;              ///< aircraft: the flight model's state
  AirControls airControls;   ///< aircraft: the autopilot's controls
  ScriptLine lastLine;       ///< scripted: the line it is dead reckoned from
  bool scripted = false;     ///< a script moves it
  bool lineApplied = false;  ///< its script has given it a line
  Eigen::Vector3d before = Eigen::Vector3d::Zero();  ///< position at the start of the step
};

/// The entities of a simulation as a range of Entity (no indexing: a
/// position in the range is not an id).
template <class E>
class EntityRange {
  using Records = std::conditional_t<std::is_const_v<E>, const std::vector<EntityRecord>, std::vector<EntityRecord>>;
  using Base = decltype(std::declval<Records&>().begin());

 public:
  class iterator {
   public:
    using value_type = std::remove_const_t<E>;
    using difference_type = std::ptrdiff_t;
    using reference = E&;
    using pointer = E*;
    using iterator_category = std::forward_iterator_tag;
    iterator() = default;
    explicit iterator(Base it) : it_(it) {}
    E& operator*() const { return it_->entity; }
    E* operator->() const { return &it_->entity; }
    iterator& operator++() {
      ++it_;
      return *this;
    }
    iterator operator++(int) {
      iterator old = *this;
      ++it_;
      return old;
    }
    bool operator==(const iterator& o) const { return it_ == o.it_; }

   private:
    Base it_{};
  };
  explicit EntityRange(Records& records) : records_(&records) {}
  iterator begin() const { return iterator(records_->begin()); }
  iterator end() const { return iterator(records_->end()); }
  std::size_t size() const { return records_->size(); }
  bool empty() const { return records_->empty(); }

 private:
  Records* records_;
};

class Simulation {
 public:
  Simulation(std::shared_ptr<SimWorld> world, SimOptions options = {});

  /// Adds an entity and gives it the next id (ids count up from 0 and are
  /// never reused in a run, removal or not). Land entities are put on the
  /// ground and oriented; entities with the edge behaviour that start in
  /// the buffer zone are moved out of it. Fails when it stands off the grid
  /// or a ship is not on water (no id is used up then).
  Result<std::uint32_t> add(Entity e);
  /// Removes entity `id` between steps (from a step hook or outside a run;
  /// never from inside step()): a `removed` event, and everything that
  /// named it lets go: munitions homing on it fly straight on, its script
  /// lines are consumed and ignored, it is no longer driven or recorded,
  /// pending launches from it are dropped. Other entities keep their ids.
  /// False when no entity has that id (never added, or removed before).
  bool remove(std::uint32_t id);

  /// Kills entity `id` between steps as a munition or collision in the
  /// step would (a kill event naming `by`): how a Detonation PDU from the
  /// network that names a local entity takes effect. Remote entities are
  /// left alone (their owner kills them). False when `id` is not a live
  /// entity of this simulation.
  bool destroy(std::uint32_t id, std::uint32_t by, const std::string& detail);

  /// An event that happened in another simulation (a remote detonation,
  /// from the network): stamped with this simulation's time, counted and
  /// listed with the step's own, so viewers and reports show it alike.
  void addEvent(Event ev) { emit(std::move(ev)); }

  /// The terrain edits the steps since the last call made, in step order
  /// (craters where munitions hit the ground). The step host applies them
  /// (terrain_edits.h) and calls objectsInCrater for each crater.
  std::vector<edit::Edit> takeTerrainEdits() { return std::exchange(pendingEdits_, {}); }
  /// The id the next edit this simulation makes gets (ids of one origin
  /// must not repeat: a journal replayed before the run holds earlier ones).
  void setNextEditId(std::uint64_t id) { nextEditId_ = id; }
  /// Takes the next id for an edit of this simulation's origin.
  std::uint64_t newEditId() { return nextEditId_++; }
  /// What a crater does to the static objects inside it (docs/DYNAMIC.md):
  /// a standing tree whose trunk is within the crater's radius falls
  /// (knocked over). For every crater applied, local or received. Returns
  /// the objects changed.
  std::uint32_t objectsInCrater(const edit::Edit& crater);

  /// An aircraft type for air entities (Entity::aircraftType indexes it).
  std::uint32_t addAircraftType(AircraftParams params);
  /// The aircraft state of an air entity (position, velocity and
  /// orientation are mirrored into the Entity after each step); null when
  /// `id` is not in the simulation.
  AirState* airState(std::uint32_t id);
  AirControls* airControls(std::uint32_t id);

  /// Scripts (Figure 73): each line for script entity `entity` moves
  /// simulation entity `id`; lines of entities not mapped are ignored.
  void addScript(std::vector<ScriptLine> lines, std::vector<std::pair<std::uint32_t, std::uint32_t>> entityToId);
  /// Records entity `id` (the driven one) into a script with entity number
  /// `scriptEntity` and type `scriptType`.
  void record(std::uint32_t id, std::uint32_t scriptEntity, std::uint32_t scriptType, RecorderOptions o = {});
  /// The recorded lines (after finishRecording, complete).
  const ScriptRecorder* recorder() const { return recorder_ ? &*recorder_ : nullptr; }
  /// The lines of every script added, as given (play and record at once
  /// writes them merged with the recorder's: compounded scripts).
  std::vector<std::vector<ScriptLine>> playedScripts() const;
  void finishRecording();

  /// Launches a munition of `type` from entity `shooter` along azimuth and
  /// elevation (degrees); guided munitions home on `target` when given.
  /// The munition's id, or UINT32_MAX when `shooter` is not in the simulation.
  std::uint32_t fire(std::uint32_t shooter, double azimuthDeg, double elevationDeg, std::uint16_t type,
                     std::uint32_t target = UINT32_MAX);

  /// One fixed step.
  void step();
  /// Steps until `seconds` of simulated time have passed (StepHost::runFor
  /// without hooks: tests and warm-ups).
  void runFor(double seconds);

  double timeS() const { return double(steps_) * options_.stepS; }
  std::uint64_t steps() const { return steps_; }
  const SimOptions& options() const { return options_; }
  SimOptions& options() { return options_; }
  /// The entities in the simulation, in id order (removed ones are gone,
  /// so a position in this range is not an id: use find()).
  EntityRange<Entity> entities() { return EntityRange<Entity>(records_); }
  EntityRange<const Entity> entities() const { return EntityRange<const Entity>(records_); }
  /// Entity `id`, or null when it was never added or has been removed. The
  /// pointer is good until the next add, fire, remove or step.
  Entity* find(std::uint32_t id);
  const Entity* find(std::uint32_t id) const;
  /// Entity `id`, which must be in the simulation (find() tells).
  Entity& entity(std::uint32_t id) { return *find(id); }
  const Entity& entity(std::uint32_t id) const { return *find(id); }
  /// The name of any entity the run ever had, removed ones too (the event
  /// log names them); null for an id never given.
  const std::string* nameOf(std::uint32_t id) const;
  /// The id the next entity added or fired gets.
  std::uint32_t nextId() const { return nextId_; }
  const std::vector<Event>& events() const { return events_; }
  const SimCounters& counters() const { return counters_; }
  SimWorld& world() { return *world_; }
  const SimWorld& world() const { return *world_; }
  const std::vector<MunitionType>& munitions() const { return munitionTypes_; }

  /// The entity the user drives, if any.
  std::optional<std::uint32_t> driven;

  /// Kills an entity now (an event with `detail`).
  void kill(std::uint32_t id, std::uint32_t by, const std::string& detail);

 private:
  using Record = EntityRecord;
  Record* recordOf(std::uint32_t id);
  const Record* recordOf(std::uint32_t id) const;
  /// Appends a record with the next id.
  Record& append(Entity e);
  void applyScripts();
  void behave(Record& r);
  void engage(Entity& e);
  void move(Record& r);
  void moveAir(Record& r);
  void flyMunition(Entity& m);
  void leaveCrater(const Entity& m, const Eigen::Vector3d& at);
  /// Figure 70's near miss: entity `e` with fight or flight senses munition
  /// `m` at `at` once, turns, and may fire back.
  void sense(Entity& e, const Entity& m, const Eigen::Vector3d& at);
  void senseRemoteMunition(const Entity& m);
  /// Calls visit(Entity&) for every live, non-munition entity in the cells
  /// around `p` (the moving pairs' cells, filled at the start of the step).
  template <typename Visit>
  void forEntitiesNear(const Eigen::Vector3d& p, Visit&& visit);
  void detonate(Entity& m, const Eigen::Vector3d& at, std::uint32_t hitEntity, std::uint32_t hitObject,
                const std::string& detail);
  void collideStatic(Record& r);
  /// Table 6's object result as the object's new state.
  void applyObjectResult(std::uint32_t object, ObjectResult r);
  void collideMoving();
  void collidePair(Record& a, Record& b);
  void bucketEntities();
  const std::vector<Triangle>& trianglesOf(std::uint16_t icon);
  std::string entityClass(const Entity& e) const;
  void emit(Event ev);

  std::shared_ptr<SimWorld> world_;
  SimOptions options_;
  std::vector<Record> records_;  ///< one per entity in the simulation, in id order
  /// By id: the index of its record in records_, kGone once removed. Ids
  /// only grow, so records_ stays sorted by id and iterating it is id order.
  std::vector<std::uint32_t> slots_;
  static constexpr std::uint32_t kGone = UINT32_MAX;
  std::uint32_t nextId_ = 0;
  std::map<std::uint32_t, std::string> removedNames_;  ///< for the event log
  std::vector<AircraftParams> aircraftTypes_;
  std::vector<MunitionType> munitionTypes_;
  std::vector<Event> events_;
  std::vector<edit::Edit> pendingEdits_;
  std::uint64_t nextEditId_ = 1;
  SimCounters counters_;
  std::uint64_t steps_ = 0;
  std::uint64_t draws_ = 0;  ///< random draws made (behaviours)

  struct Script {
    ScriptPlayer player;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> map;  ///< script entity -> id, sorted
  };
  std::vector<Script> scripts_;
  std::optional<ScriptRecorder> recorder_;
  std::uint32_t recordId_ = 0, recordEntity_ = 0, recordType_ = 0;

  // Moving/moving: entities by 100 m cell (Figure 60), rebuilt each step:
  // (cell, index into records_).
  std::vector<std::pair<std::uint64_t, std::uint32_t>> cells_;
  std::vector<std::vector<Triangle>> triangles_;  ///< per icon, built on first use
  std::vector<bool> trianglesBuilt_;
  std::vector<std::uint32_t> scratch_, touched_;

  /// Launches decided during the step, made after it (a launch appends an
  /// entity, which must not happen while entities are being iterated).
  struct PendingFire {
    std::uint32_t shooter = 0;
    double azimuthDeg = 0, elevationDeg = 0;
    std::uint16_t type = 0;
    std::uint32_t target = UINT32_MAX;
  };
  std::vector<PendingFire> pendingFire_;
};

}  // namespace sandtable::sim
