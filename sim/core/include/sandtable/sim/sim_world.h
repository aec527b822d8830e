#pragma once
// What the simulation knows of the database: the ground it drives on, the
// soil under it, and the static objects it can hit (seed VII.B, VII.C).
//
// Ground: entities follow the surface of the level of detail that is drawn
// at their position (sandtable/world/ground.h). A viewer sets `drawnLevel` to
// its scene's choice; headless runs draw level 0 (the finest) everywhere,
// unless told otherwise.
//
// Objects: every static object of modules.pack in world coordinates, in a
// grid of collision squares (Figure 56) with each square's tallest object
// (the first-level test). A square is at least as wide as the largest
// object radius plus the largest entity radius plus the farthest an entity
// moves in a step, so the 3x3 squares around an entity hold every object it
// can touch: SimWorld::objectsNear finds exactly what a search of every
// object finds (tested against objectsNearBruteForce).
//
// Modules: read through the world's ModuleSource (paging/module_source.h),
// never from modules.pack directly. refresh() polls the source's changes:
// a module with a newer generation has exactly its own soil classes,
// object bases and objects replaced (its old objects are retired, never
// removed, so object indices stay valid in events), and the collision
// squares are rebuilt. The ground (GroundClamp, Terrain) reads the
// world's HeightField at every query, so a changed patch is under the next
// step with no refresh.
//
// Thread safety: const methods are thread-safe, except that objectsNear
// counts into stats(); object states change only through setObjectState,
// and refresh() runs, from the simulation thread between steps.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/formats/materials.h"
#include "sandtable/paging/module_source.h"
#include "sandtable/paging/world.h"
#include "sandtable/world/ground.h"
#include "sandtable/world/terrain.h"

namespace sandtable::sim {

/// The grid's material byte for water (FORMAT.md, the grid's posts: 0
/// ground, 1 water, 2 filled void): the builder marks the sea and every post
/// at or below elevation 0.
inline constexpr std::uint8_t kGridWater = 1;

/// What a static object has become (seed Table 6's object results).
enum class ObjectState : std::uint8_t { standing, knockedOver, stump, ruins, destroyed };
const char* objectStateName(ObjectState s);

/// The collision class of an object (Table 6's columns).
enum class ObjectKind : std::uint8_t { tree, house, rock };
const char* objectKindName(ObjectKind k);

struct StaticObject {
  double x = 0, z = 0;     ///< world metres
  double baseY = 0;        ///< level 0's base elevation
  double radius = 0, height = 0;
  double headingDeg = 0;
  double scale = 1;
  std::uint16_t icon = 0;
  std::uint16_t cls = 0;
  ObjectKind kind = ObjectKind::rock;
  ObjectState state = ObjectState::standing;
  std::uint32_t moduleX = 0, moduleZ = 0, index = 0;  ///< where it is stored
  std::uint64_t id = 0;  ///< module::Object::id: the same object in every generation of its module
  /// False once a newer generation of its module replaced it: kept so that
  /// indices stay valid, never an obstacle and never drawn.
  bool current = true;
  /// Once retired: the index of the same object (same id) in the newer
  /// generation, which took over its state; UINT32_MAX when the newer
  /// generation no longer has it (a removed object).
  std::uint32_t successor = UINT32_MAX;
};

/// Which level is drawn at world (x, z).
using DrawnLevelFn = std::function<world::DrawnLevel(double x, double z)>;

struct SimWorldOptions {
  /// Collision square edge, metres; the seed's grid square is 125 m. Raised
  /// to fit the largest object and entity (see above).
  double squareM = 125;
  /// Radius of the largest entity the simulation will hold, metres.
  double maxEntityRadiusM = 15;
  /// Farthest an entity moves in one step, metres (a 1,200 m/s munition
  /// at 60 Hz: 20 m); munitions use swept volumes beyond that.
  double maxStepM = 20;
};

/// Counts of what objectsNear calls tested (levels 1 and 2), kept by the
/// caller (Simulation keeps them in SimCounters).
struct SearchStats {
  std::uint64_t squares = 0, squaresPassed = 0, objectsTested = 0;
};

class SimWorld {
 public:
  /// A world over posts alone (tests): no objects, the materials given.
  SimWorld(std::shared_ptr<const grid::HeightField> heights, std::uint32_t moduleSquares, std::uint32_t levels,
           std::optional<materials::Table> materials = std::nullopt);
  /// Over the grid file's posts (a GridHeightField).
  SimWorld(std::shared_ptr<const grid::GridFile> grid, std::uint32_t moduleSquares, std::uint32_t levels,
           std::optional<materials::Table> materials = std::nullopt);
  SimWorld(const SimWorld&) = delete;  // classById_ points into materials_
  SimWorld& operator=(const SimWorld&) = delete;

  /// The simulator's view of a world opened once (paging/world.h): its
  /// posts, materials and icons, and every module's objects and soil read
  /// through its ModuleSource (when it has one). Opens nothing.
  static Result<std::shared_ptr<SimWorld>> open(const paging::World& world, const SimWorldOptions& options = {});
  /// Opens the directory as a World first (tests; one database open).
  static Result<std::shared_ptr<SimWorld>> open(const std::string& directory, const SimWorldOptions& options = {});

  /// Reads again each module whose generation moved since it was read
  /// (ModuleSource::changes, one atomic load when nothing changed): its soil
  /// classes, object bases and objects are replaced, the collision squares
  /// rebuilt. Returns how many modules were read again; a failed read keeps
  /// the module as it was and is returned as problems.
  Result<std::uint32_t> refresh();

  const world::GroundClamp& clamp() const { return clamp_; }
  const world::Terrain& terrain() const { return terrain_; }
  const grid::HeightField& heights() const { return *grid_; }
  double widthM() const { return terrain_.widthMetres(); }
  double depthM() const { return terrain_.depthMetres(); }
  double originEasting() const;
  double originNorthing() const;

  void setDrawnLevel(DrawnLevelFn fn) { drawn_ = std::move(fn); }
  world::DrawnLevel drawnAt(double x, double z) const { return drawn_ ? drawn_(x, z) : world::DrawnLevel{}; }
  /// The drawn surface at (x, z); nullopt off the grid.
  std::optional<double> groundAt(double x, double z) const;

  /// The soil under (x, z): the material table's class that covers the
  /// grid triangle's centroid on level 0 (the highest priority there: a
  /// road or river decal over the skin), or the defaults where there is no
  /// table or no module.
  struct Soil {
    double stickDeg = materials::kDefaultStickDeg;
    double resist = materials::kDefaultResist;
    bool water = false;
    bool known = false;  ///< the post's material is a class of the table
  };
  Soil soilAt(double x, double z) const;
  /// The material class id under (x, z) (see soilAt), or nullopt.
  std::optional<std::uint16_t> classAt(double x, double z) const;
  /// Ships may be here (seed VIII.A.2): the grid marks the post water (the
  /// sea, or elevation <= 0), or the class there is water (lakes, rivers);
  /// with neither, elevation <= 0 where the class is unknown. False off
  /// the grid.
  bool navigable(double x, double z) const;
  bool onGrid(double x, double z) const { return x >= 0 && z >= 0 && x <= widthM() && z <= depthM(); }

  // Icons.
  const iconpack::Pack& icons() const { return icons_; }
  std::optional<std::uint16_t> iconIndex(const std::string& name) const;
  void setIcons(iconpack::Pack icons) { icons_ = std::move(icons); }

  // Static objects.
  const std::vector<StaticObject>& objects() const { return objects_; }
  /// Replaces the objects and rebuilds the squares (tests build worlds).
  void setObjects(std::vector<StaticObject> objects, const SimWorldOptions& options = {});
  void setObjectState(std::uint32_t object, ObjectState state) { objects_[object].state = state; }
  /// The current index of object `object`: itself, or the successor of a
  /// retired one (UINT32_MAX when its module's newer generation dropped it).
  std::uint32_t currentIndex(std::uint32_t object) const {
    while (object < objects_.size() && !objects_[object].current) object = objects_[object].successor;
    return object < objects_.size() ? object : UINT32_MAX;
  }
  double squareM() const { return square_; }
  std::uint32_t squaresX() const { return squaresX_; }
  std::uint32_t squaresZ() const { return squaresZ_; }
  /// The highest top (base + height) of a standing object in square (sx,
  /// sz): Figure 56's first level, the square's tallest object against the
  /// entity's height, as elevations so that it is exact on slopes too.
  /// -infinity for an empty square.
  double tallestTopIn(std::uint32_t sx, std::uint32_t sz) const { return tallest_[std::size_t(sz) * squaresX_ + sx]; }
  /// Standing objects in the 3x3 squares around (x, z) that an upright
  /// cylinder of `radius` from `bottomY` up touches: level 1 (the square's
  /// tallest top above bottomY), level 2 (2-D distance under the sum of the
  /// radii, Figure 58), level 3 (bottomY under the object's top). Fallen,
  /// stumps, ruins and destroyed objects are not obstacles. Appends object
  /// indices to `out` in ascending order.
  /// `stats`, when given, counts what the search tested: the caller owns
  /// it, so concurrent searches share nothing.
  void objectsNear(double x, double z, double radius, double bottomY, std::vector<std::uint32_t>& out,
                   SearchStats* stats = nullptr) const;
  /// The same answer by testing every object (the benchmark's baseline and
  /// the tests' reference).
  void objectsNearBruteForce(double x, double z, double radius, double bottomY,
                             std::vector<std::uint32_t>& out) const;

 private:
  void buildSquares(const SimWorldOptions& options);
  /// Reads module (kx, kz) through modules_: replaces its classes and
  /// appends its objects (the caller retires the old ones).
  Status readModule(std::uint32_t kx, std::uint32_t kz, module::Module& scratch);
  Status loadModules();
  /// Retires module (kx, kz)'s objects before index `first` (its newer
  /// generation starts there), carrying states to their successors.
  void retire(std::uint32_t kx, std::uint32_t kz, std::size_t first);

  std::shared_ptr<const grid::HeightField> grid_;
  world::GroundClamp clamp_;
  world::Terrain terrain_;
  std::optional<materials::Table> materials_;
  std::vector<const materials::Class*> classById_;  ///< material id -> class (256)
  /// Level 0's class per grid triangle (2 per square, upper first), 255
  /// where no module covers it; built by open(), per module by refresh().
  std::vector<std::uint8_t> classes_;
  std::shared_ptr<const paging::ModuleSource> modules_;
  std::vector<std::uint64_t> moduleGeneration_;  ///< the generation read, per module (row-major)
  std::uint64_t changesSeen_ = 0;                ///< modules_->changes() when last polled
  SimWorldOptions options_;
  DrawnLevelFn drawn_;
  iconpack::Pack icons_;
  std::vector<StaticObject> objects_;
  double square_ = 125;
  std::uint32_t squaresX_ = 0, squaresZ_ = 0;
  std::vector<std::uint32_t> squareStart_;   ///< CSR offsets, squares + 1
  std::vector<std::uint32_t> squareObjects_; ///< object indices by square
  std::vector<double> tallest_;
};

/// The object kind of an icon name and a material class name: trees
/// ("tree" in either), houses (buildings, "house", "garage", "building"),
/// rocks otherwise.
ObjectKind objectKindOf(const std::string& iconName, const std::string& className);

}  // namespace sandtable::sim
