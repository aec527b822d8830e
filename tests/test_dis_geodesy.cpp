// DIS coordinates against the database frame (docs/DIS.md §5): a 100 km
// UTM database's corners and centre, at two heights, go to geocentric
// positions and back within 1 cm, and local attitudes (pitch +-90 degrees
// included) to DIS Euler angles and back as the same rotation within
// 0.01 degree, with the frame's axes from geodesy::DatabaseFrame::localAxes.
// Independent checks: a heading of 90 degrees points along the frame's X as
// PROJ maps it, a pitch of 90 degrees along PROJ's vertical, and grid north
// is off true north by the UTM convergence.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sandtable/dis/orientation.h"
#include "sandtable/geodesy/geodesy.h"

namespace sandtable {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

dis::LocalAxes toDis(const geodesy::DatabaseFrame::LocalAxes& a) {
  return {{a.north.x, a.north.y, a.north.z}, {a.east.x, a.east.y, a.east.z}, {a.down.x, a.down.y, a.down.z}};
}

dis::Vec3d forward(const dis::LocalAxes& l, const dis::Attitude& a) {
  const double n = std::cos(a.pitch) * std::cos(a.heading), e = std::cos(a.pitch) * std::sin(a.heading),
               d = -std::sin(a.pitch);
  return {n * l.north.x + e * l.east.x + d * l.down.x, n * l.north.y + e * l.east.y + d * l.down.y,
          n * l.north.z + e * l.east.z + d * l.down.z};
}

dis::Vec3d unit(double x, double y, double z) {
  const double s = std::sqrt(x * x + y * y + z * z);
  return {x / s, y / s, z / s};
}

double angleDeg(const dis::Vec3d& a, const dis::Vec3d& b) {
  const double d = (a.x * b.x + a.y * b.y + a.z * b.z) /
                   std::sqrt((a.x * a.x + a.y * a.y + a.z * a.z) * (b.x * b.x + b.y * b.y + b.z * b.z));
  return std::acos(std::clamp(d, -1.0, 1.0)) / kDeg;
}

// UTM 33N, a 100 km square whose north-west corner is at E 300 km, N 5,600 km (about 12.2 E, 50.5 N).
geodesy::DatabaseFrame frame() {
  auto f = geodesy::DatabaseFrame::create("EPSG:32633", 300000.0, 5600000.0);
  EXPECT_TRUE(f.ok()) << f.error();
  return f.value();
}

const geodesy::FramePoint kPoints[] = {{0, 0, 0},           {100000, 0, 0},     {0, 0, 100000},   {100000, 0, 100000},
                                       {50000, 0, 50000},   {0, 3000, 0},       {100000, 3000, 100000}};

TEST(DisGeodesy, framePointsGoToGeocentricAndBackWithinACentimetre) {
  const auto f = frame();
  for (const auto& p : kPoints) {
    auto e = f.toEcef(p);
    ASSERT_TRUE(e.ok()) << e.error();
    // As a DIS location travels: three doubles.
    dis::EntityState s;
    s.location = {e->x, e->y, e->z};
    auto back = f.fromEcef({s.location.x, s.location.y, s.location.z});
    ASSERT_TRUE(back.ok()) << back.error();
    EXPECT_NEAR(back->x, p.x, 0.01);
    EXPECT_NEAR(back->y, p.y, 0.01);
    EXPECT_NEAR(back->z, p.z, 0.01);
  }
}

TEST(DisGeodesy, attitudesGoToEulerAnglesAndBackAtTheCorners) {
  const auto f = frame();
  for (const auto& p : kPoints) {
    auto axes = f.localAxes(p);
    ASSERT_TRUE(axes.ok()) << axes.error();
    const dis::LocalAxes l = toDis(axes.value());
    for (double pitch : {-90.0, -30.0, 0.0, 12.5, 90.0}) {
      for (double heading : {0.0, 45.0, 180.0, 300.0}) {
        for (double roll : {-60.0, 0.0, 170.0}) {
          const dis::Attitude a{heading * kDeg, pitch * kDeg, roll * kDeg};
          const dis::Attitude back = dis::toAttitude(l, dis::toEuler(l, a));
          EXPECT_LT(angleDeg(forward(l, a), forward(l, back)), 0.01) << heading << " " << pitch << " " << roll;
          if (std::abs(pitch) < 89) {
            EXPECT_NEAR(std::remainder(back.heading / kDeg - heading, 360.0), 0, 0.01);
            EXPECT_NEAR(back.pitch / kDeg, pitch, 0.01);
            EXPECT_NEAR(std::remainder(back.roll / kDeg - roll, 360.0), 0, 0.01);
          }
        }
      }
    }
  }
}

TEST(DisGeodesy, theAxesAgreeWithProjsFrameAndTheConvergence) {
  const auto f = frame();
  for (const auto& p : kPoints) {
    auto axes = f.localAxes(p);
    ASSERT_TRUE(axes.ok()) << axes.error();
    const dis::LocalAxes l = toDis(axes.value());
    // Heading 90: along the frame's +X as PROJ maps 1 m each way (UTM is conformal).
    auto east = f.toEcef({p.x + 1, p.y, p.z});
    auto west = f.toEcef({p.x - 1, p.y, p.z});
    ASSERT_TRUE(east.ok() && west.ok());
    const dis::Vec3d x = unit(east->x - west->x, east->y - west->y, east->z - west->z);
    EXPECT_LT(angleDeg(forward(l, {90 * kDeg, 0, 0}), x), 0.01);
    // Pitch 90: up, as PROJ maps 1 m of height.
    auto up = f.toEcef({p.x, p.y + 1, p.z});
    auto here = f.toEcef(p);
    ASSERT_TRUE(up.ok() && here.ok());
    EXPECT_LT(angleDeg(forward(l, {0, 90 * kDeg, 0}), unit(up->x - here->x, up->y - here->y, up->z - here->z)), 0.01);
    // Grid north against true north: the convergence, atan(tan(lon - 15) sin(lat)) to first order.
    auto g = f.toLonLatHeight(p);
    ASSERT_TRUE(g.ok());
    const dis::LocalAxes t = dis::trueAxes(g->lat * kDeg, g->lon * kDeg);
    const double gamma = std::atan(std::tan((g->lon - 15.0) * kDeg) * std::sin(g->lat * kDeg)) / kDeg;
    EXPECT_NEAR(angleDeg(l.north, t.north), std::abs(gamma), 0.01) << g->lon << " " << g->lat;
  }
}

}  // namespace
}  // namespace sandtable
