// Air-entity dynamics (seed VII.B.3): frames, the aircraft file, the
// flight model against hand-worked forces, a quaternion loop through the
// vertical, and the autopilot.
#include "sandtable/sim/aircraft.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#ifndef SANDTABLE_SOURCE_DIR
#define SANDTABLE_SOURCE_DIR "."
#endif

namespace sandtable::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kRad = kPi / 180.0;
constexpr double kDt = 1.0 / 60.0;

std::string samplePath(const char* file) {
  std::string p = SANDTABLE_SOURCE_DIR;
  p += "/samples/aircraft/";
  p += file;
  return p;
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

AircraftParams trainer() {
  auto r = readAircraftFile(samplePath("trainer.txt"));
  EXPECT_TRUE(r.ok()) << r.error();
  return r.ok() ? r.value() : AircraftParams{};
}

double wrap180(double d) {
  double w = std::fmod(d, 360.0);
  if (w <= -180) w += 360;
  if (w > 180) w -= 360;
  return w;
}

/// Body axes built by hand from heading, pitch and roll (independent of
/// the quaternion code): at roll 0 the right wing is horizontal, (cos h, 0,
/// sin h), the nose is (sin h cos p, sin p, -cos h cos p), and the up axis
/// completes them; rolling right turns the right wing toward -up.
struct Axes {
  Eigen::Vector3d forward, right, up;
};
Axes axesByHand(double hDeg, double pDeg, double rDeg) {
  const double h = hDeg * kRad, p = pDeg * kRad, r = rDeg * kRad;
  const Eigen::Vector3d forward(std::sin(h) * std::cos(p), std::sin(p), -std::cos(h) * std::cos(p));
  const Eigen::Vector3d right0(std::cos(h), 0, std::sin(h));
  const Eigen::Vector3d up0(-std::sin(h) * std::sin(p), std::cos(p), std::cos(h) * std::sin(p));
  return {forward, std::cos(r) * right0 - std::sin(r) * up0, std::cos(r) * up0 + std::sin(r) * right0};
}

void expectAxes(const Eigen::Quaterniond& q, const Axes& a, double tol, const std::string& where) {
  EXPECT_LT((forwardOf(q) - a.forward).norm(), tol) << where;
  EXPECT_LT((rightOf(q) - a.right).norm(), tol) << where;
  EXPECT_LT((upOf(q) - a.up).norm(), tol) << where;
}

// ---------------------------------------------------------------------------
// Frames

TEST(AircraftFrames, IdentityFacesNorthAndHeadingIsClockwise) {
  const Eigen::Quaterniond q0 = orientationFromEuler(0, 0, 0);
  EXPECT_LT((forwardOf(q0) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-15);
  EXPECT_LT((upOf(q0) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-15);
  // Heading 90 is east (+x), 180 south (+z), 270 west.
  EXPECT_LT((forwardOf(orientationFromEuler(90, 0, 0)) - Eigen::Vector3d(1, 0, 0)).norm(), 1e-15);
  EXPECT_LT((forwardOf(orientationFromEuler(180, 0, 0)) - Eigen::Vector3d(0, 0, 1)).norm(), 1e-15);
  EXPECT_LT((forwardOf(orientationFromEuler(270, 0, 0)) - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-15);
  // Rolling right puts the right wing down.
  EXPECT_LT((rightOf(orientationFromEuler(0, 0, 90)) - Eigen::Vector3d(0, -1, 0)).norm(), 1e-15);
  // Density: rho0 at sea level, rho0 / e one scale height up.
  EXPECT_DOUBLE_EQ(airDensity(0), 1.225);
  EXPECT_NEAR(airDensity(8500), 1.225 / std::exp(1.0), 1e-15);
}

TEST(AircraftFrames, EulerRoundTripOnManyAngles) {
  int checked = 0;
  for (double h = 0; h < 360; h += 15) {
    for (double p = -85; p <= 85; p += 10) {
      for (double r = -165; r <= 180; r += 15) {
        const std::string where = "h " + std::to_string(h) + " p " + std::to_string(p) + " r " + std::to_string(r);
        const Eigen::Quaterniond q = orientationFromEuler(h, p, r);
        EXPECT_NEAR(q.norm(), 1.0, 1e-15) << where;
        expectAxes(q, axesByHand(h, p, r), 1e-14, where);
        const Euler e = eulerFromOrientation(q);
        EXPECT_NEAR(wrap180(e.headingDeg - h), 0, 1e-9) << where;
        EXPECT_NEAR(e.pitchDeg, p, 1e-9) << where;
        EXPECT_NEAR(wrap180(e.rollDeg - r), 0, 1e-9) << where;
        EXPECT_GT(e.rollDeg, -180.0);
        EXPECT_LE(e.rollDeg, 180.0);
        EXPECT_GE(e.headingDeg, 0.0);
        EXPECT_LT(e.headingDeg, 360.0);
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 24 * 18 * 24);
  // Odd angles too, including out-of-range inputs that wrap.
  const double odd[][3] = {{359.9999, 89.99, -179.99}, {0.0001, -89.99, 0.001}, {-30, 12.5, 200}, {725, -3, -7}};
  for (const auto& a : odd) {
    const Euler e = eulerFromOrientation(orientationFromEuler(a[0], a[1], a[2]));
    const Axes hand = axesByHand(a[0], a[1], a[2]);
    expectAxes(orientationFromEuler(e.headingDeg, e.pitchDeg, e.rollDeg), hand, 1e-12, "odd");
    EXPECT_NEAR(wrap180(e.headingDeg - a[0]), 0, 1e-6);
    EXPECT_NEAR(e.pitchDeg, a[1], 1e-6);
    EXPECT_NEAR(wrap180(e.rollDeg - a[2]), 0, 1e-6);
  }
}

TEST(AircraftFrames, ExactlyVerticalIsWellDefined) {
  for (double pitch : {90.0, -90.0}) {
    for (double h = 0; h < 360; h += 30) {
      for (double r = -150; r <= 180; r += 30) {
        const Eigen::Quaterniond q = orientationFromEuler(h, pitch, r);
        const Axes hand = axesByHand(h, pitch, r);
        expectAxes(q, hand, 1e-14, "vertical");
        EXPECT_LT((forwardOf(q) - Eigen::Vector3d(0, pitch > 0 ? 1 : -1, 0)).norm(), 1e-15);
        const Euler e = eulerFromOrientation(q);
        EXPECT_EQ(e.pitchDeg, pitch);
        EXPECT_EQ(e.rollDeg, 0.0);
        EXPECT_TRUE(std::isfinite(e.headingDeg));
        // Heading carries the roll: the same attitude comes back.
        expectAxes(orientationFromEuler(e.headingDeg, e.pitchDeg, e.rollDeg), hand, 1e-12, "vertical back");
        // At roll 0 the heading is the one given; up points back from it.
        if (r == 0) {
          EXPECT_NEAR(wrap180(e.headingDeg - h), 0, 1e-9);
        }
      }
    }
  }
  // Nose straight up at heading 0, wings level: the belly faces north
  // and the canopy south.
  EXPECT_LT((upOf(orientationFromEuler(0, 90, 0)) - Eigen::Vector3d(0, 0, 1)).norm(), 1e-15);
}

// ---------------------------------------------------------------------------
// The file

TEST(AircraftFile, SamplesParse) {
  const AircraftParams p = trainer();
  EXPECT_EQ(p.name, samplePath("trainer.txt"));
  EXPECT_EQ(p.mass, 3500);
  EXPECT_EQ(p.wingArea, 18.8);
  EXPECT_EQ(p.maxThrust, 16900);
  EXPECT_EQ(p.spoolTime, 2.0);
  EXPECT_EQ(p.cl0, 0.15);
  EXPECT_EQ(p.clAlpha, 4.8);
  EXPECT_EQ(p.clMax, 1.3);
  EXPECT_EQ(p.cd0, 0.030);
  EXPECT_EQ(p.inducedDrag, 0.07);
  EXPECT_EQ(p.sideForce, 0.6);
  EXPECT_EQ(p.elevatorLimitDeg, 25);
  EXPECT_EQ(p.aileronLimitDeg, 20);
  EXPECT_EQ(p.rudderLimitDeg, 25);
  EXPECT_EQ(p.elevatorPower, 10);
  EXPECT_EQ(p.aileronPower, 30);
  EXPECT_EQ(p.rudderPower, 5);
  EXPECT_EQ(p.referencePressure, 4800);
  EXPECT_EQ(p.pitchDamping, 3);
  EXPECT_EQ(p.rollDamping, 4);
  EXPECT_EQ(p.yawDamping, 2);
  EXPECT_EQ(p.pitchStability, 12);
  EXPECT_EQ(p.yawStability, 8);
  EXPECT_EQ(p.alphaTrimDeg, 4);
  EXPECT_EQ(p.fuelCapacity, 980);
  EXPECT_EQ(p.fuelBurn, 0.30);
  const auto f = readAircraftFile(samplePath("fighter.txt"));
  ASSERT_TRUE(f.ok()) << f.error();
  EXPECT_EQ(f->mass, 8900);
  // The comment in trainer.txt claims a trim speed of about 89 m/s at sea
  // level with full fuel; check it by hand.
  const double m = p.mass + p.fuelCapacity;
  const double cl = 0.15 + 4.8 * 4 * kRad;
  EXPECT_NEAR(std::sqrt(2 * m * 9.80665 / (1.225 * 18.8 * cl)), 89, 1);
}

/// The trainer file with the line that starts with `key` replaced (or, if
/// `replacement` is empty, removed).
std::string withLine(const std::string& key, const std::string& replacement) {
  std::string text = readText(samplePath("trainer.txt"));
  const std::size_t at = text.find("\n" + key + " ");
  EXPECT_NE(at, std::string::npos) << key;
  const std::size_t end = text.find('\n', at + 1);
  text.replace(at + 1, end - at - 1 + (replacement.empty() ? 1 : 0), replacement);
  return text;
}

/// Expect exactly the first problem to point at byte `offset` with "line
/// L, column C: " worked out from the text, and to contain `hint`.
void expectError(const std::string& text, std::size_t offset, const std::string& hint) {
  const auto r = parseAircraft(text, "test.txt");
  ASSERT_FALSE(r.ok()) << "accepted; expected an error containing " << hint;
  const Problem& p = r.problems().front();
  EXPECT_EQ(p.file, "test.txt");
  EXPECT_EQ(p.offset, offset) << p.message;
  std::size_t line = 1, lineStart = 0;
  for (std::size_t k = 0; k < offset; ++k) {
    if (text[k] == '\n') ++line, lineStart = k + 1;
  }
  const std::string prefix = "line " + std::to_string(line) + ", column " + std::to_string(offset - lineStart + 1) + ": ";
  EXPECT_EQ(p.message.rfind(prefix, 0), 0u) << p.message << " (expected prefix " << prefix << ")";
  EXPECT_NE(p.message.find(hint), std::string::npos) << p.message;
}

TEST(AircraftFile, ErrorsNameLineAndColumn) {
  {  // The token after the key, in the changed line.
    const std::string t = withLine("mass", "mass   -5");
    expectError(t, t.find("-5"), "greater than 0");
  }
  {
    const std::string t = withLine("wing_area", "wing_area 0  # none");
    expectError(t, t.find("wing_area 0") + 10, "greater than 0");
  }
  {
    const std::string t = withLine("cd0", "cd0 nan");
    expectError(t, t.find("nan"), "not a finite number");
  }
  {
    const std::string t = withLine("cl_alpha", "cl_alpha 4.8abc");
    expectError(t, t.find("4.8abc"), "not a finite number");
  }
  {
    const std::string t = withLine("max_thrust", "max_thrust inf");
    expectError(t, t.find("inf"), "not a finite number");
  }
  {
    const std::string t = withLine("mass", "mass 3500 kg");
    expectError(t, t.find("kg", t.find("mass 3500")), "one value per line");
  }
  {
    const std::string t = withLine("mass", "\tmass");
    expectError(t, t.find("\tmass") + 5, "has no value");
  }
  {
    const std::string t = withLine("cd0", "wingspan 10");
    expectError(t, t.find("wingspan"), "unknown key \"wingspan\"; the keys are: mass, wing_area");
  }
  {
    std::string t = readText(samplePath("trainer.txt"));
    t += "mass 3600\n";
    expectError(t, t.rfind("mass"), "given twice (first on line 10)");
  }
  {  // A missing key points at the end of the file.
    const std::string t = withLine("fuel_burn", "");
    expectError(t, t.size(), "missing key \"fuel_burn\"");
  }
  {
    const std::string t = withLine("elevator_limit", "elevator_limit 120");
    expectError(t, t.find("120"), "at most 90");
  }
  {  // A stalled trim: 0.15 + 4.8 * 15 deg = 1.41 > 1.3.
    const std::string t = withLine("alpha_trim", "alpha_trim 15");
    expectError(t, t.find("15", t.find("alpha_trim 15")), "trim stalled");
  }
  {
    const std::string t = withLine("cd0", "cd0 0.03\x01");
    expectError(t, t.find('\x01'), "control character 0x01");
  }
  {
    const std::string t = "# no header\nmass 3500\n";
    expectError(t, t.find("mass"), "missing header");
  }
  {
    const std::string t = "sandtable-aircraft 2\n";
    expectError(t, t.find('2'), "newer than this reader");
  }
  expectError("", 0, "no header");
  expectError("  # only a comment\n", 19, "no header");
  {
    const auto r = readAircraftFile("/nonexistent/plane.txt");
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.problems().front().message.rfind("line 1, column 1: cannot open", 0), 0u);
  }
}

TEST(AircraftFile, CrlfAndTabsAndCommentsParse) {
  std::string t = readText(samplePath("trainer.txt"));
  std::string crlf;
  for (char c : t) {
    if (c == '\n') crlf += '\r';
    crlf += c == ' ' ? '\t' : c;
  }
  const auto r = parseAircraft(crlf, "crlf.txt");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r->wingArea, 18.8);
  const auto c = parseAircraft(withLine("mass", "mass 3400#no space before the comment"), "c.txt");
  ASSERT_TRUE(c.ok()) << c.error();
  EXPECT_EQ(c->mass, 3400);
}

// ---------------------------------------------------------------------------
// Flight, against hand-worked forces

/// Level flight north at altitude y, pitched to `alphaRad`, at speed v.
AirState levelAt(const AircraftParams& p, double y, double alphaRad, double v, double throttle) {
  AirState s;
  s.position = Eigen::Vector3d(0, y, 0);
  s.velocity = Eigen::Vector3d(0, 0, -v);
  s.orientation = orientationFromEuler(0, alphaRad / kRad, 0);
  s.throttle = throttle;
  s.fuelKg = p.fuelCapacity;
  return s;
}

TEST(AircraftFlight, TrimmedLevelFlightHoldsAltitude) {
  const AircraftParams p = trainer();
  const double y0 = 1000;
  const double rho = 1.225 * std::exp(-y0 / 8500);
  const double m = p.mass + p.fuelCapacity, g = 9.80665;
  // Stick centred, the aircraft settles at alpha_trim. Level flight at
  // that alpha with the nose on the horizon + alpha: vertically
  // L + T sin(a) = W, horizontally T cos(a) = D, so
  // qbar S (CL + CD tan a) = W.
  const double a = p.alphaTrimDeg * kRad;
  const double cl = p.cl0 + p.clAlpha * a;
  const double cd = p.cd0 + p.inducedDrag * cl * cl;
  const double qbar = m * g / (p.wingArea * (cl + cd * std::tan(a)));
  const double v = std::sqrt(2 * qbar / rho);
  // Within 1% of the task's first-order V = sqrt(2 m g / (rho S CL)).
  EXPECT_NEAR(v, std::sqrt(2 * m * g / (rho * p.wingArea * cl)), 0.01 * v);
  const double thrust = qbar * p.wingArea * cd / std::cos(a);
  const double throttle = thrust / (p.maxThrust * rho / 1.225);
  ASSERT_LT(throttle, 1.0);

  const auto fly = [&](double speed, double& worstDy, double& worstDv, double& worstPitch) {
    AirState s = levelAt(p, y0, a, speed, throttle);
    const AirControls c{throttle, 0, 0, 0};
    worstDy = worstDv = worstPitch = 0;
    for (int k = 0; k < 600; ++k) {  // 10 s
      stepAircraft(p, c, s, kDt);
      worstDy = std::max(worstDy, std::abs(s.position.y() - y0));
      worstDv = std::max(worstDv, std::abs(s.velocity.norm() - speed));
      worstPitch = std::max(worstPitch, std::abs(eulerFromOrientation(s.orientation).pitchDeg - p.alphaTrimDeg));
    }
  };
  double dy = 0, dv = 0, dp = 0;
  fly(v, dy, dv, dp);
  EXPECT_LT(dy, 0.2);
  EXPECT_LT(dv, 0.05);
  EXPECT_LT(dp, 0.01);
  // The bound is tight enough to matter: 5% slow, the plane sinks.
  fly(0.95 * v, dy, dv, dp);
  EXPECT_GT(dy, 5.0);
}

TEST(AircraftFlight, GlideDecelerationIsDragOverMass) {
  const AircraftParams p = trainer();
  const double y0 = 2000, v = 120, a = 2 * kRad;
  const double rho = 1.225 * std::exp(-y0 / 8500);
  const double m = p.mass + p.fuelCapacity;
  const double cl = p.cl0 + p.clAlpha * a;
  const double drag = 0.5 * rho * v * v * p.wingArea * (p.cd0 + p.inducedDrag * cl * cl);
  AirState s = levelAt(p, y0, a, v, 0);
  const AirControls idle{0, 0, 0, 0};
  stepAircraft(p, idle, s, kDt);
  // Lift and gravity are perpendicular to the horizontal velocity; only
  // drag acts along it.
  const double along = -s.velocity.z();
  EXPECT_NEAR((along - v) / kDt, -drag / m, 1e-9 * drag / m);
  EXPECT_NEAR(s.velocity.x(), 0, 1e-12);
  // Energy per kilogram falls every step while gliding.
  double energy = 0.5 * s.velocity.squaredNorm() + 9.80665 * s.position.y();
  for (int k = 0; k < 600; ++k) {
    stepAircraft(p, idle, s, kDt);
    const double e = 0.5 * s.velocity.squaredNorm() + 9.80665 * s.position.y();
    ASSERT_LT(e, energy) << "step " << k;
    energy = e;
  }
  EXPECT_LT(s.velocity.norm(), v);
}

TEST(AircraftFlight, ForcesByHandBelowAndPastTheStall) {
  const AircraftParams p = trainer();
  const double v = 100, m = p.mass + p.fuelCapacity, g = 9.80665, qbar = 0.5 * 1.225 * v * v;
  // Level, heading north, alpha 5 deg (linear lift) and 25 deg (past
  // cl_max: lift stops growing). Velocity is horizontal, so lift is
  // straight up and drag straight back (+z).
  for (double alphaDeg : {5.0, 25.0}) {
    const double cl = std::min(p.cl0 + p.clAlpha * alphaDeg * kRad, p.clMax);
    if (alphaDeg > 20) {
      EXPECT_EQ(cl, p.clMax);
    }
    const double cd = p.cd0 + p.inducedDrag * cl * cl;
    AirState s = levelAt(p, 0, alphaDeg * kRad, v, 0);
    stepAircraft(p, AirControls{}, s, kDt);
    const Eigen::Vector3d accel = (s.velocity - Eigen::Vector3d(0, 0, -v)) / kDt;
    EXPECT_NEAR(accel.y(), qbar * p.wingArea * cl / m - g, 1e-9) << alphaDeg;
    EXPECT_NEAR(accel.z(), qbar * p.wingArea * cd / m, 1e-9) << alphaDeg;
    EXPECT_NEAR(accel.x(), 0, 1e-12);
  }
  // Sideslip beta, nose north and level, velocity beta to the right: lift
  // (at alpha 0, CL = cl0) is up; the side force, -qbar S side_force beta,
  // acts along the horizontal normal to the velocity, (cos b, 0, sin b);
  // drag along -velocity.
  const double beta = 6 * kRad;
  AirState s = levelAt(p, 0, 0, v, 0);
  s.velocity = v * Eigen::Vector3d(std::sin(beta), 0, -std::cos(beta));
  const Eigen::Vector3d v0 = s.velocity;
  stepAircraft(p, AirControls{}, s, kDt);
  const double cd = p.cd0 + p.inducedDrag * p.cl0 * p.cl0;
  const Eigen::Vector3d expected = qbar * p.wingArea / m *
                                       (p.cl0 * Eigen::Vector3d(0, 1, 0) - cd * v0 / v -
                                        p.sideForce * beta * Eigen::Vector3d(std::cos(beta), 0, std::sin(beta))) -
                                   Eigen::Vector3d(0, g, 0);
  EXPECT_LT(((s.velocity - v0) / kDt - expected).norm(), 1e-9);
}

TEST(AircraftFlight, AngularAccelerationsByHand) {
  const AircraftParams p = trainer();
  // Nose north, pitched 7 deg, velocity horizontal and 3 deg to the right
  // of north. Alpha and beta from the body-axis velocity, with the body
  // axes built by hand (heading 0, pitch 7, roll 0).
  const double pitch = 7 * kRad, b = 3 * kRad, v = 90;
  AirState s = levelAt(p, 500, pitch, v, 0.5);
  s.velocity = v * Eigen::Vector3d(std::sin(b), 0, -std::cos(b));
  s.angularVelocity = Eigen::Vector3d(0.2, -0.1, 0.05);
  const Axes ax = axesByHand(0, 7, 0);
  const double u = s.velocity.dot(ax.forward), w = s.velocity.dot(ax.up), side = s.velocity.dot(ax.right);
  const double alpha = std::atan2(-w, u), beta = std::asin(side / v);
  // u = v cos b cos 7, w = -v cos b sin 7: alpha is the pitch exactly.
  EXPECT_NEAR(alpha, pitch, 1e-12);
  const double ratio = 0.5 * 1.225 * std::exp(-500.0 / 8500) * v * v / p.referencePressure;
  const AirControls c{0.5, 0.5, -0.3, 0.2};
  const double roll = ratio * p.aileronPower * -0.3 * p.aileronLimitDeg * kRad;
  const double pitchAcc = ratio * (p.elevatorPower * 0.5 * p.elevatorLimitDeg * kRad -
                                   p.pitchStability * (alpha - p.alphaTrimDeg * kRad));
  const double yaw = ratio * (p.rudderPower * 0.2 * p.rudderLimitDeg * kRad + p.yawStability * beta);
  stepAircraft(p, c, s, kDt);
  EXPECT_NEAR(s.angularVelocity.x(), (0.2 + roll * kDt) / (1 + p.rollDamping * kDt), 1e-12);
  EXPECT_NEAR(s.angularVelocity.y(), (-0.1 + pitchAcc * kDt) / (1 + p.pitchDamping * kDt), 1e-12);
  EXPECT_NEAR(s.angularVelocity.z(), (0.05 + yaw * kDt) / (1 + p.yawDamping * kDt), 1e-12);
  // The orientation turned by the new rates, in body axes: roll right
  // about forward, pitch up about right, yaw right about down.
  const Eigen::Vector3d rates = s.angularVelocity;
  const Eigen::Vector3d axis = rates.x() * ax.forward + rates.y() * ax.right - rates.z() * ax.up;
  const Eigen::Quaterniond expected =
      Eigen::Quaterniond(Eigen::AngleAxisd(axis.norm() * kDt, axis.normalized())) * orientationFromEuler(0, 7, 0);
  EXPECT_LT(expected.angularDistance(s.orientation), 1e-12);
}

TEST(AircraftFlight, NoFuelNoThrust) {
  const AircraftParams p = trainer();
  const double y0 = 0, v = 100, a = 3 * kRad;
  const double cl = p.cl0 + p.clAlpha * a;
  const double drag = 0.5 * 1.225 * v * v * p.wingArea * (p.cd0 + p.inducedDrag * cl * cl);
  AirState s = levelAt(p, y0, a, v, 1.0);
  s.fuelKg = 0;
  stepAircraft(p, AirControls{1, 0, 0, 0}, s, kDt);
  EXPECT_NEAR((-s.velocity.z() - v) / kDt, -drag / p.mass, 1e-9 * drag / p.mass);
  EXPECT_LT(s.throttle, 1.0);  // a dry engine winds down
  EXPECT_EQ(s.fuelKg, 0.0);
  // With fuel the same step accelerates: thrust 16900 N beats the drag.
  AirState f = levelAt(p, y0, a, v, 1.0);
  stepAircraft(p, AirControls{1, 0, 0, 0}, f, kDt);
  const double mf = p.mass + p.fuelCapacity;
  EXPECT_NEAR((-f.velocity.z() - v) / kDt, (p.maxThrust * std::cos(a) - drag) / mf, 1e-9 * p.maxThrust / mf);
}

TEST(AircraftFlight, EngineSpoolsAndBurnsInClosedForm) {
  const AircraftParams p = trainer();
  AirState s = levelAt(p, 3000, 4 * kRad, 100, 0);
  const double fuel0 = s.fuelKg;
  const int n = 120;  // = spool_time 2 s at 60 Hz
  for (int k = 0; k < n; ++k) stepAircraft(p, AirControls{1, 0, 0, 0}, s, kDt);
  EXPECT_NEAR(s.throttle, 1 - std::exp(-1.0), 1e-12);
  // Burn sums throttle_k * burn * dt with throttle_k = 1 - r^k.
  const double r = std::exp(-kDt / p.spoolTime);
  const double burned = p.fuelBurn * kDt * (n - (1 - std::pow(r, n)) / (1 - r));
  EXPECT_NEAR(fuel0 - s.fuelKg, burned, 1e-9);
  // Command out of range or NaN is clamped or ignored.
  AirState t = s;
  stepAircraft(p, AirControls{std::nan(""), std::nan(""), 7, -7}, t, kDt);
  EXPECT_TRUE(std::isfinite(t.throttle));
  EXPECT_LT(t.throttle, s.throttle);  // NaN throttle counts as idle
}

TEST(AircraftFlight, RollRateFollowsPowerAndDamping) {
  const AircraftParams p = trainer();
  // At the speed where qbar is the reference pressure, full aileron
  // settles at p = power * limit / damping.
  const double v = std::sqrt(2 * p.referencePressure / 1.225);
  AirState s = levelAt(p, 0, 4 * kRad, v, 0.3);
  const AirControls right{0.3, 0, 1, 0};
  const double authority = p.aileronPower * p.aileronLimitDeg * kRad;
  // The documented update, by hand: p' = (p + authority qbar/qref dt) /
  // (1 + damping dt), qbar from the state before the step.
  double rate = 0;
  for (int k = 0; k < 120; ++k) {  // 2 s
    const double qbar = 0.5 * 1.225 * std::exp(-s.position.y() / 8500) * s.velocity.squaredNorm();
    rate = (rate + authority * qbar / p.referencePressure * kDt) / (1 + p.rollDamping * kDt);
    stepAircraft(p, right, s, kDt);
    ASSERT_NEAR(s.angularVelocity.x(), rate, 1e-12) << "step " << k;
    if (k == 17) {  // 0.3 s: the right wing went down
      EXPECT_GT(eulerFromOrientation(s.orientation).rollDeg, 5.0);
      EXPECT_LT(rightOf(s.orientation).y(), -0.05);
    }
  }
  // Near the steady state (the plane gains a little speed as it rolls).
  const double steady = authority / p.rollDamping;
  EXPECT_NEAR(s.angularVelocity.x(), steady, 0.05 * steady);
  // Aileron couples into nothing else while sideslip and alpha stay put.
  EXPECT_LT(std::abs(s.angularVelocity.z()), 0.05);
}

TEST(AircraftFlight, LoopThroughTheVerticalIsContinuous) {
  const AircraftParams p = trainer();
  AirState s = levelAt(p, 3000, 2 * kRad, 160, 1.0);
  const AirControls pull{1, 0.6, 0, 0};
  double loopAngle = 0, maxPitch = -90, minPitch = 90;
  int flipsUp = 0;
  Eigen::Vector3d prevForward = forwardOf(s.orientation);
  double prevHeading = eulerFromOrientation(s.orientation).headingDeg;
  Eigen::Quaterniond prevQ = s.orientation;
  int k = 0;
  for (; k < 60 * 60 && loopAngle < 2 * kPi; ++k) {
    stepAircraft(p, pull, s, kDt);
    ASSERT_TRUE(s.position.allFinite() && s.velocity.allFinite());
    ASSERT_NEAR(s.orientation.norm(), 1.0, 1e-12) << "step " << k;
    // The quaternion itself is continuous too (no sign flip, no jump).
    ASSERT_GT(prevQ.dot(s.orientation), std::cos(bodyRateVector(s).norm() * kDt / 2) - 1e-12) << "step " << k;
    prevQ = s.orientation;
    const Eigen::Vector3d f = forwardOf(s.orientation), up = upOf(s.orientation);
    // The nose moves no further than the body rates allow.
    const double step = std::atan2(prevForward.cross(f).norm(), prevForward.dot(f));
    ASSERT_LE(step, bodyRateVector(s).norm() * kDt + 1e-12) << "step " << k;
    // It stays in the north-south vertical plane and always turns nose up
    // (about the right wing, +x).
    ASSERT_LT(std::abs(f.x()), 1e-9);
    const double turn = prevForward.cross(f).x();
    ASSERT_GT(turn, 0.0) << "step " << k;
    loopAngle += step;
    // Euler angles: heading 0 and roll 0 while the nose points north of
    // the vertical, heading 180 and roll 180 (inverted) while it points
    // south; the flip happens only where the nose crosses the vertical.
    const Euler e = eulerFromOrientation(s.orientation);
    maxPitch = std::max(maxPitch, e.pitchDeg);
    minPitch = std::min(minPitch, e.pitchDeg);
    if (f.z() < -1e-6) {
      ASSERT_LT(std::abs(wrap180(e.headingDeg)), 1e-6) << "step " << k;
      ASSERT_LT(std::abs(e.rollDeg), 1e-6) << "step " << k;
      ASSERT_GT(up.y(), 0.0);
    } else if (f.z() > 1e-6) {
      ASSERT_LT(std::abs(wrap180(e.headingDeg - 180)), 1e-6) << "step " << k;
      ASSERT_GT(std::abs(e.rollDeg), 180 - 1e-6) << "step " << k;
      ASSERT_LT(up.y(), 0.0);
    }
    if (std::abs(wrap180(e.headingDeg - prevHeading)) > 1.0) {
      ASSERT_GT(std::abs(f.y()), 0.99) << "heading jumped away from the vertical at step " << k;
      if (f.y() > 0) ++flipsUp;
    }
    prevForward = f;
    prevHeading = e.headingDeg;
  }
  EXPECT_GE(loopAngle, 2 * kPi) << "the loop did not close in 60 s";
  EXPECT_GT(maxPitch, 89.0);
  EXPECT_LT(minPitch, -89.0);
  EXPECT_EQ(flipsUp, 1);
  // Back where it started: nose north, upright.
  EXPECT_LT(std::abs(wrap180(eulerFromOrientation(s.orientation).headingDeg)), 1e-6);
}

TEST(AircraftFlight, VerticalClimbFlipsHeadingOnlyAsPhysics) {
  const AircraftParams p = trainer();
  AirState s;
  s.position = Eigen::Vector3d(0, 1000, 0);
  s.orientation = orientationFromEuler(37, 90, 0);
  s.velocity = Eigen::Vector3d(0, 150, 0);
  s.throttle = 1;
  s.fuelKg = 100;
  // Straight up at alpha 0, below alpha_trim: the weathercock lifts the
  // nose over the back, toward heading 37 + 180.
  for (int k = 0; k < 60; ++k) {
    stepAircraft(p, AirControls{1, 0, 0, 0}, s, kDt);
    ASSERT_TRUE(s.orientation.coeffs().allFinite());
  }
  const Eigen::Vector3d f = forwardOf(s.orientation);
  EXPECT_GT(f.y(), 0.9);
  const double horizontalHeading = std::atan2(f.x(), -f.z()) / kRad;
  EXPECT_NEAR(wrap180(horizontalHeading - 217), 0, 1e-6);
  const Euler e = eulerFromOrientation(s.orientation);
  EXPECT_NEAR(e.headingDeg, 217, 1e-6);
  EXPECT_NEAR(std::abs(e.rollDeg), 180, 1e-6);
  EXPECT_LT(e.pitchDeg, 90);
}

TEST(AircraftFlight, Deterministic) {
  const AircraftParams p = trainer();
  const auto run = [&] {
    AirState s = levelFlight(p, Eigen::Vector3d(10, 1500, -20), 45, 110);
    for (int k = 0; k < 600; ++k) {
      AirControls c = holdAttitude(p, s, 90, 1600, 120);
      c.rudder += 0.1 * std::sin(k * 0.05);
      stepAircraft(p, c, s, kDt);
    }
    return s;
  };
  const AirState a = run(), b = run();
  EXPECT_EQ(std::memcmp(a.position.data(), b.position.data(), sizeof(double) * 3), 0);
  EXPECT_EQ(std::memcmp(a.velocity.data(), b.velocity.data(), sizeof(double) * 3), 0);
  EXPECT_EQ(std::memcmp(a.orientation.coeffs().data(), b.orientation.coeffs().data(), sizeof(double) * 4), 0);
  EXPECT_EQ(a.fuelKg, b.fuelKg);
}

TEST(AircraftFlight, LevelFlightStartsBalanced) {
  const AircraftParams p = trainer();
  const AirState s = levelFlight(p, Eigen::Vector3d(0, 500, 0), 90, 110);
  EXPECT_LT((s.velocity - Eigen::Vector3d(110, 0, 0)).norm(), 1e-12);
  const double rho = 1.225 * std::exp(-500.0 / 8500);
  const double qbar = 0.5 * rho * 110 * 110;
  const double cl = (p.mass + p.fuelCapacity) * 9.80665 / (qbar * p.wingArea);
  const Euler e = eulerFromOrientation(s.orientation);
  EXPECT_NEAR(e.pitchDeg, (cl - p.cl0) / p.clAlpha / kRad, 1e-9);
  EXPECT_NEAR(e.headingDeg, 90, 1e-9);
  EXPECT_NEAR(s.throttle, qbar * p.wingArea * (p.cd0 + p.inducedDrag * cl * cl) / (p.maxThrust * rho / 1.225), 1e-12);
  EXPECT_EQ(s.fuelKg, p.fuelCapacity);
}

// ---------------------------------------------------------------------------
// Autopilot

struct Recovery {
  double rollDeg, headingErrDeg, altitudeErrM, speed;
};

Recovery recover(const AircraftParams& p, double bankDeg, double startHeading, double targetHeading, double speed) {
  const double alt = 2000;
  AirState s = levelFlight(p, Eigen::Vector3d(0, alt, 0), startHeading, speed);
  const Euler e = eulerFromOrientation(s.orientation);
  s.orientation = orientationFromEuler(startHeading, e.pitchDeg, bankDeg);
  for (int k = 0; k < 60 * 60; ++k) {
    stepAircraft(p, holdAttitude(p, s, targetHeading, alt, speed), s, kDt);
  }
  const Euler f = eulerFromOrientation(s.orientation);
  return {f.rollDeg, wrap180(f.headingDeg - targetHeading), s.position.y() - alt, s.velocity.norm()};
}

TEST(AircraftAutopilot, RecoversFromBankAndHeadingError) {
  const AircraftParams t = trainer();
  const auto f = readAircraftFile(samplePath("fighter.txt"));
  ASSERT_TRUE(f.ok());
  struct Case {
    const AircraftParams* p;
    double bank, start, target, speed;
  };
  const Case cases[] = {
      {&t, 60, 20, 0, 100}, {&t, -60, 20, 0, 100}, {&t, 60, 340, 0, 100}, {&t, -60, 340, 0, 100},
      {&t, 60, 200, 180, 140}, {&f.value(), 60, 20, 0, 150}, {&f.value(), -60, 110, 90, 180},
  };
  for (const Case& c : cases) {
    const Recovery r = recover(*c.p, c.bank, c.start, c.target, c.speed);
    const std::string where = c.p->name + " bank " + std::to_string(c.bank) + " from " + std::to_string(c.start);
    EXPECT_LT(std::abs(r.rollDeg), 5.0) << where;
    EXPECT_LT(std::abs(r.headingErrDeg), 5.0) << where;
    EXPECT_LT(std::abs(r.altitudeErrM), 50.0) << where;
    EXPECT_NEAR(r.speed, c.speed, 5.0) << where;
  }
}

TEST(AircraftAutopilot, ClimbsAndTurnsToNewTargets) {
  const AircraftParams p = trainer();
  AirState s = levelFlight(p, Eigen::Vector3d(0, 1000, 0), 0, 100);
  for (int k = 0; k < 120 * 60; ++k) stepAircraft(p, holdAttitude(p, s, 135, 1300, 110), s, kDt);
  const Euler e = eulerFromOrientation(s.orientation);
  EXPECT_NEAR(e.headingDeg, 135, 2.0);
  EXPECT_NEAR(s.position.y(), 1300, 10.0);
  EXPECT_NEAR(s.velocity.norm(), 110, 2.0);
  EXPECT_LT(std::abs(e.rollDeg), 2.0);
}

}  // namespace
}  // namespace sandtable::sim
