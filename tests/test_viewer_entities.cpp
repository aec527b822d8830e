// What moves, drawn (`sandtable fly --scenario`, docs/VIEWER.md "Entities"):
// over a 2 km synthetic database built with samples/icons.txt, seen from
// straight above at full terrain detail, a tank placed at a known spot shows
// its olive armour at its projected pixel, long along its heading and with
// its gun along its turret's angle; a tree the simulation destroyed is gone
// from the frame and a stump'd one changes to its stump; a flash and a trail
// are drawn while they last and not after. Through the CLI, a scenario's red
// tank is a red dot on the map at its own place, stats.json gains the `sim`
// objects, and a wrong --attach is a usage error naming the entities.
#include <cmath>
#include <fstream>
#include <limits>

#include <nlohmann/json.hpp>

#include "sandtable/formats/database.h"
#include "sandtable/formats/pack.h"
#include "sandtable/render/image.h"
#include "sandtable/render/map_view.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/camera_math.h"
#include "sandtable/scene/module_scene.h"
#include "sandtable/viewer/flight.h"
#include "sandtable/viewer/fly_session.h"
#include "sandtable/testing/xvfb.h"
#include "sandtable/world/ground.h"
#include "test_support.h"
#include "sandtable/testing/require.h"

// After gtest (test_support.h): Xlib's macros would break its templates.
#include <X11/Xlib.h>
#include <X11/extensions/XTest.h>
#include <X11/keysym.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <thread>
// Xlib defines Status as a macro; ours is sandtable::Status (base/result.h).
#undef Status

namespace sandtable::test {
namespace {

using scene::DynamicScene;
using render::Image;
using render::Rgb;

constexpr std::uint32_t kWidth = 640, kHeight = 360;
constexpr double kFovDeg = 30, kAbove = 60;
constexpr double kPi = 3.14159265358979323846;

struct Tree {
  double x = 0, y = 0, z = 0, height = 0;
  std::uint32_t kx = 0, kz = 0, index = 0;
};

class ViewerEntities : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new TempDir("entities");
    const auto synth = runCli({"synth", "-o", *tmp_ / "inputs", "--size-km", "2"});
    ASSERT_EQ(synth.exitCode, 0) << synth.err;
    const auto j = nlohmann::json::parse(slurpFile(*tmp_ / "inputs/synth.json"));
    const auto& b = j["bounds"];
    bounds_ = {b["west"].get<double>(), b["south"].get<double>(), b["east"].get<double>(), b["north"].get<double>()};
    const auto build = runCli({"build", "--elevation", *tmp_ / "inputs/dted2", "--culture", *tmp_ / "inputs/culture.gpkg",
                               "--extent", std::to_string(bounds_[0]), std::to_string(bounds_[1]),
                               std::to_string(bounds_[2]), std::to_string(bounds_[3]), "--spacing", "30", "--icons",
                               std::string(SANDTABLE_SOURCE_DIR) + "/samples/icons.txt", "-o", *tmp_ / "db"});
    ASSERT_EQ(build.exitCode, 0) << build.err;
    auto db = openDatabase(*tmp_ / "db");
    ASSERT_TRUE(db.ok()) << db.error();
    db_ = new Database(std::move(db.value()));
    findLoneTree();
  }
  static void TearDownTestSuite() {
    delete db_;
    db_ = nullptr;
    delete tmp_;
    tmp_ = nullptr;
  }
  void SetUp() override {
    std::string why;
    SANDTABLE_REQUIRE(render::headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
    ASSERT_NE(db_, nullptr);
  }

  /// A tree with no other object within 12 m (seen from above, its own),
  /// and an open spot with none within 25 m, both well inside the database.
  static void findLoneTree() {
    auto reader = pack::PackReader::open(db_->directory);
    ASSERT_TRUE(reader.ok()) << reader.error();
    const auto& h = reader.value()->header();
    std::vector<Tree> all;
    for (std::uint32_t kz = 0; kz < h.modulesZ; ++kz) {
      for (std::uint32_t kx = 0; kx < h.modulesX; ++kx) {
        auto m = reader.value()->read(kx, kz);
        ASSERT_TRUE(m.ok()) << m.error();
        for (std::uint32_t i = 0; i < m->objects.size(); ++i) {
          const module::Object& o = m->objects[i];
          all.push_back({kx * h.moduleSize + o.x, m->levels[0].objectY[i], kz * h.moduleSize + o.z, o.height, kx,
                         kz, i});
          if (db_->icons->icons[o.icon].name != "tree") all.back().height = -1;  // not a tree
        }
      }
    }
    const double width = db_->grid->spacing() * (db_->grid->postsX() - 1);
    const double depth = db_->grid->spacing() * (db_->grid->postsZ() - 1);
    const auto inside = [&](double x, double z) { return x > 150 && z > 150 && x < width - 150 && z < depth - 150; };
    const auto nearest = [&](double x, double z, const Tree* self) {
      double best = INFINITY;
      for (const Tree& u : all) {
        if (&u != self) best = std::min(best, std::hypot(u.x - x, u.z - z));
      }
      return best;
    };
    bool found = false;
    for (const Tree& t : all) {
      if (t.height > 0 && inside(t.x, t.z) && nearest(t.x, t.z, &t) >= 12) {
        tree_ = t;
        found = true;
        break;
      }
    }
    ASSERT_TRUE(found) << "no lone tree inside the database among " << all.size() << " objects";
    for (double z = 200; z < depth - 200; z += 10) {
      for (double x = 200; x < width - 200; x += 10) {
        if (nearest(x, z, nullptr) >= 25) {
          open_ = {x, z};
          return;
        }
      }
    }
    FAIL() << "no open ground";
  }

  static std::uint16_t iconOf(const std::string& name) {
    for (std::size_t k = 0; k < db_->icons->icons.size(); ++k) {
      if (db_->icons->icons[k].name == name) return std::uint16_t(k);
    }
    ADD_FAILURE() << "no icon " << name;
    return 0;
  }

  static double groundAt(double x, double z) {
    const world::GroundClamp clamp(db_->grid);
    return clamp.surfaceXZ(x, z).value_or(0);
  }

  /// A frame from `kAbove` m over world (x, z) looking straight down (north
  /// up the image), terrain at full detail, with what `fill` adds.
  struct Shot {
    Image image;
    Eigen::Matrix4d viewProjection;
    viewer::FrameStats stats;
    Eigen::Vector2d project(double x, double y, double z) const {
      const Eigen::Vector4d c = viewProjection * Eigen::Vector4d(x, y, z, 1);
      return {(c.x() / c.w() + 1) / 2 * kWidth, (1 - c.y() / c.w()) / 2 * kHeight};
    }
    Rgb at(double x, double y, double z) const {
      const Eigen::Vector2d p = project(x, y, z);
      return image.at(std::uint32_t(std::floor(p.x())), std::uint32_t(std::floor(p.y())));
    }
  };
  static Shot shoot(double x, double z, const std::function<void(DynamicScene&)>& fill) {
    viewer::FlightOptions o;
    o.view.width = kWidth;
    o.view.height = kHeight;
    o.view.fog = false;
    o.view.hud = false;
    o.view.hfovDeg = kFovDeg;
    o.view.viewDistance = 3000;
    o.output.frames = 2;
    o.pager.sync = true;
    o.motion.speedKmh = 0;
    o.motion.pitchDeg = -89;
    o.render.mode = viewer::TerrainMode::modules;
    o.render.lod.mode = scene::LodMode::full;
    const double ground = groundAt(x, z);
    viewer::FlightHooks hooks(o);
    hooks.onPose = [&](std::uint32_t, double, world::GroundClamp&) -> std::optional<world::Pose> {
      world::Pose p;
      p.easting = db_->manifest.originEasting + x;
      p.northing = db_->manifest.originNorthing - z;
      p.altitude = ground + kAbove;
      p.headingDeg = 0;
      return p;
    };
    hooks.onFrameContent = [&](std::uint32_t, scene::DisplayBuffer& buf, viewer::FrameStats&) {
      if (fill) fill(buf.dynamic);
    };
    Shot s;
    hooks.onFrame = [&](std::uint32_t, const Image& img) { s.image = img; };
    auto r = viewer::fly(*db_, o, &hooks);
    EXPECT_TRUE(r.ok()) << r.error();
    if (!r.ok() || r->frames.empty()) return s;
    s.stats = r->frames.back();
    scene::Camera cam;
    cam.x = s.stats.easting - db_->manifest.originEasting;
    cam.z = db_->manifest.originNorthing - s.stats.northing;
    cam.y = s.stats.eyeElevation;
    cam.headingDeg = 0;
    cam.pitchDeg = -89;
    cam.hfovDeg = kFovDeg;
    cam.aspect = double(kWidth) / kHeight;
    cam.viewDistance = s.stats.viewDistance;
    s.viewProjection = scene::viewProjection(cam, 0, 0);
    return s;
  }

  static scene::DynamicInstance tankAt(double x, double z, double headingDeg, float turretDeg) {
    scene::DynamicInstance d;
    d.icon = iconOf("tank");
    d.onSurface = true;
    d.shadow = true;
    d.x = x;
    d.z = z;
    d.y = groundAt(x, z);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(-headingDeg * kPi / 180, Eigen::Vector3d::UnitY()));
    d.orientation = {float(q.x()), float(q.y()), float(q.z()), float(q.w())};
    d.turretAzimuthDeg = turretDeg;
    d.force = 2;
    return d;
  }

  static TempDir* tmp_;
  static Database* db_;
  static std::array<double, 4> bounds_;
  static Tree tree_;
  static std::array<double, 2> open_;  ///< world (x, z) of open ground
};
TempDir* ViewerEntities::tmp_ = nullptr;
Database* ViewerEntities::db_ = nullptr;
std::array<double, 4> ViewerEntities::bounds_{};
Tree ViewerEntities::tree_;
std::array<double, 2> ViewerEntities::open_{};

int sum(Rgb c) { return c.r + c.g + c.b; }
int distance(Rgb a, Rgb b) { return std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b); }

/// The armour's olive (builtin tank, 0.22 0.26 0.12) on a face lit from
/// above: ambient 0.40 + 0.60 x the sun's 40-degree elevation.
bool olive(Rgb c) {
  const double light = 0.40 + 0.60 * std::sin(40 * kPi / 180);
  const Rgb want{std::uint8_t(std::lround(0.22 * 255 * light)), std::uint8_t(std::lround(0.26 * 255 * light)),
                 std::uint8_t(std::lround(0.12 * 255 * light))};
  return distance(c, want) <= 12;
}

TEST_F(ViewerEntities, aTankShowsItsOliveAtItsPixelAlongItsHeadingWithItsGunAlongItsTurret) {
  const double x = open_[0], z = open_[1];
  const double y = groundAt(x, z);
  const Shot bare = shoot(x, z, nullptr);
  ASSERT_EQ(distance(bare.at(x, y, z), Rgb{0x87, 0xCE, 0xEB}) > 30, true) << "the ground must show, not the sky";
  const Shot north = shoot(x, z, [&](DynamicScene& d) { d.instances.push_back(tankAt(x, z, 0, 0)); });
  const Shot east = shoot(x, z, [&](DynamicScene& d) { d.instances.push_back(tankAt(x, z, 90, 0)); });
  const Shot turned = shoot(x, z, [&](DynamicScene& d) { d.instances.push_back(tankAt(x, z, 0, 90)); });
  EXPECT_EQ(north.stats.entitiesDrawn, 1u);
  EXPECT_EQ(bare.stats.entitiesDrawn, 0u);
  // The turret's roof at the tank's origin: olive, where the bare ground was not.
  const Rgb roof = north.at(x, y + 2.3, z);
  EXPECT_TRUE(olive(roof)) << int(roof.r) << " " << int(roof.g) << " " << int(roof.b);
  EXPECT_FALSE(olive(bare.at(x, y + 2.3, z)));
  // Heading north, the 7 m hull runs north-south: its roof 2.2 m ahead of
  // the origin (0.8 m right, clear of the turret and the gun) is olive, and
  // 3.5 m east is bare ground (past the hull's 1.75 m and its shadow);
  // heading east, the other way round.
  EXPECT_TRUE(olive(north.at(x + 0.8, y + 1.6, z - 2.2)));
  EXPECT_LT(distance(north.at(x + 3.5, y, z), bare.at(x + 3.5, y, z)), 9);
  EXPECT_TRUE(olive(east.at(x + 2.2, y + 1.6, z + 0.8)));
  EXPECT_LT(distance(east.at(x, y, z + 3.5), bare.at(x, y, z + 3.5)), 9);
  // The gun (the barrel 2 to 6 m ahead of the ring, 2 m up): north with
  // the turret at 0, east with it turned 90 degrees on a hull heading north.
  const double gunY = y + 2.0;
  EXPECT_GT(distance(north.at(x, gunY, z - 5.5), bare.at(x, gunY, z - 5.5)), 40);
  EXPECT_LT(distance(north.at(x + 5.5, gunY, z), bare.at(x + 5.5, gunY, z)), 9);
  EXPECT_GT(distance(turned.at(x + 5.5, gunY, z), bare.at(x + 5.5, gunY, z)), 40);
  EXPECT_LT(distance(turned.at(x, gunY, z - 5.5), bare.at(x, gunY, z - 5.5)), 9);
}

TEST_F(ViewerEntities, aTankStandsOnTheCoarseLevelDrawnUnderItNotOnTheFinest) {
  // Rings of 40, 80 and 120 m, and the eye 250 m south of the tank in the
  // next module, more than 120 m past its edge: the tank's whole module is
  // one node at the coarsest level. Find ground where that level lies at
  // least 2.5 m off the finest surface, with nothing in the line of sight.
  const auto reader = pack::PackReader::open(db_->directory);
  ASSERT_TRUE(reader.ok()) << reader.error();
  const auto& header = reader.value()->header();
  const std::uint32_t levels = header.levels;
  ASSERT_GE(levels, 2u);
  const world::GroundClamp clamp(db_->grid, header.moduleSquares, levels);
  const world::DrawnLevel coarsest{levels - 1, 0};
  const double width = db_->grid->spacing() * (db_->grid->postsX() - 1);
  const double depth = db_->grid->spacing() * (db_->grid->postsZ() - 1);
  constexpr double kBack = 250, kUp = 60;
  std::optional<std::array<double, 2>> spot;
  for (std::uint32_t kz = 0; (kz + 1) * header.moduleSize + 140 < depth && !spot; ++kz) {
    const double edge = (kz + 1) * header.moduleSize;
    for (double z = edge - kBack + 140; z < edge - 5 && !spot; z += 10) {
      for (double x = 100; x < width - 100 && !spot; x += 10) {
        const double fine = *clamp.surfaceXZ(x, z), drawn = *clamp.surfaceXZ(x, z, coarsest);
        if (std::abs(drawn - fine) < 2.5) continue;
        // The sight line to 2 m over the lower surface passes over both on the way.
        const double base = fine + kUp, target = std::min(fine, drawn) + 2;
        bool clear = true;
        for (double t = 0.05; t < 0.95 && clear; t += 0.01) {
          const double zt = z + kBack * (1 - t);
          const double ground = std::max(*clamp.surfaceXZ(x, zt), *clamp.surfaceXZ(x, zt, coarsest));
          clear = ground + 1 < base + t * (target - base);
        }
        if (clear) spot = std::array<double, 2>{x, z};
      }
    }
  }
  ASSERT_TRUE(spot.has_value()) << "no open coarse slope in view";
  const double x = (*spot)[0], z = (*spot)[1], fine = *clamp.surfaceXZ(x, z);
  std::optional<world::DrawnLevel> drawnThere;
  const auto shootFrom = [&](bool withTank) {
    viewer::FlightOptions o;
    o.view.width = kWidth;
    o.view.height = kHeight;
    o.view.fog = false;
    o.view.hud = false;
    o.view.hfovDeg = 12;
    o.view.viewDistance = 3000;
    o.output.frames = 2;
    o.pager.sync = true;  // no upload budget: what is selected is drawn
    o.render.objects = false;
    o.render.mode = viewer::TerrainMode::modules;
    o.render.lod.rings = {40, 80, 120};
    const double pitch = std::atan2(-kUp, kBack) * 180 / kPi;
    viewer::FlightHooks hooks(o);
    hooks.onPose = [&](std::uint32_t, double, world::GroundClamp&) -> std::optional<world::Pose> {
      world::Pose p;
      p.easting = db_->manifest.originEasting + x;
      p.northing = db_->manifest.originNorthing - (z + kBack);
      p.altitude = fine + kUp;
      p.pitchDeg = pitch;
      p.headingDeg = 0;
      return p;
    };
    hooks.onFrameContent = [&](std::uint32_t, scene::DisplayBuffer& buf, viewer::FrameStats&) {
      drawnThere = scene::drawnLevelAt(buf, x, z);
      // The snapshot the simulator's entities stand on says the same
      // everywhere, after the buffer is gone.
      const scene::DrawnLevels kept(buf);
      for (double px = 0; px < 2000; px += 37) {
        for (double pz = 0; pz < 2000; pz += 41) {
          const auto a = scene::drawnLevelAt(buf, px, pz), b = kept.at(px, pz);
          ASSERT_EQ(a.has_value(), b.has_value()) << px << " " << pz;
          if (a) {
            EXPECT_EQ(a->level, b->level);
            EXPECT_EQ(a->morph, b->morph);
          }
        }
      }
      if (withTank) buf.dynamic.instances.push_back(tankAt(x, z, 90, 0));  // on the finest surface, as the simulator puts it
    };
    Shot s;
    hooks.onFrame = [&](std::uint32_t, const Image& img) { s.image = img; };
    auto r = viewer::fly(*db_, o, &hooks);
    EXPECT_TRUE(r.ok()) << r.error();
    scene::Camera cam;
    cam.x = x;
    cam.z = z + kBack;
    cam.y = fine + kUp;
    cam.pitchDeg = pitch;
    cam.hfovDeg = 12;
    cam.aspect = double(kWidth) / kHeight;
    cam.viewDistance = 3000;
    s.viewProjection = scene::viewProjection(cam, 0, 0);
    return s;
  };
  const Shot bare = shootFrom(false), tank = shootFrom(true);
  ASSERT_TRUE(drawnThere.has_value());
  ASSERT_EQ(drawnThere->level, levels - 1) << "the rings should draw the tank's module whole, at its coarsest";
  const double drawn = *clamp.surfaceXZ(x, z, *drawnThere);
  // The topmost row where the tank changed the frame, in its middle column.
  const auto column = std::uint32_t(std::floor(tank.project(x, drawn, z).x()));
  int top = -1;
  for (std::uint32_t v = 0; v < kHeight && top < 0; ++v) {
    if (distance(tank.image.at(column, v), bare.image.at(column, v)) > 30) top = int(v);
  }
  ASSERT_GE(top, 0) << "the tank is not in the frame";
  // Its turret's roof (2.3 m) stands on the drawn surface, not the finest.
  const double onDrawn = tank.project(x, drawn + 2.3, z).y(), onFinest = tank.project(x, fine + 2.3, z).y();
  ASSERT_GT(std::abs(onDrawn - onFinest), 25) << "the levels must differ on the screen";
  EXPECT_NEAR(top, onDrawn, 8) << "level " << drawnThere->level << "; the finest would put it at row " << onFinest;
}

TEST_F(ViewerEntities, aDestroyedTreeIsGoneAndAStumpedOneChanges) {
  const Tree& t = tree_;
  const auto with = [&](scene::ObjectLook look) {
    return shoot(t.x, t.z, [&](DynamicScene& d) { d.objectOverrides.push_back({t.kx, t.kz, t.index, look}); });
  };
  const Shot standing = shoot(t.x, t.z, nullptr);
  const Shot destroyed = with(scene::ObjectLook::destroyed);
  const Shot stump = with(scene::ObjectLook::stump);
  const Shot fallen = with(scene::ObjectLook::knockedOver);
  // Count the pixels around the tree that changed.
  const auto changed = [&](const Shot& a, const Shot& b, double radius) {
    const Eigen::Vector2d c = standing.project(t.x, t.y, t.z);
    const double px = radius * (c - standing.project(t.x + 1, t.y, t.z)).norm();
    int n = 0;
    for (int v = int(c.y() - px); v <= int(c.y() + px); ++v) {
      for (int u = int(c.x() - px); u <= int(c.x() + px); ++u) {
        if (u < 0 || v < 0 || u >= int(kWidth) || v >= int(kHeight)) continue;
        n += distance(a.image.at(std::uint32_t(u), std::uint32_t(v)), b.image.at(std::uint32_t(u), std::uint32_t(v))) > 24;
      }
    }
    return n;
  };
  // Seen from above, the standing tree's crown covers its trunk; gone, the
  // ground shows there; elsewhere the frame is the same.
  EXPECT_GT(changed(standing, destroyed, 2), 50);
  EXPECT_EQ(destroyed.stats.objectsRemoved, 1u);
  EXPECT_EQ(standing.stats.objectsRemoved, 0u);
  EXPECT_EQ(distance(standing.image.at(5, 5), destroyed.image.at(5, 5)), 0);
  // A stump: its cut face (light wood, red above green) where the crown was.
  const Rgb cut = stump.at(t.x, t.y + 0.5, t.z);
  EXPECT_GT(cut.r, cut.g) << int(cut.r) << " " << int(cut.g) << " " << int(cut.b);
  const Rgb crown = standing.at(t.x, t.y + 0.5, t.z);
  EXPECT_GT(crown.g, crown.r);
  EXPECT_GT(changed(standing, stump, 2), 50);
  EXPECT_GT(changed(destroyed, stump, 0.3), 0);  // the stump is there, unlike the destroyed tree
  EXPECT_EQ(stump.stats.objectsChanged, 1u);
  // Knocked over: lying along its heading, not where it stood.
  EXPECT_GT(changed(standing, fallen, 2), 50);
  EXPECT_GT(changed(destroyed, fallen, t.height), 50);
}

TEST_F(ViewerEntities, aFlashAndATrailAreDrawnWhileTheyLast) {
  const double x = open_[0], z = open_[1];
  const double y = groundAt(x, z);
  const Shot bare = shoot(x, z, nullptr);
  const auto flash = [&](float age) {
    return shoot(x, z, [&](DynamicScene& d) { d.flashes.push_back({x, y, z, age, 0.5f, 6}); });
  };
  const Shot young = flash(0.1f), old = flash(0.6f);
  const Rgb core = young.at(x, y + 2, z);
  EXPECT_GT(core.r, 220) << int(core.r) << " " << int(core.g) << " " << int(core.b);
  EXPECT_GT(core.g, 150);
  EXPECT_GT(sum(core), sum(bare.at(x, y + 2, z)) + 200);
  // Its rim is orange: warm, red over green over blue.
  const Rgb rim = young.at(x + 3, y + 2, z);
  EXPECT_TRUE(rim.r > rim.g && rim.g > rim.b) << int(rim.r) << " " << int(rim.g) << " " << int(rim.b);
  EXPECT_EQ(young.stats.flashesDrawn, 1u);
  EXPECT_EQ(old.stats.flashesDrawn, 0u);
  EXPECT_EQ(distance(old.at(x, y + 2, z), bare.at(x, y + 2, z)), 0);
  // A trail 10 m up, 30 m east-west through the middle: light smoke while
  // young, nothing once older than its life.
  const auto trail = [&](float age) {
    return shoot(x, z, [&](DynamicScene& d) {
      scene::Trail t;
      t.points = {{x - 15, y + 10, z, age}, {x + 15, y + 10, z, age}};
      d.trails.push_back(t);
    });
  };
  const Shot smoke = trail(0), gone = trail(2.5f);
  EXPECT_GT(sum(smoke.at(x + 5, y + 10, z)), sum(bare.at(x + 5, y + 10, z)) + 150);
  EXPECT_EQ(smoke.stats.trailsDrawn, 1u);
  EXPECT_EQ(distance(gone.at(x + 5, y + 10, z), bare.at(x + 5, y + 10, z)), 0);
}

TEST_F(ViewerEntities, theCliDrawsAScenarioRedTankAsARedDotOnTheMapAndReportsTheSimulation) {
  // A red tank in the middle of the database (projected frame), the eye
  // over the south-west quarter so its own arrow is elsewhere on the map.
  const auto& m = db_->manifest;
  const double tx = 0.5 * (m.eastEasting() - m.originEasting), tz = 0.5 * (m.originNorthing - m.southNorthing());
  const std::string scenario = *tmp_ / "red.scenario";
  std::ofstream(scenario) << "sandtable-scenario 1\nframe projected\nseed 5\n"
                          << "entity red1 icon=tank force=red mobility=tracked at=" << std::fixed
                          << m.originEasting + tx << "," << m.originNorthing - tz << " heading=90\n"
                          << "entity blue1 icon=truck force=blue mobility=wheeled at=" << m.originEasting + tx - 300
                          << "," << m.originNorthing - tz + 300 << " heading=0 speed=20\n";
  const double lon = bounds_[0] + 0.2 * (bounds_[2] - bounds_[0]), lat = bounds_[1] + 0.2 * (bounds_[3] - bounds_[1]);
  const std::string out = *tmp_ / "cli";
  const auto r = runCli({"fly", *tmp_ / "db", "--scenario", scenario, "--headless", "--png", out, "--frames", "3",
                         "--size", std::to_string(kWidth) + "x" + std::to_string(kHeight), "--map", "--speed", "0",
                         "--at", std::to_string(lon), std::to_string(lat)});
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("sim:      0.1 s simulated, 2/2 entities alive"), std::string::npos) << r.out;
  // The map's layout, as the viewer composes it on a frame of this size.
  render::MapView map(db_->grid);
  map.setVisible(true);
  Image scratch;
  scratch.width = kWidth;
  scratch.height = kHeight;
  scratch.rgba.assign(std::size_t(kWidth) * kHeight * 4, 0);
  const render::MapLayout layout = map.compose(scratch, 0, 0, 0);
  int px = 0, py = 0;
  ASSERT_TRUE(render::MapView::pixelOf(layout, tx, tz, px, py));
  const Image frame = readPng(out + "/frame_00002.png");
  ASSERT_EQ(frame.width, kWidth);
  const Rgb dot = frame.at(std::uint32_t(px), std::uint32_t(py));
  EXPECT_EQ(distance(dot, render::forceColour(2)), 0) << int(dot.r) << " " << int(dot.g) << " " << int(dot.b);
  // stats.json: the run's summary and each frame's state.
  const auto stats = nlohmann::json::parse(slurpFile(out + "/stats.json"));
  ASSERT_TRUE(stats.contains("sim")) << stats.dump().substr(0, 400);
  EXPECT_EQ(stats["sim"]["entities"], 2);
  EXPECT_EQ(stats["sim"]["seed"], 5);
  EXPECT_EQ(stats["sim"]["steps"], 4);  // frame 2 is at 2/30 s: 4 steps of 1/60 s
  EXPECT_EQ(stats["sim"]["view"], "stealth");
  EXPECT_EQ(stats["frames"][2]["sim"]["alive"], 2);
  EXPECT_EQ(stats["frames"][2]["sim"]["steps"], 4);
  EXPECT_TRUE(stats["frames"][2]["dynamic"].contains("entities_drawn"));
  // Attached to the tank, the panel reports it.
  const std::string attached = *tmp_ / "attached";
  const auto a = runCli({"fly", *tmp_ / "db", "--scenario", scenario, "--headless", "--png", attached, "--frames", "2",
                         "--size", "640x360", "--attach", "red1"});
  ASSERT_EQ(a.exitCode, 0) << a.err;
  const auto as = nlohmann::json::parse(slurpFile(attached + "/stats.json"));
  EXPECT_EQ(as["frames"][1]["sim"]["attached"], "red1");
  EXPECT_EQ(as["frames"][1]["dynamic"]["entities_drawn"].get<int>() >= 1, true);
  // A wrong name is the caller's to fix.
  const auto bad = runCli({"fly", *tmp_ / "db", "--scenario", scenario, "--headless", "--png", *tmp_ / "bad",
                           "--attach", "nobody"});
  EXPECT_EQ(bad.exitCode, 2);
  EXPECT_NE(bad.err.find("--attach nobody: no entity of that name in the scenario (it has red1, blue1)"),
            std::string::npos)
      << bad.err;
  const auto noScenario = runCli({"fly", *tmp_ / "db", "--headless", "--png", *tmp_ / "bad", "--attach", "red1"});
  EXPECT_EQ(noScenario.exitCode, 2);
  EXPECT_NE(noScenario.err.find("--attach needs --scenario FILE"), std::string::npos) << noScenario.err;
}

void sleepMs(long ms) {
  const timespec t{ms / 1000, (ms % 1000) * 1'000'000};
  nanosleep(&t, nullptr);
}

/// Frames written to `dir` so far.
std::size_t framesIn(const std::string& dir) {
  std::size_t n = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) n += e.path().filename().string().rfind("frame_", 0) == 0;
  return n;
}

/// Waits until the flight has written `n` more frames (or has ended): a key
/// tapped before is then seen by a frame whatever the machine's speed, where
/// a fixed sleep was too short on a loaded machine. A frame polls the
/// window's events before it is drawn, so the second frame after a tap has
/// it; three leave one to spare.
void waitFrames(const std::string& dir, std::size_t n, const std::atomic<bool>& done) {
  const std::size_t start = framesIn(dir);
  while (!done && framesIn(dir) < start + n) sleepMs(10);
}

/// The top-level window whose name starts with `prefix`; 0 if none yet.
Window findWindow(Display* dpy, const std::string& prefix) {
  Window root = 0, parent = 0, *children = nullptr;
  unsigned n = 0;
  Window found = 0;
  if (!XQueryTree(dpy, DefaultRootWindow(dpy), &root, &parent, &children, &n)) return 0;
  for (unsigned k = 0; k < n && !found; ++k) {
    char* name = nullptr;
    if (XFetchName(dpy, children[k], &name) && name) {
      if (std::string(name).rfind(prefix, 0) == 0) found = children[k];
      XFree(name);
    }
  }
  if (children) XFree(children);
  return found;
}

void tap(Display* dpy, KeySym sym) {
  const KeyCode code = XKeysymToKeycode(dpy, sym);
  XTestFakeKeyEvent(dpy, code, True, CurrentTime);
  XTestFakeKeyEvent(dpy, code, False, CurrentTime);
  XSync(dpy, False);
}

TEST_F(ViewerEntities, inAWindowTheKeysDriveStopAndCycleTheEntities) {
  SANDTABLE_REQUIRE(std::system("command -v Xvfb > /dev/null 2>&1") == 0, "Xvfb (apt-get install xvfb)");
  auto xvfb = testsupport::Xvfb::start();
  ASSERT_TRUE(xvfb) << "Xvfb is installed but did not start";
  Display* keys = XOpenDisplay(xvfb->display.c_str());
  ASSERT_NE(keys, nullptr);
  int ev = 0, err = 0, major = 0, minor = 0;
  ASSERT_TRUE(XTestQueryExtension(keys, &ev, &err, &major, &minor)) << "Xvfb lacks XTEST";
  const auto& m = db_->manifest;
  const double e = 0.5 * (m.originEasting + m.eastEasting()), n = 0.5 * (m.originNorthing + m.southNorthing());
  const std::string scenario = *tmp_ / "drive.scenario";
  std::ofstream(scenario) << "sandtable-scenario 1\nframe projected\n" << std::fixed
                          << "entity lead icon=tank force=blue mobility=tracked at=" << e << "," << n
                          << " heading=10 speed=30 driven\n"
                          << "entity wing icon=tank force=blue mobility=tracked at=" << e + 100 << "," << n
                          << " heading=10 speed=30\n";
  const std::string frames = *tmp_ / "window";
  CommandResult result;
  std::atomic<bool> done{false};
  const char* old = std::getenv("DISPLAY");
  const std::string saved = old ? old : "";
  ::setenv("DISPLAY", xvfb->display.c_str(), 1);
  std::thread flight([&] {
    result = runCli({"fly", *tmp_ / "db", "--scenario", scenario, "--drive", "--window", "--frames", "900",
                     "--size", "320x180", "--png", frames});
    done = true;
  });
  for (int k = 0; k < 1200 && !done && !std::filesystem::exists(frames + "/frame_00000.png"); ++k) sleepMs(50);
  Window w = 0;
  for (int k = 0; k < 200 && !done && !(w = findWindow(keys, "sandtable fly")); ++k) sleepMs(50);
  // Keys reach the simulation at its next step (the step host's before-step
  // hook) and frames can be faster than the 60 Hz step, so each key gets
  // enough frames for several steps before the next (Space re-seeds the
  // drive from the entity and would drop arrows no step has applied yet).
  constexpr std::size_t kKeyFrames = 20;
  if (w) {
    XSetInputFocus(keys, w, RevertToPointerRoot, CurrentTime);
    tap(keys, XK_Up);    // commanded 30 -> 39 km/h
    tap(keys, XK_Up);    // -> 48
    tap(keys, XK_Left);  // 10 -> 5 degrees
    waitFrames(frames, kKeyFrames, done);
    tap(keys, XK_space);  // all stop: commanded 0
    waitFrames(frames, kKeyFrames, done);
    tap(keys, XK_Tab);  // attached to the next entity: wing
    waitFrames(frames, kKeyFrames, done);
    tap(keys, XK_e);  // the stealth eye
    waitFrames(frames, kKeyFrames, done);
    tap(keys, XK_q);
  }
  flight.join();
  if (old) ::setenv("DISPLAY", saved.c_str(), 1);
  else ::unsetenv("DISPLAY");
  XCloseDisplay(keys);
  ASSERT_EQ(result.exitCode, 0) << result.err;
  const auto stats = nlohmann::json::parse(slurpFile(frames + "/stats.json"));
  const auto& f = stats["frames"];
  ASSERT_LT(f.size(), 900u) << "q never arrived";
  // In order: driving at the keys' commands, then all stop, then attached
  // to the wing, then the stealth eye.
  std::size_t k = 0;
  const auto until = [&](const std::function<bool(const nlohmann::json&)>& want) {
    while (k < f.size() && !want(f[k]["sim"])) ++k;
    return k < f.size();
  };
  EXPECT_EQ(f[0]["sim"]["view"], "driving");
  EXPECT_NEAR(f[0]["sim"]["focus"]["command_speed_kmh"].get<double>(), 30, 1e-6);
  ASSERT_TRUE(until([](const nlohmann::json& s) {
    return s["view"] == "driving" && std::abs(s["focus"]["command_speed_kmh"].get<double>() - 48) < 1e-6 &&
           std::abs(s["focus"]["command_heading"].get<double>() - 5) < 1e-6;
  })) << "the arrows never set 48 km/h and 5 degrees";
  ASSERT_TRUE(until([](const nlohmann::json& s) {
    return s["view"] == "driving" && s["focus"]["command_speed_kmh"].get<double>() == 0;
  })) << "Space never stopped it";
  ASSERT_TRUE(until([](const nlohmann::json& s) { return s["view"] == "attached" && s["attached"] == "wing"; }))
      << "Tab never attached the eye to the wing";
  ASSERT_TRUE(until([](const nlohmann::json& s) { return s["view"] == "stealth"; })) << "E never detached";
  EXPECT_EQ(stats["sim"]["view"], "stealth");
}

}  // namespace
}  // namespace sandtable::test
