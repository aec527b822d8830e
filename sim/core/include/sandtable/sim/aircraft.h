#pragma once
// Air entities (seed VII.B.3): a six-degree-of-freedom flight model whose
// orientation is a unit quaternion, so a vertical climb or a loop has no
// gimbal lock; Euler angles exist only for display and the network. The
// aircraft's numbers (mass, wing, engine, lift and drag coefficients,
// control limits and power, fuel) come from a text file, `sandtable-aircraft
// 1` (docs/AIRCRAFT.md), so one model flies a trainer or a fighter. Also a
// stateless attitude/altitude/speed autopilot used by the simulator and by
// computer-generated aircraft.
//
// Frames. World: x east, y up, z south (north is -z); y is the altitude in
// metres. Body (the icon frame): forward -Z, up +Y, right +X. The
// orientation quaternion q maps body vectors to world vectors
// (v_world = q * v_body). Heading is clockwise from north, pitch nose-up
// positive, roll right-wing-down positive.
//
// Thread safety: free functions on values; AircraftParams is read-only
// during a step, so one set of parameters may be shared by any number of
// threads stepping different AirStates. One AirState from one thread at a
// time. Deterministic: the same inputs give the same bits.
#include <cstddef>
#include <string>
#include <string_view>

#include <Eigen/Geometry>

#include "sandtable/base/result.h"
#include "sandtable/sim/units.h"  // kGravity

namespace sandtable::sim {

inline constexpr const char* kAircraftHeaderLine = "sandtable-aircraft 1";
/// Largest aircraft file readAircraftFile accepts.
inline constexpr std::size_t kMaxAircraftFileBytes = 1u << 20;
/// Sea-level air density, kg/m^3, and the scale height of the exponential
/// atmosphere, m.
inline constexpr double kSeaLevelDensity = 1.225;
inline constexpr double kScaleHeight = 8500.0;
/// The simulator's fixed step, s.
inline constexpr double kDefaultAirStep = 1.0 / 60.0;

/// One aircraft type, as read from its file. Units are SI except the
/// angles marked deg. See docs/AIRCRAFT.md for each field.
struct AircraftParams {
  std::string name;              ///< the name given to parseAircraft (usually the file)
  double mass = 0;               ///< kg, empty (without fuel); flying mass = mass + fuel
  double wingArea = 0;           ///< m^2, reference area S
  double maxThrust = 0;          ///< N, full throttle at sea level (scales with density)
  double spoolTime = 0;          ///< s, engine first-order time constant (0 = instant)
  double cl0 = 0;                ///< lift coefficient at zero angle of attack
  double clAlpha = 0;            ///< lift-curve slope, per rad
  double clMax = 0;              ///< stall: |CL| never exceeds it
  double cd0 = 0;                ///< zero-lift drag coefficient
  double inducedDrag = 0;        ///< k in CD = CD0 + k CL^2
  double sideForce = 0;          ///< side-force coefficient per rad of sideslip (opposes it)
  double elevatorLimitDeg = 0;   ///< surface deflection at full stick, deg
  double aileronLimitDeg = 0;
  double rudderLimitDeg = 0;
  double elevatorPower = 0;      ///< rad/s^2 per rad of deflection at referencePressure
  double aileronPower = 0;
  double rudderPower = 0;
  double pitchDamping = 0;       ///< 1/s: rate decay
  double rollDamping = 0;
  double yawDamping = 0;
  double pitchStability = 0;     ///< rad/s^2 per rad of (alpha - alphaTrim) at referencePressure
  double yawStability = 0;       ///< rad/s^2 per rad of sideslip at referencePressure
  double alphaTrimDeg = 0;       ///< angle of attack the aircraft settles at with the stick centred, deg
  double referencePressure = 0;  ///< Pa, dynamic pressure at which the powers and stabilities hold
  double fuelCapacity = 0;       ///< kg
  double fuelBurn = 0;           ///< kg/s at full throttle (proportional to throttle)
};

/// Pilot or autopilot inputs. Values outside the ranges are clamped; a
/// non-finite value counts as 0.
struct AirControls {
  double throttle = 0;  ///< commanded engine setting 0..1
  double elevator = 0;  ///< -1..1 of the elevator limit; + = stick back, nose up
  double aileron = 0;   ///< -1..1 of the aileron limit; + = roll right (right wing down)
  double rudder = 0;    ///< -1..1 of the rudder limit; + = nose right
};

/// The state the dynamics integrate.
struct AirState {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< world metres (y = altitude)
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< world m/s (still air: also the airspeed vector)
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< body to world, unit
  /// Body rates, rad/s, in the aviation sense: x = p (roll, right wing
  /// down +), y = q (pitch, nose up +), z = r (yaw, nose right +). Not the
  /// angular-velocity vector in body axes; bodyRateVector() gives that.
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();
  double throttle = 0;  ///< actual engine setting 0..1 after spool-up
  double fuelKg = 0;
};

struct Euler {
  double headingDeg = 0;  ///< clockwise from north, [0, 360)
  double pitchDeg = 0;    ///< nose up +, [-90, 90]
  double rollDeg = 0;     ///< right wing down +, (-180, 180]; 0 at exactly +-90 pitch
};

/// Heading, then pitch about the new right axis, then roll about the new
/// forward axis: the same rotation as orientationOf (entity.h).
Eigen::Quaterniond orientationFromEuler(double headingDeg, double pitchDeg, double rollDeg);
/// The inverse of orientationFromEuler. At pitch +-90 heading and roll are
/// one degree of freedom: roll is reported 0 and heading carries it, so
/// orientationFromEuler(eulerFromOrientation(q)) is q (up to sign).
Euler eulerFromOrientation(const Eigen::Quaterniond& q);

/// Body axes in world coordinates.
Eigen::Vector3d forwardOf(const Eigen::Quaterniond& q);
Eigen::Vector3d upOf(const Eigen::Quaterniond& q);
Eigen::Vector3d rightOf(const Eigen::Quaterniond& q);
/// The angular-velocity vector in body axes (x right, y up, z back) from
/// the rates (p, q, r): (q, -r, -p).
Eigen::Vector3d bodyRateVector(const AirState& s);

/// Air density of the exponential standard atmosphere at altitude h (m).
double airDensity(double altitudeM);

/// Derived air data of a state, for displays, autopilots and tests.
struct AirData {
  double density = 0;          ///< kg/m^3
  double speed = 0;            ///< m/s
  double dynamicPressure = 0;  ///< Pa, rho V^2 / 2
  double alphaRad = 0;         ///< angle of attack, + = air from below the nose
  double betaRad = 0;          ///< sideslip, + = moving to the right of the nose
  double massKg = 0;           ///< empty mass + fuel
};
AirData airData(const AircraftParams& p, const AirState& s);

/// The parameters from `sandtable-aircraft 1` text. `name` is the file
/// name used in problems; every problem's message starts "line N, column
/// M: " and its offset is the byte offset of the bad token.
Result<AircraftParams> parseAircraft(std::string_view text, const std::string& name);
Result<AircraftParams> readAircraftFile(const std::string& path);

/// A state in wings-level horizontal flight at `speedMs` on `headingDeg`,
/// pitched to the angle of attack where lift equals weight (clamped to
/// the stall), throttle set to balance drag, full fuel. Starting point for
/// scenarios; approximately trimmed (the stick is not centred unless the
/// speed is the trim speed).
AirState levelFlight(const AircraftParams& p, const Eigen::Vector3d& position, double headingDeg, double speedMs);

/// Advance one step of dt seconds (semi-implicit Euler; docs/AIRCRAFT.md
/// gives the equations). dt <= 0 or non-finite leaves the state as it is.
/// No ground: the caller handles terrain contact.
void stepAircraft(const AircraftParams& p, const AirControls& c, AirState& s, double dt = kDefaultAirStep);

/// A stateless PD autopilot: rolls to a bank proportional to the heading
/// error (at most 30 deg), sets the angle of attack for the flight path
/// that closes the altitude error, and the throttle for drag plus the
/// speed error. Controls for the present state; call it every step.
AirControls holdAttitude(const AircraftParams& p, const AirState& s, double targetHeadingDeg, double targetAltitudeM,
                         double targetSpeedMs);

}  // namespace sandtable::sim
