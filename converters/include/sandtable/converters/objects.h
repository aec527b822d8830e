#pragma once
// Static objects placed in the load modules (seed chapter V.F, icon
// placement, and IX.B, Figure 87; docs/ICONS.md §8): explicit points,
// point features matched by `place` lines and areas scattered by `scatter`
// lines of the material table, each standing on every level's triangles.
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/converters/culture.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/formats/materials.h"
#include "sandtable/formats/module.h"

namespace sandtable::convert {

/// Everything placement needs, resolved against the icon database;
/// immutable once made, so module jobs share it across threads.
struct ObjectPlan {
  /// One object at a known place, in the database frame (metres east and
  /// south of the north-west post).
  struct Point {
    double x = 0, z = 0;
    std::uint16_t icon = 0;
    std::uint16_t cls = module::kObjectClassExplicit;
    std::uint16_t heading = 0;
    float scale = 1;
  };
  struct Scatter {
    std::uint16_t classId = 0;   ///< area class scattered over
    std::uint16_t icon = 0;
    double cell = 10;            ///< jitter cell edge, metres: sqrt(10000 / density per hectare)
    materials::Variation variation;
    std::uint64_t seed = 1;
  };
  std::vector<Point> points;
  std::vector<Scatter> scatters;
  /// Per icon, its bounding cylinder radius and height at scale 1.
  std::vector<std::array<float, 2>> cylinders;
  bool empty() const { return points.empty() && scatters.empty(); }
};

/// The plan of a build: the table's scatter lines, the culture's matched
/// points and every explicit points file (`files`: GeoJSON, GeoPackage,
/// CSV or anything OGR reads; fields `icon`, optional `heading` in degrees
/// clockwise from north and `scale`; CSV columns x/lon/longitude and
/// y/lat/latitude; a layer without a CRS is WGS 84 longitude/latitude),
/// resolved against `icons` and transformed into `frame`. A points file
/// naming an unknown icon, or with no `icon` field, is an error naming the
/// file and feature; a scatter or place line naming an icon the database
/// lacks is a warning (nothing placed for it); points outside the database
/// are dropped with one warning per file.
Result<ObjectPlan> makeObjectPlan(const std::vector<std::string>& files, const CultureFrame& frame,
                                  const materials::Table& table, const Culture* culture,
                                  const iconpack::Pack& icons);

/// Deterministic variation of one object: scale in [min, max] and a heading
/// over the whole turn, from a hash of the seed and a position key.
void vary(const materials::Variation& v, std::uint64_t seed, std::uint64_t key, float& scale,
          std::uint16_t& heading);

/// Counts from placing one module's objects.
struct ObjectTotals {
  std::uint64_t placed = 0;
  std::uint64_t scatterRefused = 0;  ///< scatter candidates on another class or under a decal
  std::map<std::uint16_t, std::uint64_t> byClass;  ///< class id (kObjectClassExplicit: points files)
};

/// Adds to `m` the objects of `plan` that lie in it: `points` are the
/// indices into plan.points of the module's points; scatters are generated
/// over the module's rectangle (x0, z0: its north-west corner in the frame)
/// on the level-0 skin of their class and off every decal, by the rule of
/// formats/scatter.h, and m.scattering gets the rules that placed a tree
/// (module version 6 stores them instead of the trees). Each object gets
/// its base height on every level (Level::objectY) and a stable id
/// (Object::id). Objects are sorted by icon, z, x, then id. Thread-safe.
void placeObjects(const ObjectPlan& plan, const std::vector<std::uint32_t>& points, double x0, double z0,
                  module::Module& m, ObjectTotals& totals);

}  // namespace sandtable::convert
