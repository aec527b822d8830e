#pragma once
// The simulation as the stealth viewer shows and drives it (`sandtable fly
// DB --scenario FILE`, docs/VIEWER.md "Entities (fly --scenario)"): a
// sim::Simulation stepped on the application's fixed-step clock, turned
// each frame into what the renderer draws (scene/dynamic.h: entities with
// icons, full orientation, turret angle and gun elevation, munition trails, detonation
// flashes, the static objects the simulation changed), the 2-D map's marks,
// the panel's lines and stats.json's `sim` objects; and the three ways of
// looking: the stealth eye, an eye tethered behind and above an entity,
// and driving one (the eye's first-order key scheme feeding the entity's
// commands, its autopilot turning them into track forces).
//
// Time: the simulation only moves in fixed steps (SimOptions::stepS, 60 Hz),
// all through one sim::StepHost (the runner `sandtable sim` uses).
// Headless, frame k is at k / 30 s and the session is stepped to
// StepHost::stepsFor(t) steps, so a flight is deterministic frame by frame
// and gives the simulation `sandtable sim` gives for as long. The entities
// follow the finest surface, as headless runs of the simulator do; the
// renderer sets each surface entity on the level of detail it draws there
// (DynamicInstance::onSurface), so the simulation does not depend on what
// the pager had loaded.
//
// Thread safety: one thread (fly()'s main thread) owns a SimSession; it
// steps the simulation and reads it. What it hands out (DynamicScene, map
// marks, panel lines, JSON text) are copies for the render thread.
#include <array>
#include <functional>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/base/result.h"
#include "sandtable/render/map_view.h"
#include "sandtable/scene/module_scene.h"
#include "sandtable/scene/dynamic.h"
#include "sandtable/sim/simulation.h"
#include "sandtable/sim/step_host.h"
#include "sandtable/viewer/viewer_keys.h"
#include "sandtable/world/controls.h"
#include "sandtable/world/ground.h"
#include "sandtable/world/pose.h"

namespace sandtable::viewer {

enum class ViewMode : std::uint8_t {
  stealth,   ///< the free eye (keys or --path or the straight line)
  attached,  ///< tethered behind and above an entity
  driving,   ///< tethered, and the keys drive the entity
};
const char* viewModeName(ViewMode m);

/// The tethered eye: behind the entity along its (eased) heading and
/// above it, looking down at its middle.
struct TetherSettings {
  double sizeFactor = 5;        ///< distance = sizeFactor x the entity's size (its largest half extent or height)
  double minDistanceM = 18, maxDistanceM = 250;
  double heightRatio = 0.4;     ///< height above the entity / distance
  double headingLagS = 0.6;     ///< time constant of the eye's heading following the entity's
  double minAglM = 2;           ///< never closer to the ground under the eye (nor than a quarter of the distance)
  double pitchBiasDeg = 3;      ///< looks this much above the entity, so it sits below the centre
};

/// Driving: the eye's first-order scheme (controls.h) on the entity's
/// commands: Up / Down step the commanded speed (held: repeats), Left /
/// Right turn the commanded heading (a step, then a rate while held);
/// Page Up / Page Down climb an aircraft's commanded altitude.
struct DriveSettings {
  double speedStepMs = 2.5;
  double reverseFraction = 0.25;  ///< the slowest command is -this x the vehicle's top speed
  double turnStepDeg = 5;
  double turnRateDegS = 30;
  double climbStepM = 50;
  double climbRateMS = 100;
};

struct SimSessionOptions {
  std::string attach;     ///< attach the eye to this entity at the start ("": stealth)
  bool drive = false;     ///< drive from the start: `attach`, else the scenario's driven entity
  double trailS = 2.0;    ///< munition trails: seconds of positions kept and fading
  double flashS = 0.5;    ///< a detonation's flash lasts this long
  std::string scenario;   ///< the scenario file, for stats.json
  /// Simulated seconds run before the first frame (`fly --sim-start`).
  double startS = 0;
  TetherSettings tether;
  DriveSettings driving;
  /// Networked (fly --dis): an --attach name no entity has yet is not an
  /// error; the eye attaches when one appears (remote entities arrive with
  /// their first PDU).
  bool attachWhenSeen = false;
  /// Finds the entity an --attach text names when no entity has that name
  /// (fly --dis: a DIS id "site:application:entity"); may be empty.
  std::function<std::optional<std::uint32_t>(const std::string&)> findEntity;
  /// Lines added to the panel (fly --dis: the network's figures); may be empty.
  std::function<std::vector<std::string>()> extraPanel;
  /// Marks added to the map under the entities (the terrain edits); may be empty.
  std::function<std::vector<render::MapMark>()> extraMarks;
  /// Names drawn over the entities within labelRangeM of the eye (fly
  /// --dis: the DIS markings), nearest first (the viewer draws the first
  /// kMaxLabelsDrawn in the frame that do not overlap).
  bool labels = false;
  double labelRangeM = 4000;
};

/// A name to draw over an entity: where (world metres, above its top) and
/// what, in its force's colour.
struct EntityLabel {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  std::string text;
  std::uint8_t force = 0;
  bool alive = true;
};

class SimSession {
 public:
  /// Fails (Problem::file "--attach" / "--drive") when the entity to attach
  /// to does not exist, or when driving has nobody to drive.
  static Result<std::unique_ptr<SimSession>> create(std::unique_ptr<sim::Simulation> simulation,
                                                    SimSessionOptions options);

  sim::Simulation& simulation() { return *sim_; }
  const sim::Simulation& simulation() const { return *sim_; }
  double stepS() const { return sim_->options().stepS; }

  // ---- time (main thread)
  /// Steps the simulation until it has taken `steps` steps; a simulation
  /// already past it stays.
  void advanceToStep(std::uint64_t steps);
  /// Headless: steps to flight time `t` seconds after the start
  /// (SimSessionOptions::startS): round(t / stepS) steps after it.
  void advanceToFlightTime(double t);
  /// One fixed step: the driving controls advance and feed the driven
  /// entity's commands (a before-step hook), then the simulation steps.
  void step();
  /// The runner every step goes through: add hooks here (the network).
  sim::StepHost& stepHost() { return host_; }
  /// The levels the last frame drew: the entities stand on them from the
  /// next step on (seed: they follow the terrain that is drawn there).
  /// Where nothing was drawn, level 0.
  void setDrawn(std::shared_ptr<const scene::DrawnLevels> drawn);
  /// After a frame's steps: every live munition's position joins its
  /// trail, and new events are read (detonations flash; objects that a
  /// collision or a munition changed get their new look).
  void sample();

  // ---- what a frame shows (copies)
  /// Entities (dead munitions left out; a munition without an icon only
  /// leaves its trail), trails, flashes and the changed static objects.
  void fill(scene::DynamicScene& out) const;
  /// Every entity but the munitions, the attached one selected.
  std::vector<render::MapMark> mapMarks() const;
  /// With SimSessionOptions::labels: the named entities within range of
  /// `eye`, nearest first; else none.
  std::vector<EntityLabel> labels(const Eigen::Vector3d& eye) const;
  /// Entity count (alive / total), the view mode, and the attached (else
  /// the scenario's driven) entity: name, icon, force, alive or dead,
  /// speed, heading, fuel; driving: the commands.
  std::vector<std::string> panelLines() const;
  /// The frame's `sim` object for stats.json (JSON text).
  std::string frameJson() const;
  /// stats.json's top-level `sim`: sim::summaryJson plus seed, scenario
  /// and the view (JSON text).
  std::string summaryJson() const;
  /// One line for the command's summary.
  std::string summaryLine() const;

  // ---- the view (main thread)
  ViewMode mode() const { return mode_; }
  std::optional<std::uint32_t> attached() const { return attached_; }
  /// The entity the panel reports: the attached one, else the scenario's driven one.
  std::optional<std::uint32_t> focus() const;
  /// Attaches the eye to entity `id` (stops driving another one).
  void attach(std::uint32_t id);
  /// Back to the stealth eye.
  void detach();
  /// Drives entity `id` (attaching to it): its controller becomes `driven`,
  /// its autopilot holds the commands the keys set.
  void drive(std::uint32_t id);
  /// Stops driving; the entity keeps its last commands.
  void stopDriving();
  /// sim::allStop on the driven (else attached, else scenario's driven) entity.
  void allStop();
  /// Tab, Shift+Tab, E, D, Space (viewer_keys.h).
  void handle(ViewerKey k);
  /// Whether `k` steers the tether or the driven entity in this mode
  /// (arrows, Page Up / Down), instead of the stealth eye.
  bool steers(world::Key k) const;
  /// An arrow or page key in attached or driving mode: driving, the
  /// commands (DriveSettings); attached, Up / Down bring the eye nearer /
  /// farther, Left / Right orbit it by 15 degrees, Page Up / Down raise or
  /// lower it.
  void handle(const world::KeyEvent& e);
  /// The tethered eye at the attached entity now: the eye's heading eases
  /// towards the entity's (TetherSettings::headingLagS of simulated time
  /// since the last call), `ground` keeps it above the drawn ground.
  world::Pose tetherPose(world::GroundClamp& ground);
  /// The commanded speed (m/s) and heading (degrees) while driving.
  std::optional<std::pair<double, double>> driveCommands() const;

 private:
  SimSession(std::unique_ptr<sim::Simulation> simulation, SimSessionOptions options);
  void applyDrive();
  /// attachWhenSeen: attaches when the awaited entity has appeared.
  void attachAwaited();
  /// The entity an --attach text names (its name, else findEntity).
  std::optional<std::uint32_t> named(const std::string& text) const;
  void seedDrive(const sim::Entity& e);
  bool isTarget(const sim::Entity& e) const { return e.domain != sim::Domain::munition; }
  float turretOf(const sim::Entity& e) const;
  static float gunOf(const sim::Entity& e);
  /// An entity's name (a removed one's too), or null.
  nlohmann::json nameJson(std::optional<std::uint32_t> id) const;

  std::unique_ptr<sim::Simulation> sim_;
  sim::StepHost host_;  ///< steps *sim_
  SimSessionOptions options_;
  ViewMode mode_ = ViewMode::stealth;
  std::optional<std::uint32_t> attached_;
  std::uint64_t startSteps_ = 0;
  bool attachedOnce_ = false;  ///< attachWhenSeen: the awaited entity was attached (a later detach stays)
  std::optional<world::Controller> driveKeys_;  ///< driving: its speed and heading are the commands
  // The tether.
  std::optional<double> tetherHeading_, tetherTime_;
  double zoom_ = 1, orbitDeg_ = 0, heightRatio_ = 0.4;
  // Read from the simulation's events.
  std::size_t eventsSeen_ = 0;
  struct Passed {
    Eigen::Vector3d position;
    double timeS = 0;  ///< simulated time it was there
  };
  struct TrailPoints {
    std::vector<Passed> points;
    std::array<std::uint8_t, 3> rgb{236, 236, 228};
  };
  std::map<std::uint32_t, TrailPoints> trails_;  ///< by munition id
  struct Detonation {
    scene::Flash flash;  ///< its ageS is set when a frame is filled
    double timeS = 0;
  };
  std::vector<Detonation> flashes_;
  std::set<std::uint32_t> changedObjects_;       ///< SimWorld::objects indices
  std::vector<bool> aimed_;                      ///< per entity: its gun azimuth was ever set
};

}  // namespace sandtable::viewer
