// Dead reckoning in closed form (dead_reckoning.h). With Ω the skew matrix
// of the body rates ω, w = |ω| and x = w Δt:
//   exp(Ω Δt)           = I + s1 Ω + s2 Ω²          (Rodrigues)
//   R1 = ∫ exp(Ω t) dt   = Δt I + c1 Ω + c2 Ω²
//   R2 = ∫ t exp(Ω t) dt = Δt²/2 I + d1 Ω + d2 Ω²
// s1 = sin x / w, s2 = c1 = (1 - cos x) / w², c2 = (x - sin x) / w³,
// d1 = (sin x - x cos x) / w³, d2 = (x²/2 + 1 - cos x - x sin x) / w⁴;
// written with Ω² = ωωᵀ - w² I these are Annex E's R1 and R2. Below
// x = 1e-3 each coefficient is its Taylor series (error under x⁶).
#include "sandtable/dis/dead_reckoning.h"

#include <cmath>

namespace sandtable::dis {

namespace {

enum Algorithm : std::uint8_t { kStatic = 1, kFPW, kRPW, kRVW, kFVW, kFPB, kRPB, kRVB, kFVB };

Vec3d apply(const Matrix3& m, const Vec3d& v) {
  return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
          m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
}
Vec3d add(const Vec3d& a, const Vec3d& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3d scale(const Vec3d& a, double s) { return {a.x * s, a.y * s, a.z * s}; }

/// a I + b Ω + c Ω² for the skew matrix Ω of ω.
Matrix3 series(double a, double b, double c, const Vec3d& w) {
  const Matrix3 o{{{0, -w.z, w.y}, {w.z, 0, -w.x}, {-w.y, w.x, 0}}};
  const Matrix3 o2 = multiply(o, o);
  Matrix3 m{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) m[i][j] = (i == j ? a : 0.0) + b * o[i][j] + c * o2[i][j];
  }
  return m;
}

struct Coefficients {
  double s1, s2, c1, c2, d1, d2;
};

Coefficients coefficients(const Vec3d& omega, double dt) {
  const double w = std::sqrt(omega.x * omega.x + omega.y * omega.y + omega.z * omega.z);
  const double x = w * dt, x2 = x * x, x4 = x2 * x2;
  if (std::abs(x) < 1e-3) {
    const double t2 = dt * dt, t3 = t2 * dt, t4 = t3 * dt;
    const double half = t2 * (0.5 - x2 / 24 + x4 / 720);
    return {dt * (1 - x2 / 6 + x4 / 120), half, half, t3 * (1.0 / 6 - x2 / 120 + x4 / 5040),
            t3 * (1.0 / 3 - x2 / 30 + x4 / 840), t4 * (0.125 - x2 / 144 + x4 / 5760)};
  }
  const double s = std::sin(x), c = std::cos(x), w2 = w * w, w3 = w2 * w;
  return {s / w, (1 - c) / w2, (1 - c) / w2, (x - s) / w3, (s - x * c) / w3, (x2 / 2 + 1 - c - x * s) / (w2 * w2)};
}

bool rotates(std::uint8_t a) { return a == kRPW || a == kRVW || a == kRPB || a == kRVB; }
bool accelerates(std::uint8_t a) { return a == kRVW || a == kFVW || a == kRVB || a == kFVB; }
bool bodyAxes(std::uint8_t a) { return a >= kFPB && a <= kFVB; }

}  // namespace

Motion motionOf(const EntityState& s) {
  Motion m;
  m.algorithm = s.deadReckoning.algorithm;
  m.position = s.location;
  m.orientation = rotationMatrix(s.orientation.psi, s.orientation.theta, s.orientation.phi);
  m.velocity = {s.velocity.x, s.velocity.y, s.velocity.z};
  const Vec3f& a = s.deadReckoning.acceleration;
  const Vec3f& w = s.deadReckoning.angularVelocity;
  m.acceleration = {a.x, a.y, a.z};
  m.angularVelocity = {w.x, w.y, w.z};
  return m;
}

Motion advance(const Motion& m, double dt) {
  const std::uint8_t a = m.algorithm;
  if (a < kFPW || a > kFVB) return m;  // Static, and numbers the standard does not define
  Motion out = m;
  const Vec3d acc = accelerates(a) ? m.acceleration : Vec3d{};
  // The body's turn over dt: what the orientation does for R*, and what the
  // body-axis velocity is carried through for 6-9 (F*B: no turn).
  const Vec3d w = rotates(a) ? m.angularVelocity : Vec3d{};
  const Coefficients k = coefficients(w, dt);
  if (bodyAxes(a)) {
    const Vec3d moved = add(apply(series(dt, k.c1, k.c2, w), m.velocity),
                            apply(series(dt * dt / 2, k.d1, k.d2, w), acc));
    out.position = add(m.position, apply(m.orientation, moved));
  } else {
    out.position = add(m.position, add(scale(m.velocity, dt), scale(acc, dt * dt / 2)));
  }
  out.velocity = add(m.velocity, scale(acc, dt));  // world or body axes, as given
  if (rotates(a)) out.orientation = multiply(m.orientation, series(1, k.s1, k.s2, w));
  return out;
}

}  // namespace sandtable::dis
