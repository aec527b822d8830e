// Air entities (seed VII.B.3): the aircraft file reader, the Euler <->
// quaternion conversions, the six-degree-of-freedom step and the autopilot.
// docs/AIRCRAFT.md states the equations this file implements.
#include "sandtable/sim/aircraft.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>
#include <vector>

#include "sandtable/sim/entity.h"
#include "text.h"

namespace sandtable::sim {
namespace {

using namespace text;  // the line readers' shared helpers

constexpr std::size_t kMaxProblems = 20;
/// Below this airspeed (m/s) the air exerts nothing: alpha and sideslip
/// have no meaning for a body at rest.
constexpr double kMinAirspeed = 1e-6;
/// Horizontal length of the forward vector below which the nose counts as
/// exactly vertical (about 2e-7 deg off).
constexpr double kVertical = 1e-9;

double clampd(double v, double lo, double hi) { return std::min(std::max(v, lo), hi); }

/// A control input as used: non-finite counts as 0 (a NaN from a broken
/// joystick driver must not poison the state), then clamped.
double control(double v, double lo, double hi) { return std::isfinite(v) ? clampd(v, lo, hi) : 0.0; }

/// Angle in degrees wrapped to (-180, 180]. Not turnBetween(0, deg)
/// (entity.h): that goes through [0, 360), which rounds a small negative
/// angle to the last bit of 360 and would move the autopilot's controls.
double wrap180(double deg) {
  double w = std::fmod(deg, 360.0);
  if (w <= -180.0) w += 360.0;
  if (w > 180.0) w -= 360.0;
  return w;
}

// ---------------------------------------------------------------------------
// The file format.

struct Field {
  const char* key;
  double AircraftParams::*member;
  double lo, hi;
  bool loOpen;  ///< lo itself is not allowed (must be > lo)
  const char* unit;
};

// Bounds keep the model in the range where it was tested and reject
// typos (a mass of 35 kg, a limit of 250 deg); they are not physical laws.
const Field kFields[] = {
    {"mass", &AircraftParams::mass, 0, 1e6, true, "kg, empty mass"},
    {"wing_area", &AircraftParams::wingArea, 0, 2000, true, "m^2"},
    {"max_thrust", &AircraftParams::maxThrust, 0, 2e6, false, "N at sea level"},
    {"spool_time", &AircraftParams::spoolTime, 0, 60, false, "s, 0 = instant"},
    {"cl0", &AircraftParams::cl0, -2, 2, false, "lift coefficient at zero alpha"},
    {"cl_alpha", &AircraftParams::clAlpha, 0, 20, true, "per rad"},
    {"cl_max", &AircraftParams::clMax, 0, 5, true, "lift coefficient at the stall"},
    {"cd0", &AircraftParams::cd0, 0, 2, false, "zero-lift drag coefficient"},
    {"induced_drag", &AircraftParams::inducedDrag, 0, 2, false, "k in CD = CD0 + k CL^2"},
    {"side_force", &AircraftParams::sideForce, 0, 10, false, "per rad of sideslip"},
    {"elevator_limit", &AircraftParams::elevatorLimitDeg, 0, 90, true, "deg"},
    {"aileron_limit", &AircraftParams::aileronLimitDeg, 0, 90, true, "deg"},
    {"rudder_limit", &AircraftParams::rudderLimitDeg, 0, 90, true, "deg"},
    {"elevator_power", &AircraftParams::elevatorPower, 0, 1000, false, "rad/s^2 per rad"},
    {"aileron_power", &AircraftParams::aileronPower, 0, 1000, false, "rad/s^2 per rad"},
    {"rudder_power", &AircraftParams::rudderPower, 0, 1000, false, "rad/s^2 per rad"},
    {"pitch_damping", &AircraftParams::pitchDamping, 0, 1000, true, "1/s"},
    {"roll_damping", &AircraftParams::rollDamping, 0, 1000, true, "1/s"},
    {"yaw_damping", &AircraftParams::yawDamping, 0, 1000, true, "1/s"},
    {"pitch_stability", &AircraftParams::pitchStability, 0, 1000, true, "rad/s^2 per rad"},
    {"yaw_stability", &AircraftParams::yawStability, 0, 1000, false, "rad/s^2 per rad"},
    {"alpha_trim", &AircraftParams::alphaTrimDeg, -20, 20, false, "deg"},
    {"reference_pressure", &AircraftParams::referencePressure, 0, 1e6, true, "Pa"},
    {"fuel_capacity", &AircraftParams::fuelCapacity, 0, 1e6, false, "kg"},
    {"fuel_burn", &AircraftParams::fuelBurn, 0, 1000, false, "kg/s at full throttle"},
};
constexpr std::size_t kFieldCount = std::size(kFields);

std::string knownKeys() {
  std::string s;
  for (const Field& f : kFields) {
    if (!s.empty()) s += ", ";
    s += f.key;
  }
  return s;
}

std::string rangeText(const Field& f) {
  std::string s = f.loOpen ? "greater than " : "at least ";
  s += shortNumber(f.lo);
  s += " and at most ";
  s += shortNumber(f.hi);
  return s;
}

class Parser {
 public:
  Parser(std::string_view text, std::string name) : text_(text), name_(std::move(name)) {}

  Result<AircraftParams> run() {
    bool header = false;
    std::size_t pos = 0;
    std::size_t lineNo = 0;
    while (pos < text_.size()) {
      lineStart_ = pos;
      const std::string_view line = nextLine(text_, pos);
      ++lineNo;
      if (!plainText(line, lineStart_)) continue;
      // Keys and numbers never hold a '#', so one anywhere starts a comment.
      const auto tok = tokenize(line, Comment::anywhere);
      if (tok.empty()) continue;
      if (!header) {
        if (!headerLine(tok)) return problems_;
        header = true;
        continue;
      }
      keyLine(tok, lineNo);
    }
    if (!header) {
      fail(text_.size(), std::string("the file has no header; its first line that is not a comment must be \"") +
                             kAircraftHeaderLine + "\"");
      return problems_;
    }
    for (std::size_t k = 0; k < kFieldCount; ++k) {
      if (lines_[k] == 0) {
        std::string m = "missing key ";
        m += text::quoted(kFields[k].key);
        m += "; add a line \"";
        m += kFields[k].key;
        m += " VALUE\" (";
        m += kFields[k].unit;
        m += ")";
        fail(text_.size(), m);
      }
    }
    if (problems_.empty()) crossCheck();
    if (!problems_.empty()) return problems_;
    params_.name = name_;
    return params_;
  }

 private:
  /// Line (from 1) and column (from 0, in bytes) of a byte offset.
  std::pair<std::size_t, std::size_t> where(std::size_t offset) const {
    std::size_t line = 1, lineStart = 0;
    for (std::size_t k = 0; k < offset && k < text_.size(); ++k) {
      if (text_[k] == '\n') {
        ++line;
        lineStart = k + 1;
      }
    }
    return {line, offset - lineStart};
  }

  void fail(std::size_t offset, const std::string& what) {
    if (problems_.size() >= kMaxProblems) return;
    const auto [line, column] = where(offset);
    problems_.push_back({name_, offset, lineColumnMessage(line, column, what)});
  }

  bool plainText(std::string_view line, std::size_t start) {
    const std::size_t k = findControl(line);
    if (k == std::string_view::npos) return true;
    fail(start + k, controlCharacter(line[k]) + "; an aircraft file is plain text (remove it)");
    return false;
  }

  /// Byte offset in the whole text of a word of the current line.
  std::size_t offsetOf(const Token& t) const { return lineStart_ + t.column; }

  bool headerLine(const std::vector<Token>& tok) {
    if (tok[0].text == "sandtable-aircraft" && tok.size() == 2) {
      double v = 0;
      if (tok[1].text == "1") return true;
      if (finiteNumber(tok[1].text, v) && v > 1) {
        std::string m = "version ";
        m += tok[1].text;
        m += " is newer than this reader knows (1); use a newer sandtable or write \"";
        m += kAircraftHeaderLine;
        m += "\"";
        fail(offsetOf(tok[1]), m);
        return false;
      }
    }
    fail(offsetOf(tok[0]), std::string("missing header; the first line that is not a comment must be \"") +
                            kAircraftHeaderLine + "\"");
    return false;
  }

  void keyLine(const std::vector<Token>& tok, std::size_t lineNo) {
    if (tok[0].text == "sandtable-aircraft") {
      return fail(offsetOf(tok[0]), "the header may appear only once; remove this line");
    }
    std::size_t f = kFieldCount;
    for (std::size_t k = 0; k < kFieldCount; ++k) {
      if (tok[0].text == kFields[k].key) f = k;
    }
    if (f == kFieldCount) {
      std::string m = "unknown key ";
      m += text::quoted(tok[0].text);
      m += "; the keys are: ";
      m += knownKeys();
      return fail(offsetOf(tok[0]), m);
    }
    const Field& field = kFields[f];
    if (lines_[f] != 0) {
      std::string m = "key ";
      m += text::quoted(field.key);
      m += " is given twice (first on line ";
      m += std::to_string(lines_[f]);
      m += "); keep one";
      return fail(offsetOf(tok[0]), m);
    }
    if (tok.size() == 1) {
      std::string m = "key ";
      m += text::quoted(field.key);
      m += " has no value; write \"";
      m += field.key;
      m += " VALUE\" (";
      m += field.unit;
      m += ")";
      return fail(offsetOf(tok[0]) + tok[0].text.size(), m);
    }
    if (tok.size() > 2) {
      std::string m = "unexpected ";
      m += text::quoted(tok[2].text);
      m += " after the value of ";
      m += text::quoted(field.key);
      m += "; one value per line (comments start with #)";
      return fail(offsetOf(tok[2]), m);
    }
    double v = 0;
    if (!finiteNumber(tok[1].text, v)) {
      std::string m = "value ";
      m += text::quoted(tok[1].text);
      m += " of ";
      m += text::quoted(field.key);
      m += " is not a finite number; write a decimal number such as 12.5 (";
      m += field.unit;
      m += ")";
      return fail(offsetOf(tok[1]), m);
    }
    if ((field.loOpen ? !(v > field.lo) : !(v >= field.lo)) || !(v <= field.hi)) {
      std::string m = text::quoted(field.key);
      m += " ";
      m += tok[1].text;
      m += " is out of range; it must be ";
      m += rangeText(field);
      m += " (";
      m += field.unit;
      m += ")";
      return fail(offsetOf(tok[1]), m);
    }
    params_.*field.member = v;
    lines_[f] = lineNo;
    valueOffsets_[f] = offsetOf(tok[1]);
  }

  std::size_t fieldIndex(const char* key) const {
    for (std::size_t k = 0; k < kFieldCount; ++k) {
      if (std::string_view(kFields[k].key) == key) return k;
    }
    return 0;
  }

  /// Relations between keys: the trim angle of attack must not be stalled.
  void crossCheck() {
    const double cl = params_.cl0 + params_.clAlpha * params_.alphaTrimDeg * kDegToRad;
    if (!(std::abs(cl) < params_.clMax)) {
      std::string m = "alpha_trim ";
      m += shortNumber(params_.alphaTrimDeg);
      m += " deg gives CL = cl0 + cl_alpha * alpha_trim = ";
      m += shortNumber(cl);
      m += ", beyond cl_max ";
      m += shortNumber(params_.clMax);
      m += "; the aircraft would trim stalled: lower alpha_trim or raise cl_max";
      fail(valueOffsets_[fieldIndex("alpha_trim")], m);
    }
  }

  std::string_view text_;
  std::string name_;
  std::vector<Problem> problems_;
  AircraftParams params_;
  std::size_t lines_[kFieldCount] = {};
  std::size_t valueOffsets_[kFieldCount] = {};
  std::size_t lineStart_ = 0;  ///< byte offset of the current line
};

// ---------------------------------------------------------------------------
// Dynamics.

/// Mass that flies: the airframe plus what fuel is left.
double flyingMass(const AircraftParams& p, const AirState& s) { return p.mass + std::max(s.fuelKg, 0.0); }

double availableThrust(const AircraftParams& p, double density) {
  return p.maxThrust * density / kSeaLevelDensity;
}

/// What the air does in one state: the aerodynamic force in body axes and
/// the angular accelerations (p, q, r order) from controls and static
/// stability. Damping is left to the integrator, which treats it
/// implicitly.
struct AeroResult {
  Eigen::Vector3d forceBody = Eigen::Vector3d::Zero();
  Eigen::Vector3d drive = Eigen::Vector3d::Zero();
};

AeroResult aerodynamics(const AircraftParams& p, const AirControls& c, const Eigen::Vector3d& vBody, double density) {
  AeroResult out;
  const double speed = vBody.norm();
  if (!(speed > kMinAirspeed)) return out;
  const Eigen::Vector3d vHat = vBody / speed;
  const double alpha = std::atan2(-vBody.y(), -vBody.z());
  const double beta = std::asin(clampd(vBody.x() / speed, -1.0, 1.0));
  const double qbar = 0.5 * density * speed * speed;
  const double cl = clampd(p.cl0 + p.clAlpha * alpha, -p.clMax, p.clMax);
  const double cd = p.cd0 + p.inducedDrag * cl * cl;
  // Lift is perpendicular to the airflow in the plane of symmetry:
  // right x vHat = (0, -vHat.z, vHat.y); side force completes the frame.
  Eigen::Vector3d liftDir(0.0, -vHat.z(), vHat.y());
  const double liftNorm = liftDir.norm();
  liftDir = liftNorm > 1e-12 ? Eigen::Vector3d(liftDir / liftNorm) : Eigen::Vector3d::Zero();
  const Eigen::Vector3d sideDir = vHat.cross(liftDir);
  out.forceBody = qbar * p.wingArea * (cl * liftDir - cd * vHat - p.sideForce * beta * sideDir);
  const double ratio = qbar / p.referencePressure;
  out.drive.x() = ratio * p.aileronPower * c.aileron * p.aileronLimitDeg * kDegToRad;
  out.drive.y() = ratio * (p.elevatorPower * c.elevator * p.elevatorLimitDeg * kDegToRad -
                           p.pitchStability * (alpha - p.alphaTrimDeg * kDegToRad));
  out.drive.z() = ratio * (p.rudderPower * c.rudder * p.rudderLimitDeg * kDegToRad + p.yawStability * beta);
  return out;
}

AirControls sanitized(const AirControls& c) {
  return {control(c.throttle, 0, 1), control(c.elevator, -1, 1), control(c.aileron, -1, 1),
          control(c.rudder, -1, 1)};
}

}  // namespace

// ---------------------------------------------------------------------------
// Frames.

Eigen::Quaterniond orientationFromEuler(double headingDeg, double pitchDeg, double rollDeg) {
  // The entities' rotation (entity.h): yaw -h about +Y, then pitch about
  // the body's +X, then roll -r about the body's +Z (right wing down).
  return orientationOf(headingDeg, pitchDeg, rollDeg);
}

Euler eulerFromOrientation(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d m = q.normalized().toRotationMatrix();
  const Eigen::Vector3d right = m.col(0), up = m.col(1), forward = -m.col(2);
  const double horizontal = std::hypot(forward.x(), forward.z());
  Euler e;
  e.pitchDeg = std::atan2(forward.y(), horizontal) / kDegToRad;
  double heading = 0;
  if (horizontal < kVertical) {
    // Nose straight up or down: roll folds into heading; the right wing is
    // horizontal and points along (cos h, 0, sin h) at roll 0.
    e.pitchDeg = forward.y() > 0 ? 90.0 : -90.0;
    heading = std::atan2(right.z(), right.x()) / kDegToRad;
    e.rollDeg = 0;
  } else {
    heading = std::atan2(forward.x(), -forward.z()) / kDegToRad;
    // right.y = -sin(roll) cos(pitch), up.y = cos(roll) cos(pitch).
    e.rollDeg = std::atan2(-right.y(), up.y()) / kDegToRad;
    if (e.rollDeg <= -180.0) e.rollDeg += 360.0;
  }
  e.headingDeg = wrapDeg(heading);
  return e;
}

Eigen::Vector3d forwardOf(const Eigen::Quaterniond& q) { return q * Eigen::Vector3d(0, 0, -1); }
Eigen::Vector3d upOf(const Eigen::Quaterniond& q) { return q * Eigen::Vector3d(0, 1, 0); }
Eigen::Vector3d rightOf(const Eigen::Quaterniond& q) { return q * Eigen::Vector3d(1, 0, 0); }

Eigen::Vector3d bodyRateVector(const AirState& s) {
  // Roll p turns about forward (-Z), pitch q about right (+X), yaw r
  // (nose right) about down (-Y).
  return {s.angularVelocity.y(), -s.angularVelocity.z(), -s.angularVelocity.x()};
}

double airDensity(double altitudeM) { return kSeaLevelDensity * std::exp(-altitudeM / kScaleHeight); }

AirData airData(const AircraftParams& p, const AirState& s) {
  AirData a;
  a.density = airDensity(s.position.y());
  const Eigen::Vector3d vBody = s.orientation.normalized().conjugate() * s.velocity;
  a.speed = vBody.norm();
  a.dynamicPressure = 0.5 * a.density * a.speed * a.speed;
  if (a.speed > kMinAirspeed) {
    a.alphaRad = std::atan2(-vBody.y(), -vBody.z());
    a.betaRad = std::asin(clampd(vBody.x() / a.speed, -1.0, 1.0));
  }
  a.massKg = flyingMass(p, s);
  return a;
}

// ---------------------------------------------------------------------------
// The file.

Result<AircraftParams> parseAircraft(std::string_view text, const std::string& name) {
  if (text.size() > kMaxAircraftFileBytes) {
    std::string m = "line 1, column 1: the file is ";
    m += std::to_string(text.size());
    m += " bytes, more than the ";
    m += std::to_string(kMaxAircraftFileBytes);
    m += " an aircraft file may have; is this the right file?";
    return Problem{name, 0, m};
  }
  return Parser(text, name).run();
}

Result<AircraftParams> readAircraftFile(const std::string& path) {
  auto body = text::readText(path, kMaxAircraftFileBytes, "the aircraft file", "line 1, column 1: ");
  if (!body) return body.problems();
  return parseAircraft(body.value(), path);
}

// ---------------------------------------------------------------------------
// Flight.

AirState levelFlight(const AircraftParams& p, const Eigen::Vector3d& position, double headingDeg, double speedMs) {
  AirState s;
  s.position = position;
  s.fuelKg = p.fuelCapacity;
  const double speed = std::isfinite(speedMs) ? std::max(speedMs, 0.0) : 0.0;
  const double density = airDensity(position.y());
  const double qbar = 0.5 * density * speed * speed;
  double alpha = p.alphaTrimDeg * kDegToRad;
  double cl = p.cl0 + p.clAlpha * alpha;
  if (qbar > 0) {
    cl = clampd(flyingMass(p, s) * kGravity / (qbar * p.wingArea), -p.clMax, p.clMax);
    alpha = (cl - p.cl0) / p.clAlpha;
  }
  s.orientation = orientationFromEuler(headingDeg, alpha / kDegToRad, 0);
  s.velocity = speed * headingVector(headingDeg);
  const double drag = qbar * p.wingArea * (p.cd0 + p.inducedDrag * cl * cl);
  const double thrust = availableThrust(p, density);
  s.throttle = thrust > 0 ? clampd(drag / thrust, 0, 1) : 0;
  return s;
}

void stepAircraft(const AircraftParams& p, const AirControls& controls, AirState& s, double dt) {
  if (!(dt > 0) || !std::isfinite(dt)) return;
  const AirControls c = sanitized(controls);
  const double density = airDensity(s.position.y());
  const Eigen::Quaterniond q = s.orientation.normalized();
  const Eigen::Matrix3d toWorld = q.toRotationMatrix();
  const Eigen::Vector3d vBody = toWorld.transpose() * s.velocity;
  const bool hasFuel = s.fuelKg > 0;
  const double mass = flyingMass(p, s);

  // Forces at the start of the step.
  AeroResult aero = aerodynamics(p, c, vBody, density);
  const double thrust = hasFuel ? s.throttle * availableThrust(p, density) : 0.0;
  aero.forceBody.z() -= thrust;  // along the nose, body -Z
  const Eigen::Vector3d accel = toWorld * aero.forceBody / mass - Eigen::Vector3d(0, kGravity, 0);

  // Rates: explicit drive, implicit damping, so any damping is stable.
  Eigen::Vector3d& w = s.angularVelocity;
  w.x() = (w.x() + aero.drive.x() * dt) / (1 + p.rollDamping * dt);
  w.y() = (w.y() + aero.drive.y() * dt) / (1 + p.pitchDamping * dt);
  w.z() = (w.z() + aero.drive.z() * dt) / (1 + p.yawDamping * dt);

  // Orientation from the new body rates: the exact rotation of a constant
  // rate over the step, applied in body axes (right-multiplied).
  const Eigen::Vector3d omega = bodyRateVector(s);
  const double angle = omega.norm() * dt;
  Eigen::Quaterniond turned = q;
  if (angle > 0) turned = q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega.normalized()));
  s.orientation = turned.normalized();

  // Translation: semi-implicit Euler.
  s.velocity += accel * dt;
  s.position += s.velocity * dt;

  // Engine: first-order spool (exact for a held command); a dry engine
  // winds down. Fuel burns at the setting that made this step's thrust.
  const double command = hasFuel ? c.throttle : 0.0;
  const double follow = p.spoolTime > 0 ? 1.0 - std::exp(-dt / p.spoolTime) : 1.0;
  const double used = s.throttle;
  s.throttle = clampd(s.throttle + (command - s.throttle) * follow, 0.0, 1.0);
  if (hasFuel) s.fuelKg = std::max(0.0, s.fuelKg - used * p.fuelBurn * dt);
}

AirControls holdAttitude(const AircraftParams& p, const AirState& s, double targetHeadingDeg, double targetAltitudeM,
                         double targetSpeedMs) {
  // Gains, chosen for a time scale of seconds: a bank loop of 2.5 rad/s,
  // a flight-path loop of 2 s, an altitude loop of 10 s, a speed loop of
  // 3 s; each outer loop several times slower than the one inside it.
  constexpr double kRollFreq = 2.5, kRollDampingRatio = 0.8;
  constexpr double kBankPerHeading = 2.0, kMaxBankDeg = 30.0;
  constexpr double kAltitudeGain = 0.1, kMaxClimbDeg = 10.0;
  constexpr double kPathGain = 0.5, kSpeedGain = 0.3, kSideslipGain = 2.0;

  AirControls c;
  const AirData a = airData(p, s);
  if (a.speed < 1.0) {
    c.throttle = 1;  // no airspeed, no authority: only the engine can help
    return c;
  }
  const Euler e = eulerFromOrientation(s.orientation);
  const double ratio = std::max(a.dynamicPressure / p.referencePressure, 0.05);
  const double pRate = s.angularVelocity.x();

  // Lateral: bank toward the heading, by inverse roll dynamics so the
  // bank follows a damped second-order response.
  const double headingErr = wrap180(targetHeadingDeg - e.headingDeg) * kDegToRad;
  const double bankCmd = clampd(kBankPerHeading * headingErr, -kMaxBankDeg * kDegToRad, kMaxBankDeg * kDegToRad);
  const double bankErr = wrap180((bankCmd / kDegToRad) - e.rollDeg) * kDegToRad;
  const double rollAccel = kRollFreq * kRollFreq * bankErr - 2 * kRollDampingRatio * kRollFreq * pRate;
  const double aileronAuthority = p.aileronPower * p.aileronLimitDeg * kDegToRad * ratio;
  if (aileronAuthority > 0) c.aileron = clampd((rollAccel + p.rollDamping * pRate) / aileronAuthority, -1, 1);

  // Rudder helps the weathercock against sideslip.
  c.rudder = clampd(kSideslipGain * a.betaRad / (p.rudderLimitDeg * kDegToRad), -1, 1);

  // Longitudinal: altitude error -> climb rate -> flight path -> load
  // factor -> angle of attack -> the elevator that trims at it.
  const double weight = a.massKg * kGravity;
  const double gamma = std::asin(clampd(s.velocity.y() / a.speed, -1, 1));
  const double maxClimb = a.speed * std::sin(kMaxClimbDeg * kDegToRad);
  const double climbCmd = clampd(kAltitudeGain * (targetAltitudeM - s.position.y()), -maxClimb, maxClimb);
  const double gammaCmd = std::asin(climbCmd / a.speed);
  const double cosBank = std::max(std::cos(e.rollDeg * kDegToRad), 0.5);
  const double loadFactor = std::cos(gamma) / cosBank + a.speed * kPathGain * (gammaCmd - gamma) / kGravity;
  const double clCmd = clampd(loadFactor * weight / (a.dynamicPressure * p.wingArea), -0.5 * p.clMax, 0.9 * p.clMax);
  const double alphaCmd = (clCmd - p.cl0) / p.clAlpha;
  const double elevatorAuthority = p.elevatorPower * p.elevatorLimitDeg * kDegToRad;
  if (elevatorAuthority > 0) {
    c.elevator = clampd(p.pitchStability * (alphaCmd - p.alphaTrimDeg * kDegToRad) / elevatorAuthority, -1, 1);
  }

  // Throttle: drag at the commanded lift, the climb, and the speed error.
  const double drag = a.dynamicPressure * p.wingArea * (p.cd0 + p.inducedDrag * clCmd * clCmd);
  const double need = drag + weight * std::sin(gamma) + a.massKg * kSpeedGain * (targetSpeedMs - a.speed);
  const double available = availableThrust(p, a.density);
  c.throttle = available > 0 ? clampd(need / available, 0, 1) : 0;
  return c;
}

}  // namespace sandtable::sim
