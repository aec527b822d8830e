#pragma once
// An entity of the simulation (seed chapter VII): what it is, where it is,
// how it moves and who controls it.
//
// World frame (the terrain's, sandtable/world/terrain.h): x east and z south
// of the grid's north-west corner, y up, metres. Body frame (the icons'):
// forward -Z, up +Y, right +X, so heading h (clockwise from north) turns
// forward to (sin h, 0, -cos h). Speeds are m/s, angles in the structs are
// degrees unless a name says otherwise.
//
// Thread safety: plain values and pure functions.
#include <cstdint>
#include <string>

#include <Eigen/Geometry>

#include "sandtable/sim/units.h"

namespace sandtable::sim {

enum class Domain : std::uint8_t { land, sea, air, munition };

/// How the entity moves: the control orders of seed Table 5 (`simple`:
/// first-order speed and turn rate, zero-order heading), or a dynamics
/// model (VII.B).
enum class Mobility : std::uint8_t { simple, tracked, wheeled, ship, aircraft, ballistic, guided };

/// Who decides what it does (VIII): nothing, the reactive behaviours of the
/// computer-generated forces, a script, the user, or another simulation on
/// the network (`remote`, seed VIII.C's network entity: the DIS gateway
/// sets its state before every step; this simulation never moves, steers,
/// bounces or kills it, since its owner does that and says so in its PDUs,
/// but local entities see it, collide with it and shoot at it).
enum class Controller : std::uint8_t { none, behaviour, script, driven, remote };

/// The four reactive behaviours of seed VIII.A, each on or off.
struct Behaviours {
  bool zigzag = false;
  bool environment = false;  ///< ships turn back at land, land entities at water
  bool edge = false;         ///< reverse in the buffer zone at the edge of the world
  bool fight = false;        ///< fight (armed) or flight (unarmed)
  /// Beyond the seed, whose noise entities only fire back: an armed entity
  /// fires at the nearest enemy in range and in sight (BehaviourOptions).
  bool engage = false;
  bool any() const { return zigzag || environment || edge || fight || engage; }
};

/// The controls of a land vehicle's dynamics, fractions -1..1 of the
/// vehicle's force limit (VII.B.2.b): a tracked vehicle's two track forces,
/// a wheeled vehicle's throttle and steering (fraction of its steering
/// limit, positive to the right).
struct LandControls {
  double leftTrack = 0, rightTrack = 0;
  double throttle = 0, steer = 0;
};

/// Table 5's first-order commands for `simple` and `ship` mobility (and
/// what the behaviours and the autopilot steer for every mobility).
struct Commands {
  double speedMs = 0;        ///< wanted speed along the heading
  double headingDeg = 0;     ///< wanted heading; turned towards at the turn rate
  double altitudeM = 0;      ///< air: wanted altitude above the datum
  /// Table 5's order for `simple` mobility: 1 (speed and turn rate: the
  /// fields above) or 2 (acceleration and angular acceleration: the two
  /// below, integrated; speed and turn rate stay within the vehicle's
  /// limits). Order 0 (position and orientation) is a script line.
  int order = 1;
  double accelerationMs2 = 0;
  double turnAccelerationDegS2 = 0;  ///< clockwise positive
};

/// A vehicle's physical limits; the defaults are a 40 t tank.
struct VehicleParams {
  double massKg = 40000;
  double maxForceN = 400000;   ///< all tracks or wheels together, at low speed
  double powerW = 1.1e6;       ///< above powerW / maxForceN m/s the force falls as power / speed
  double maxSpeedMs = 20;      ///< the behaviours' and the autopilot's cruise limit
  double turnRateDegS = 30;    ///< simple/ship mobility, and the tracked pivot limit
  double steerLimitDeg = 35;   ///< wheeled: the front axle's limit (alpha)
  double fuelBurnPerS = 0;     ///< fraction of a full tank per second at full force; 0: never runs dry
};

struct Entity {
  std::uint32_t id = 0;        ///< given by Simulation::add / fire: stable, never reused in a run
  std::string name;
  std::uint16_t icon = 0;      ///< index into icons.pack
  std::string iconName;
  std::uint8_t force = 0;      ///< side: 0 neutral, 1 blue, 2 red, 3 green, others free
  Domain domain = Domain::land;
  Mobility mobility = Mobility::simple;
  Controller controller = Controller::none;
  Behaviours behaviours;

  // Kinematics (seed Figure 44's entity state).
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();  ///< body rates, rad/s
  /// The orientation, stored once: heading (clockwise from north), pitch
  /// (nose up) and roll (right side down), as the seed's entity state and
  /// DIS's Euler angles hold it. orientation() derives the quaternion; an
  /// aircraft's flight model keeps its own quaternion (AirState) and mirrors
  /// these angles from it after every step.
  double headingDeg = 0, pitchDeg = 0, rollDeg = 0;
  double speedMs = 0;        ///< land and sea: signed speed along the heading; air: airspeed
  double heightAgl = 0;      ///< above the drawn ground

  /// Body-to-world rotation of the stored angles (orientationOf).
  Eigen::Quaterniond orientation() const;

  bool alive = true;
  bool armed = false, resupply = false;  ///< from the icon definition
  double fuel = 1;           ///< fraction of a full tank

  // Size, from the icon: bounding cylinder and box (projected points).
  double radius = 1, height = 2;
  double halfLength = 2, halfWidth = 1;
  double sphereRadius = 2;   ///< max distance along any axis from the origin (Figure 61)

  VehicleParams vehicle;
  LandControls controls;
  Commands commands;
  std::uint32_t aircraftType = 0;  ///< index into Simulation's aircraft types (air + aircraft)
  double throttle = 0;             ///< aircraft engine setting after spool-up
  bool autopilot = false;          ///< hold commands (VII.D)

  // Behaviour state.
  double nextTurnS = 0;            ///< zig-zag: when the current leg ends
  std::uint32_t lastSensed = UINT32_MAX;  ///< fight or flight: the last munition reacted to
  double nextShotS = 0;                   ///< engage: reloaded at this time
  double cruiseMs = 0;                    ///< object avoidance: the speed to resume, 0 when not slowed
  std::uint32_t pressing = UINT32_MAX;    ///< the object it was stopped by and still touches (one event)
  double gunAzimuthDeg = 0, gunElevationDeg = 0;

  // Munitions.
  std::uint32_t launcher = UINT32_MAX;  ///< who fired it
  std::uint32_t target = UINT32_MAX;    ///< guided: the entity it homes on
  double fuseS = 0;                     ///< detonates in the air after this long
  std::uint16_t munitionType = 0;       ///< index into the munition table
};

/// The unit horizontal vector of a heading: (sin h, 0, -cos h).
Eigen::Vector3d headingVector(double headingDeg);
/// Heading of a horizontal direction (x, z), degrees in [0, 360).
double headingOf(double dx, double dz);
/// Wraps to [0, 360).
double wrapDeg(double deg);
/// Signed smallest turn from `from` to `to`, degrees in (-180, 180].
double turnBetween(double fromDeg, double toDeg);
/// Body-to-world rotation of heading (clockwise from north), pitch (nose up)
/// and roll (right side down), applied as yaw, then pitch, then roll.
Eigen::Quaterniond orientationOf(double headingDeg, double pitchDeg, double rollDeg);

const char* domainName(Domain d);
const char* mobilityName(Mobility m);

}  // namespace sandtable::sim
