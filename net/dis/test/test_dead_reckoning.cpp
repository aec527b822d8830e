// Dead reckoning (dead_reckoning.h): hand values, every algorithm against a
// numerical integration of its equations of motion written here apart
// (RK4, 4,000 steps), with large, small and zero turn rates, and the
// half-step check (two steps of dt/2 are one step of dt).
#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "sandtable/dis/dead_reckoning.h"

namespace sandtable::dis {
namespace {

Motion start(std::uint8_t algorithm, Vec3d omega) {
  Motion m;
  m.algorithm = algorithm;
  m.position = {4000000.0, 600000.0, 4900000.0};
  m.orientation = rotationMatrix(0.3, -0.7, 1.1);
  m.velocity = {12.0, -3.0, 2.5};
  m.acceleration = {0.5, 1.5, -0.8};
  m.angularVelocity = omega;
  return m;
}

// --- the reference: the equations of motion, integrated numerically ---

struct State {
  std::array<double, 3> p, v;
  std::array<double, 9> r;  // row-major, body to world
};

State derivative(const State& s, const Motion& m) {
  const std::uint8_t a = m.algorithm;
  const bool rotating = a == 3 || a == 4 || a == 7 || a == 8;
  const bool accelerating = a == 4 || a == 5 || a == 8 || a == 9;
  const bool body = a >= 6;
  State d{};
  const auto& w = m.angularVelocity;
  if (rotating) {  // dR/dt = R [w]x
    const double o[9] = {0, -w.z, w.y, w.z, 0, -w.x, -w.y, w.x, 0};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) d.r[3 * i + j] = s.r[3 * i] * o[j] + s.r[3 * i + 1] * o[3 + j] + s.r[3 * i + 2] * o[6 + j];
    }
  }
  if (accelerating) d.v = {m.acceleration.x, m.acceleration.y, m.acceleration.z};
  for (int i = 0; i < 3; ++i) {
    d.p[i] = body ? s.r[3 * i] * s.v[0] + s.r[3 * i + 1] * s.v[1] + s.r[3 * i + 2] * s.v[2] : s.v[i];
  }
  return d;
}

State axpy(const State& s, const State& d, double h) {
  State o = s;
  for (int i = 0; i < 3; ++i) o.p[i] += h * d.p[i], o.v[i] += h * d.v[i];
  for (int i = 0; i < 9; ++i) o.r[i] += h * d.r[i];
  return o;
}

/// The displacement from m.position (integrated from 0, so that the
/// reference's own rounding stays far under the tolerance), the velocity
/// and the orientation after dt.
State integrate(const Motion& m, double dt) {
  State s{{0, 0, 0}, {m.velocity.x, m.velocity.y, m.velocity.z}, {}};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) s.r[3 * i + j] = m.orientation[i][j];
  }
  if (m.algorithm < 2 || m.algorithm > 9) return s;
  const int n = 4000;
  const double h = dt / n;
  for (int k = 0; k < n; ++k) {
    const State k1 = derivative(s, m), k2 = derivative(axpy(s, k1, h / 2), m);
    const State k3 = derivative(axpy(s, k2, h / 2), m), k4 = derivative(axpy(s, k3, h), m);
    for (int i = 0; i < 3; ++i) {
      s.p[i] += h / 6 * (k1.p[i] + 2 * k2.p[i] + 2 * k3.p[i] + k4.p[i]);
      s.v[i] += h / 6 * (k1.v[i] + 2 * k2.v[i] + 2 * k3.v[i] + k4.v[i]);
    }
    for (int i = 0; i < 9; ++i) s.r[i] += h / 6 * (k1.r[i] + 2 * k2.r[i] + 2 * k3.r[i] + k4.r[i]);
  }
  return s;
}

void expectNear(const Motion& got, const Motion& want, double metres, double unit, const std::string& what) {
  EXPECT_NEAR(got.position.x, want.position.x, metres) << what;
  EXPECT_NEAR(got.position.y, want.position.y, metres) << what;
  EXPECT_NEAR(got.position.z, want.position.z, metres) << what;
  EXPECT_NEAR(got.velocity.x, want.velocity.x, unit) << what;
  EXPECT_NEAR(got.velocity.y, want.velocity.y, unit) << what;
  EXPECT_NEAR(got.velocity.z, want.velocity.z, unit) << what;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(got.orientation[i][j], want.orientation[i][j], unit) << what;
  }
}

TEST(DisDeadReckoning, handValues) {
  Motion m = start(2, {});  // FPW: P + V dt
  Motion a = advance(m, 2.0);
  EXPECT_DOUBLE_EQ(a.position.x, 4000024.0);
  EXPECT_DOUBLE_EQ(a.position.y, 599994.0);
  EXPECT_DOUBLE_EQ(a.position.z, 4900005.0);
  EXPECT_EQ(a.orientation, m.orientation);
  m.algorithm = 5;  // FVW: + A dt^2 / 2
  a = advance(m, 2.0);
  EXPECT_DOUBLE_EQ(a.position.x, 4000025.0);
  EXPECT_DOUBLE_EQ(a.position.z, 4900003.4);
  EXPECT_DOUBLE_EQ(a.velocity.y, 0.0);
  m.algorithm = 1;  // Static
  a = advance(m, 100.0);
  EXPECT_EQ(a.position.x, m.position.x);
  EXPECT_EQ(a.orientation, m.orientation);
  // RPB from the identity, turning left... about body z at w = 0.5 rad/s with 10 m/s forward:
  // a circle, (v/w sin x, v/w (1 - cos x), 0) after x = w dt, and a yaw of x.
  Motion c;
  c.algorithm = 7;
  c.orientation = rotationMatrix(0, 0, 0);
  c.velocity = {10, 0, 0};
  c.angularVelocity = {0, 0, 0.5};
  a = advance(c, 2.0);
  EXPECT_NEAR(a.position.x, 20 * std::sin(1.0), 1e-12);
  EXPECT_NEAR(a.position.y, 20 * (1 - std::cos(1.0)), 1e-12);
  EXPECT_NEAR(a.position.z, 0, 1e-12);
  EXPECT_NEAR(rotationAngles(a.orientation)[0], 1.0, 1e-12);
}

TEST(DisDeadReckoning, everyAlgorithmFollowsItsEquationsOfMotion) {
  for (std::uint8_t alg = 1; alg <= 9; ++alg) {
    for (const Vec3d w : {Vec3d{0.3, -0.2, 0.5}, Vec3d{0, 0, 2.0}, Vec3d{1e-9, 0, -2e-9}, Vec3d{0, 0, 0}}) {
      for (double dt : {0.05, 1.0, 3.0}) {
        const Motion m = start(alg, w);
        const Motion got = advance(m, dt);
        const State ref = integrate(m, dt);
        Motion want = got;
        want.position = {m.position.x + ref.p[0], m.position.y + ref.p[1], m.position.z + ref.p[2]};
        want.velocity = {ref.v[0], ref.v[1], ref.v[2]};
        for (int i = 0; i < 3; ++i) {
          for (int j = 0; j < 3; ++j) want.orientation[i][j] = ref.r[3 * i + j];
        }
        expectNear(got, want, 1e-6, 1e-9,
                   "algorithm " + std::to_string(alg) + " w " + std::to_string(w.x) + "," + std::to_string(w.z) + " dt " +
                       std::to_string(dt));
      }
    }
  }
}

TEST(DisDeadReckoning, twoHalfStepsAreOneStep) {
  for (std::uint8_t alg = 1; alg <= 9; ++alg) {
    for (const Vec3d w : {Vec3d{0.3, -0.2, 0.5}, Vec3d{4e-4, 0, 0}, Vec3d{0, 0, 0}}) {
      const Motion m = start(alg, w);
      for (double dt : {0.002, 0.5, 5.0, -1.0}) {
        expectNear(advance(advance(m, dt / 2), dt / 2), advance(m, dt), 1e-7, 1e-12,
                   "algorithm " + std::to_string(alg) + " dt " + std::to_string(dt));
      }
    }
  }
}

TEST(DisDeadReckoning, aPduGivesItsMotion) {
  EntityState s;
  s.location = {1, 2, 3};
  s.orientation = {0.5f, -0.25f, 1.0f};
  s.velocity = {4, 5, 6};
  s.deadReckoning.algorithm = 8;
  s.deadReckoning.acceleration = {0.5f, 0, 0};
  s.deadReckoning.angularVelocity = {0, 0.125f, 0};
  const Motion m = motionOf(s);
  EXPECT_EQ(m.algorithm, 8);
  EXPECT_EQ(m.position.z, 3.0);
  EXPECT_EQ(m.velocity.y, 5.0);
  EXPECT_EQ(m.acceleration.x, 0.5);
  EXPECT_EQ(m.angularVelocity.y, 0.125);
  const auto back = rotationAngles(m.orientation);
  EXPECT_NEAR(back[0], 0.5, 1e-6);
  EXPECT_NEAR(back[1], -0.25, 1e-6);
  EXPECT_NEAR(back[2], 1.0, 1e-6);
}

}  // namespace
}  // namespace sandtable::dis
