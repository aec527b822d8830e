// Collision response (seed VII.C): Table 6 cell by cell against the seed
// typed in here, the table format's errors, Figure 64's sectors and
// responses, the glancing bounce worked by hand, and the contact ray
// through boxes whose overlap is known in closed form.
#include "sandtable/sim/collision_response.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace sandtable::sim {
namespace {

using E = EntityResult;
using O = ObjectResult;

#ifdef SANDTABLE_SOURCE_DIR
const std::string kSample = std::string(SANDTABLE_SOURCE_DIR) + "/samples/collisions.txt";
#endif

double kmh(double v) { return v / 3.6; }

// ------------------------------------------------------------ Table 6

/// Seed Table 6, typed from the dissertation (entity result / object
/// result; slow, medium, fast), not read from the sample.
struct SeedCell {
  const char* entity;
  const char* object;
  StaticOutcome slow, medium, fast;
};
const SeedCell kSeedTable6[] = {
    {"tank", "tree", {E::stop, O::none}, {E::destroyed, O::knockedOver}, {E::destroyed, O::stump}},
    {"tank", "house", {E::stop, O::none}, {E::destroyed, O::none}, {E::destroyed, O::ruins}},
    {"tank", "rock", {E::stop, O::none}, {E::destroyed, O::none}, {E::destroyed, O::none}},
    {"airplane", "tree", {E::destroyed, O::none}, {E::destroyed, O::knockedOver}, {E::destroyed, O::stump}},
    {"airplane", "house", {E::destroyed, O::none}, {E::destroyed, O::none}, {E::destroyed, O::ruins}},
    {"airplane", "rock", {E::stop, O::none}, {E::destroyed, O::none}, {E::destroyed, O::none}},
    {"missile", "tree", {E::destroyed, O::destroyed}, {E::destroyed, O::destroyed}, {E::destroyed, O::destroyed}},
    {"missile", "house", {E::destroyed, O::destroyed}, {E::destroyed, O::destroyed}, {E::destroyed, O::destroyed}},
    {"missile", "rock", {E::destroyed, O::none}, {E::destroyed, O::none}, {E::destroyed, O::none}},
};

std::string show(const StaticOutcome& o) {
  std::string s(resultName(o.entity));
  s += "/";
  s += resultName(o.object);
  return s;
}

void expectSeedCells(const CollisionTable& t) {
  std::size_t rows = 0;
  for (const auto& [entity, objects] : t.results) rows += objects.size();
  EXPECT_EQ(rows, 9u) << "Table 6 has 3 x 3 rows";
  for (const SeedCell& c : kSeedTable6) {
    SCOPED_TRACE(std::string(c.entity) + " hits " + c.object);
    const auto e = t.results.find(c.entity);
    ASSERT_NE(e, t.results.end());
    const auto row = e->second.find(c.object);
    ASSERT_NE(row, e->second.end());
    EXPECT_EQ(show(row->second[0]), show(c.slow));
    EXPECT_EQ(show(row->second[1]), show(c.medium));
    EXPECT_EQ(show(row->second[2]), show(c.fast));
  }
}

TEST(CollisionTable, BuiltInHoldsTable6) { expectSeedCells(defaultCollisionTable()); }

#ifdef SANDTABLE_SOURCE_DIR
TEST(CollisionTable, SampleHoldsTable6AndEqualsBuiltIn) {
  auto r = readCollisionTable(kSample);
  ASSERT_TRUE(r.ok()) << r.error();
  expectSeedCells(r.value());
  EXPECT_TRUE(r.value() == defaultCollisionTable());
  auto text = parseCollisionTable(defaultCollisionTableText(), "built-in");
  ASSERT_TRUE(text.ok()) << text.error();
  EXPECT_TRUE(text.value() == r.value());
}
#endif

/// Speeds inside each bin of the shipped edges (tank 10/40 km/h,
/// airplane 150/400, missile always fast) give the seed's cells.
TEST(CollisionTable, LookupEveryCellInsideItsBin) {
  const CollisionTable& t = defaultCollisionTable();
  struct Speeds {
    const char* entity;
    double slow, medium, fast;  // km/h
  };
  const Speeds speeds[] = {{"tank", 5, 25, 70}, {"airplane", 100, 250, 900}, {"missile", 0, 0, 3000}};
  for (const SeedCell& c : kSeedTable6) {
    for (const Speeds& s : speeds) {
      if (std::string(s.entity) != c.entity) continue;
      SCOPED_TRACE(std::string(c.entity) + " hits " + c.object);
      if (std::string(c.entity) == "missile") {
        // "0 0": every speed is fast; the seed's three cells are equal.
        for (double v : {0.0, 50.0, 3000.0}) EXPECT_EQ(show(lookup(t, c.entity, c.object, kmh(v))), show(c.fast));
        continue;
      }
      EXPECT_EQ(show(lookup(t, c.entity, c.object, kmh(s.slow))), show(c.slow));
      EXPECT_EQ(show(lookup(t, c.entity, c.object, kmh(s.medium))), show(c.medium));
      EXPECT_EQ(show(lookup(t, c.entity, c.object, kmh(s.fast))), show(c.fast));
    }
  }
}

TEST(CollisionTable, BinEdges) {
  const CollisionTable& t = defaultCollisionTable();
  const double below = -1e-9;
  struct Case {
    const char* entity;
    double speedMs;
    SpeedBin want;
  };
  const Case cases[] = {
      {"tank", 0, SpeedBin::slow},
      {"tank", kmh(10) + below, SpeedBin::slow},
      {"tank", kmh(10), SpeedBin::medium},  // an edge is in the faster bin
      {"tank", kmh(40) + below, SpeedBin::medium},
      {"tank", kmh(40), SpeedBin::fast},
      {"tank", -kmh(40), SpeedBin::fast},  // reversing: the magnitude counts
      {"airplane", kmh(150) + below, SpeedBin::slow},
      {"airplane", kmh(150), SpeedBin::medium},
      {"airplane", kmh(400) + below, SpeedBin::medium},
      {"airplane", kmh(400), SpeedBin::fast},
      {"missile", 0, SpeedBin::fast},
      {"missile", kmh(1), SpeedBin::fast},
      {"submarine", kmh(1000), SpeedBin::slow},  // no speeds line
      {"tank", std::numeric_limits<double>::quiet_NaN(), SpeedBin::slow},
  };
  for (const Case& c : cases) {
    EXPECT_EQ(speedBin(t, c.entity, c.speedMs), c.want) << c.entity << " at " << c.speedMs << " m/s";
  }
  // Through lookup: a tank at exactly 10 km/h knocks the tree over.
  EXPECT_EQ(show(lookup(t, "tank", "tree", kmh(10))), "destroyed/knocked-over");
  EXPECT_EQ(show(lookup(t, "tank", "tree", kmh(10) + below)), "stop/none");
  EXPECT_EQ(show(lookup(t, "tank", "tree", kmh(40))), "destroyed/stump");
}

TEST(CollisionTable, UnknownPairIsStopNoneOrTheDefaultLine) {
  const CollisionTable& t = defaultCollisionTable();
  EXPECT_EQ(show(lookup(t, "tank", "fence", kmh(90))), "stop/none");
  EXPECT_EQ(show(lookup(t, "boat", "tree", kmh(90))), "stop/none");

  auto r = parseCollisionTable("sandtable-collisions 1\nspeeds tank 10 40\n", "t");
  ASSERT_TRUE(r.ok()) << r.error();  // speeds without results is fine
  EXPECT_EQ(show(lookup(r.value(), "tank", "tree", kmh(90))), "stop/none");

  r = parseCollisionTable("sandtable-collisions 1\ndefault destroyed/ruins\n", "t");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(show(lookup(r.value(), "tank", "tree", kmh(90))), "destroyed/ruins");
}

TEST(CollisionTable, EditedTableOpenEndedClasses) {
  const char* text =
      "# a user's table\r\n"
      "sandtable-collisions 1   # header\r\n"
      "speeds\tjeep 5 5\r\n"
      "result jeep fence none/knocked-over none/knocked-over stop/destroyed\r\n";
  auto r = parseCollisionTable(text, "edited.txt");
  ASSERT_TRUE(r.ok()) << r.error();
  const CollisionTable& t = r.value();
  ASSERT_EQ(t.speeds.count("jeep"), 1u);
  EXPECT_EQ(t.speeds.at("jeep").mediumKmh, 5);
  EXPECT_EQ(t.speeds.at("jeep").fastKmh, 5);
  // Equal edges: no medium bin.
  EXPECT_EQ(show(lookup(t, "jeep", "fence", kmh(4.9))), "none/knocked-over");
  EXPECT_EQ(show(lookup(t, "jeep", "fence", kmh(5))), "stop/destroyed");
}

// ------------------------------------------------------------ table errors

struct ErrorCase {
  const char* what;
  std::string text;
  std::string badToken;  // the token the offset must point at ("" = end of the line, see endLine)
  int line, column;
  const char* says;
};

TEST(CollisionTable, ErrorsNameLineAndColumn) {
  const std::string h = "sandtable-collisions 1\n";
  const std::string sp = "speeds tank 10 40\n";
  const std::vector<ErrorCase> cases = {
      {"bad header", "# c\nsandtable-collision 1\n", "sandtable-collision", 2, 1, "missing header"},
      {"newer version", "sandtable-collisions 2\n", "2", 1, 22, "newer"},
      {"header twice", h + "sandtable-collisions 1\n", "sandtable-collisions 1\n", 2, 1, "only once"},
      {"unknown directive", h + "rezult tank tree a/b c/d e/f\n", "rezult", 2, 1, "unknown directive"},
      {"unknown entity result", h + sp + "result tank tree halt/none stop/none stop/none\n", "halt/none", 3, 18,
       "unknown entity result \"halt\""},
      {"unknown object result", h + sp + "result tank tree stop/none stop/flat stop/none\n", "flat", 3, 33,
       "unknown object result \"flat\""},
      {"cell without slash", h + sp + "result tank tree stop stop/none stop/none\n", "stop stop", 3, 18,
       "ENTITY/OBJECT"},
      {"result too many fields", h + sp + "result tank tree stop/none stop/none stop/none stop/none\n",
       "stop/none\n", 3, 48, "takes 5 fields, not 6"},
      {"result too few fields", h + sp + "result tank tree stop/none stop/none\n", "\n", 3, 37,
       "takes 5 fields, not 4"},
      {"speeds too few fields", h + "speeds tank 10\n", "\n", 2, 15, "takes 3 fields, not 2"},
      {"speeds decrease", h + "speeds tank 40 10\n", "10\n", 2, 16, "must not decrease"},
      {"speeds not a number", h + "speeds tank ten 40\n", "ten", 2, 13, "km/h"},
      {"speeds negative", h + "speeds tank -1 40\n", "-1", 2, 13, "km/h"},
      {"duplicate speeds", h + sp + "speeds  tank 1 2\n", "tank 1 2", 3, 9, "already given on line 2"},
      {"duplicate result", h + sp + "result tank tree stop/none stop/none stop/none\n" +
                                "result tank tree stop/none stop/none stop/none\n",
       "result tank tree stop/none stop/none stop/none\n#", 4, 8, "already given on line 3"},
      {"results but no speeds", h + "\nresult  boat tree stop/none stop/none stop/none\n", "boat", 3, 9,
       "no speeds line"},
      {"default twice", h + "default stop/none\ndefault stop/none\n", "default stop/none\n#", 3, 1,
       "already given on line 2"},
      {"bad class name", h + "speeds ta/nk 10 40\n", "ta/nk", 2, 8, "may hold only"},
      {"control character", h + "speeds tank\x01 10 40\n", "\x01", 2, 12, "control character 0x01"},
  };
  for (const ErrorCase& c : cases) {
    SCOPED_TRACE(c.what);
    auto r = parseCollisionTable(c.text, "mine.txt");
    ASSERT_FALSE(r.ok());
    const Problem& p = r.problems().front();
    EXPECT_EQ(p.file, "mine.txt");
    const std::string want = "line " + std::to_string(c.line) + ", column " + std::to_string(c.column) + ": ";
    EXPECT_EQ(p.message.substr(0, want.size()), want) << p.message;
    EXPECT_NE(p.message.find(c.says), std::string::npos) << p.message;
    // The offset is the bad token's byte offset: find the token in its line.
    std::size_t lineStart = 0;
    for (int k = 1; k < c.line; ++k) lineStart = c.text.find('\n', lineStart) + 1;
    EXPECT_EQ(p.offset, lineStart + static_cast<std::size_t>(c.column - 1));
    // The hand-counted column agrees with where the token is.
    std::string token = c.badToken;
    if (token.size() > 1 && token.back() == '#') {
      // A repeated line: its second copy.
      token.pop_back();
      const auto first = c.text.find(token);
      EXPECT_EQ(p.offset, c.text.find(token, first + 1) + (p.offset - lineStart));
      continue;
    }
    EXPECT_EQ(c.text.compare(p.offset, token.size(), token), 0)
        << "offset " << p.offset << " points at \"" << c.text.substr(p.offset, 10) << "\"";
  }
}

TEST(CollisionTable, EmptyTableAndMissingFile) {
  auto r = parseCollisionTable("# only a comment\n\n", "empty.txt");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.problems().front().message.find("empty"), std::string::npos);
  EXPECT_EQ(r.problems().front().message.substr(0, 18), "line 3, column 1: ");

  auto f = readCollisionTable("/nonexistent/collisions.txt");
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.problems().front().file, "/nonexistent/collisions.txt");
}

TEST(CollisionTable, EveryProblemReported) {
  auto r = parseCollisionTable("sandtable-collisions 1\nspeeds a 2 1\nspeeds b x 1\nresult c d x/y a/b c/d\n", "t");
  ASSERT_FALSE(r.ok());
  // Lines 2, 3, 4 (three bad cells), and c without speeds.
  EXPECT_GE(r.problems().size(), 4u);
}

// ------------------------------------------------------------ Figure 64

TEST(MovingCollision, ClassifyImpactBounds) {
  struct Case {
    double deg;
    ImpactKind want;
  };
  using K = ImpactKind;
  const Case cases[] = {
      {0, K::front},        {5, K::front},      {5.001, K::glancing},  {354.999, K::glancing},
      {355, K::front},      {359.9, K::front},  {360, K::front},       {-5, K::front},
      {84.999, K::glancing}, {85, K::right},    {90, K::right},        {95, K::right},
      {95.001, K::glancing}, {174.9, K::glancing}, {175, K::rear},     {180, K::rear},
      {185, K::rear},       {185.1, K::glancing}, {264.9, K::glancing}, {265, K::left},
      {270, K::left},       {275, K::left},     {275.1, K::glancing},  {45, K::glancing},
      {810, K::right},      {-90, K::left},     {std::numeric_limits<double>::quiet_NaN(), K::glancing},
  };
  for (const Case& c : cases) EXPECT_EQ(classifyImpact(c.deg), c.want) << c.deg;
}

constexpr double kDeg = std::numbers::pi / 180.0;

/// The ground-plane unit vector of a compass bearing (x east, z south).
Eigen::Vector2d compass(double deg) { return {std::sin(deg * kDeg), -std::cos(deg * kDeg)}; }

/// A stands still at (100, 200) heading `heading`; B sits 6 m away at
/// `rel` degrees relative to A's heading and drives straight at A at
/// `speed` m/s, so the closing speed is `speed`.
MovingOutcome strike(double heading, double rel, double speed, double kill = 10) {
  MovingState a{{100, 200}, {0, 0}, heading};
  const Eigen::Vector2d n = compass(heading + rel);
  MovingState b{a.position + 6 * n, -speed * n, heading + rel + 180};
  return resolveMoving(a, b, kill);
}

TEST(MovingCollision, Figure64Branches) {
  using K = ImpactKind;
  struct Case {
    double rel;
    K kind;
  };
  const Case cases[] = {
      {0, K::front},      {5, K::front},      {355, K::front},    {85, K::right},     {95, K::right},
      {175, K::rear},     {185, K::rear},     {265, K::left},     {275, K::left},     {5.5, K::glancing},
      {354.5, K::glancing}, {84.5, K::glancing}, {95.5, K::glancing}, {174.5, K::glancing}, {185.5, K::glancing},
      {264.5, K::glancing}, {275.5, K::glancing}, {45, K::glancing},
  };
  for (double heading : {0.0, 130.0, 300.0}) {
    for (const Case& c : cases) {
      for (double speed : {4.0, 16.0}) {  // slow and fast against a kill speed of 10 m/s
        SCOPED_TRACE("heading " + std::to_string(heading) + " rel " + std::to_string(c.rel) + " speed " +
                     std::to_string(speed));
        const MovingOutcome o = strike(heading, c.rel, speed);
        EXPECT_EQ(o.kindA, c.kind);
        // B drives straight at A: A is dead ahead of B.
        EXPECT_EQ(o.kindB, K::front);
        if (c.kind != K::glancing) {
          const bool fast = speed > 10;
          EXPECT_EQ(o.killA, fast);
          EXPECT_EQ(o.killB, fast);
          EXPECT_EQ(o.stopA, !fast);
          EXPECT_EQ(o.stopB, !fast);
          EXPECT_EQ(o.newVelocityA, Eigen::Vector2d(0, 0));
          EXPECT_EQ(o.newVelocityB, Eigen::Vector2d(0, 0));
          continue;
        }
        EXPECT_FALSE(o.killA || o.killB || o.stopA || o.stopB);
        // A stood still and stays still; B's velocity -speed n (all along
        // the normal) turns round to +speed n and keeps half.
        const Eigen::Vector2d n = compass(heading + c.rel);
        EXPECT_NEAR((o.newVelocityA).norm(), 0, 1e-12);
        EXPECT_NEAR((o.newVelocityB - 0.5 * speed * n).norm(), 0, 1e-9);
        EXPECT_NEAR(std::remainder(o.newHeadingB - (heading + c.rel), 360.0), 0, 1e-9);
        EXPECT_NEAR(o.newHeadingA, heading, 1e-12);  // zero velocity keeps the heading
        EXPECT_GT((o.newVelocityB - o.newVelocityA).dot(n), 0) << "separating";
      }
    }
  }
}

TEST(MovingCollision, ClosingSpeedIsTheRelativeSpeed) {
  // Head-on at 6 m/s each: neither is above 10, but they close at 12.
  MovingState a{{0, 0}, {0, -6}, 0};
  MovingState b{{0, -5}, {0, 6}, 180};
  MovingOutcome o = resolveMoving(a, b, 10);
  EXPECT_EQ(o.kindA, ImpactKind::front);
  EXPECT_TRUE(o.killA && o.killB);

  // Nose to tail at 20 and 18 m/s: both fast, closing at 2.
  a = {{0, 0}, {0, -20}, 0};
  b = {{0, -5}, {0, -18}, 0};
  o = resolveMoving(a, b, 10);
  EXPECT_EQ(o.kindA, ImpactKind::front);
  EXPECT_EQ(o.kindB, ImpactKind::rear);
  EXPECT_FALSE(o.killA || o.killB);
  EXPECT_TRUE(o.stopA && o.stopB);

  // Exactly the kill speed is not above it: stop.
  a = {{0, 0}, {10, 0}, 90};
  b = {{5, 0}, {0, 0}, 0};
  o = resolveMoving(a, b, 10);
  EXPECT_EQ(o.kindA, ImpactKind::front);
  EXPECT_EQ(o.kindB, ImpactKind::left);  // A is due west of B, which heads north
  EXPECT_TRUE(o.stopA && o.stopB);
  EXPECT_FALSE(o.killA);
}

TEST(MovingCollision, GlancingBounceByHand) {
  // A heads north at 10 m/s; B, 3 m east and 3 m north of A (bearing 45),
  // heads west at 4 m/s. The line of centres n = (1, -1)/sqrt2.
  // A: along n = +7.07 (towards B): normal (5,-5) -> (-5,5), tangential
  //    (-5,-5) kept; half of (-10, 0) = (-5, 0): due west, 270.
  // B: along n = -2.83 (towards A): normal (-2,2) -> (2,-2), tangential
  //    (-2,-2) kept; half of (0, -4) = (0, -2): due north, 0.
  const MovingState a{{0, 0}, {0, -10}, 0};
  const MovingState b{{3, -3}, {-4, 0}, 270};
  const MovingOutcome o = resolveMoving(a, b, 10);
  EXPECT_EQ(o.kindA, ImpactKind::glancing);
  EXPECT_EQ(o.kindB, ImpactKind::glancing);  // A at 225 from B, 315 relative to 270
  EXPECT_FALSE(o.killA || o.killB || o.stopA || o.stopB);
  EXPECT_NEAR(o.newVelocityA.x(), -5, 1e-12);
  EXPECT_NEAR(o.newVelocityA.y(), 0, 1e-12);
  EXPECT_NEAR(o.newVelocityB.x(), 0, 1e-12);
  EXPECT_NEAR(o.newVelocityB.y(), -2, 1e-12);
  EXPECT_NEAR(o.newHeadingA, 270, 1e-9);
  EXPECT_NEAR(std::remainder(o.newHeadingB, 360.0), 0, 1e-9);
  const Eigen::Vector2d n = Eigen::Vector2d(1, -1).normalized();
  EXPECT_NEAR((o.newVelocityB - o.newVelocityA).dot(n), 7 / std::sqrt(2.0), 1e-12);

  // bounceKeep 1 keeps the whole speed; above 1 is clamped to 1.
  for (double keep : {1.0, 3.0}) {
    const MovingOutcome k = resolveMoving(a, b, 10, keep);
    EXPECT_NEAR(k.newVelocityA.x(), -10, 1e-12);
    EXPECT_NEAR(k.newVelocityB.y(), -4, 1e-12);
  }
}

TEST(MovingCollision, GlancingKeepsAComponentAlreadyPointingAway) {
  // A's velocity (-8, -6) has -1.41 along n (away from B): kept as it is,
  // so A only slows to half: (-4, -3).
  const MovingState a{{0, 0}, {-8, -6}, 0};
  const MovingState b{{3, -3}, {0, 0}, 0};
  const MovingOutcome o = resolveMoving(a, b, 10);
  EXPECT_EQ(o.kindA, ImpactKind::glancing);
  EXPECT_NEAR(o.newVelocityA.x(), -4, 1e-12);
  EXPECT_NEAR(o.newVelocityA.y(), -3, 1e-12);
  EXPECT_NEAR(o.newHeadingA, 360 - std::atan2(4.0, 3.0) / kDeg, 1e-9);  // 306.87, a little west of north-west
}

TEST(MovingCollision, CoincidentIsFrontImpact) {
  const MovingState a{{1, 1}, {0, -20}, 0};
  const MovingState b{{1, 1}, {0, 0}, 90};
  const MovingOutcome o = resolveMoving(a, b, 10);
  EXPECT_EQ(o.kindA, ImpactKind::front);
  EXPECT_TRUE(o.killA && o.killB);
}

// ------------------------------------------------------------ contact ray

/// A box centred on the body origin with half extents h: 12 triangles.
std::vector<Triangle> box(float hx, float hy, float hz) {
  const Eigen::Vector3f v[8] = {{-hx, -hy, -hz}, {hx, -hy, -hz}, {hx, hy, -hz}, {-hx, hy, -hz},
                                {-hx, -hy, hz},  {hx, -hy, hz},  {hx, hy, hz},  {-hx, hy, hz}};
  const int quads[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};
  std::vector<Triangle> t;
  for (const auto& q : quads) {
    t.push_back({v[q[0]], v[q[1]], v[q[2]]});
    t.push_back({v[q[0]], v[q[2]], v[q[3]]});
  }
  return t;
}

Eigen::Affine3d at(const Eigen::Vector3d& p, double yawDeg = 0) {
  Eigen::Affine3d m = Eigen::Affine3d::Identity();
  m.translate(p);
  m.rotate(Eigen::AngleAxisd(yawDeg * kDeg, Eigen::Vector3d::UnitY()));
  return m;
}

TEST(ContactRay, RayTriangle) {
  const Triangle tri{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const Eigen::Vector3d down(0, 0, -1);
  EXPECT_NEAR(*rayTriangle({0.2, 0.2, 5}, down, tri), 5, 1e-12);
  EXPECT_NEAR(*rayTriangle({0.2, 0.2, 5}, 2 * down, tri), 2.5, 1e-12);  // t in units of |dir|
  EXPECT_NEAR(*rayTriangle({0.5, 0.5, 5}, down, tri), 5, 1e-12);        // on the hypotenuse
  EXPECT_NEAR(*rayTriangle({0, 0, -3}, -down, tri), 3, 1e-12);          // from behind, at a corner
  EXPECT_FALSE(rayTriangle({0.2, 0.2, 5}, -down, tri));                 // pointing away
  EXPECT_FALSE(rayTriangle({0.6, 0.6, 5}, down, tri));                  // outside
  EXPECT_FALSE(rayTriangle({-0.1, 0.2, 5}, down, tri));
  EXPECT_FALSE(rayTriangle({0.2, 0.2, 0}, {1, 0, 0}, tri));            // in the plane
  EXPECT_FALSE(rayTriangle({0.2, 0.2, 5}, down, Triangle{{0, 0, 0}, {1, 1, 0}, {2, 2, 0}}));  // degenerate
  // Slanted: from (0.25, 0.25, 1) along (0, 0, -1) meets z = 0 at t = 1.
  EXPECT_NEAR(*rayTriangle({0.25, 0.25, 1}, Eigen::Vector3d(0.25, 0, -1), tri), 1, 1e-12);
}

TEST(ContactRay, UnitCubesHitIffTheyOverlap) {
  const auto cube = box(0.5f, 0.5f, 0.5f);
  const Eigen::Vector3d base(10, 2, -5);
  const Eigen::Vector3d axes[] = {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 0, 1).normalized()};
  for (const Eigen::Vector3d& u : axes) {
    for (double d : {0.5, 0.9, 1.1, 2.0}) {
      SCOPED_TRACE("direction " + std::to_string(u.z()) + " distance " + std::to_string(d));
      const Eigen::Vector3d off = d * u;
      // Axis-aligned unit cubes overlap when every axis is within 1.
      const bool overlap = std::abs(off.x()) < 1 && std::abs(off.y()) < 1 && std::abs(off.z()) < 1;
      const Contact c = contactPoint(cube, at(base), cube, at(base + off));
      EXPECT_EQ(c.hit, overlap);
      // Along x the ray leaves each cube at 0.5; along the xz diagonal at
      // an edge, sqrt(2)/2.
      const double half = u.z() == 0 ? 0.5 : std::sqrt(0.5);
      EXPECT_NEAR(c.distA, half, 1e-9);
      EXPECT_NEAR(c.distB, half, 1e-9);
      if (!c.hit) continue;
      // Equal cubes: the middle of the overlap is the middle between them.
      EXPECT_NEAR((c.worldPoint - (base + off / 2)).norm(), 0, 1e-9);
      EXPECT_NEAR((c.bodyPointA - off / 2).norm(), 0, 1e-9);
      EXPECT_NEAR((c.bodyPointB + off / 2).norm(), 0, 1e-9);
    }
  }
}

TEST(ContactRay, UnequalBoxesContactInTheOverlap) {
  // A: unit cube; B: half extents 1. Origins 1.2 apart along x: A ends at
  // 0.5, B begins at 0.2; the overlap [0.2, 0.5] has its middle at 0.35.
  const Contact c = contactPoint(box(0.5f, 0.5f, 0.5f), at({0, 0, 0}), box(1, 1, 1), at({1.2, 0, 0}));
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.distA, 0.5, 1e-9);
  EXPECT_NEAR(c.distB, 1.0, 1e-9);
  EXPECT_NEAR((c.worldPoint - Eigen::Vector3d(0.35, 0, 0)).norm(), 0, 1e-9);
  EXPECT_NEAR((c.bodyPointB - Eigen::Vector3d(-0.85, 0, 0)).norm(), 0, 1e-9);
}

TEST(ContactRay, BodyCoordinatesAfterRotatingB) {
  // B is a 2 x 1 x 0.5 box (half extents 1, 0.5, 0.25). Yawed 90 degrees
  // about +y, body x points to world -z and body z to world +x, so along
  // world x B reaches 0.25 instead of 1.
  const auto a = box(0.5f, 0.5f, 0.5f);
  const auto b = box(1, 0.5f, 0.25f);
  Contact c = contactPoint(a, at({0, 0, 0}), b, at({0.7, 0, 0}, 90));
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.distB, 0.25, 1e-9);
  // Overlap [0.45, 0.5]: contact at x = 0.475, 0.225 west of B's origin,
  // which is B's body -z.
  EXPECT_NEAR((c.worldPoint - Eigen::Vector3d(0.475, 0, 0)).norm(), 0, 1e-9);
  EXPECT_NEAR((c.bodyPointA - Eigen::Vector3d(0.475, 0, 0)).norm(), 0, 1e-9);
  EXPECT_NEAR((c.bodyPointB - Eigen::Vector3d(0, 0, -0.225)).norm(), 0, 1e-9);

  // Unrotated, the same box reaches 1 along x: at 0.7 the contact is at
  // the middle of [-0.3, 0.5], x = 0.1, B's body -x.
  c = contactPoint(a, at({0, 0, 0}), b, at({0.7, 0, 0}));
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR((c.bodyPointB - Eigen::Vector3d(-0.6, 0, 0)).norm(), 0, 1e-9);

  // At 0.8 only the unrotated box reaches A (0.5 + 0.25 < 0.8).
  EXPECT_FALSE(contactPoint(a, at({0, 0, 0}), b, at({0.8, 0, 0}, 90)).hit);
  EXPECT_TRUE(contactPoint(a, at({0, 0, 0}), b, at({0.8, 0, 0})).hit);
}

TEST(ContactRay, EmptyIconsAndCoincidentOrigins) {
  const auto cube = box(0.5f, 0.5f, 0.5f);
  Contact c = contactPoint({}, at({0, 0, 0}), cube, at({0.4, 0, 0}));
  EXPECT_EQ(c.distA, 0);
  EXPECT_TRUE(c.hit);  // B alone reaches past A's origin: 0 + 0.5 >= 0.4
  // The overlap runs from B's surface at -0.1 to A's "surface" at 0.
  EXPECT_NEAR((c.worldPoint - Eigen::Vector3d(-0.05, 0, 0)).norm(), 0, 1e-9);
  c = contactPoint({}, at({0, 0, 0}), cube, at({0.6, 0, 0}));
  EXPECT_FALSE(c.hit);
  c = contactPoint(cube, at({3, 0, 0}), cube, at({3, 0, 0}, 45));
  EXPECT_TRUE(c.hit);
  EXPECT_EQ(c.worldPoint, Eigen::Vector3d(3, 0, 0));
}

}  // namespace
}  // namespace sandtable::sim
