#pragma once
// Culture: 2-D vector features (roads, rivers, lakes, forest, land use,
// soil) read through OGR, classified by the material table, transformed
// into the database frame, repaired, and decaled onto the terrain
// triangles of one module level (seed chapter V, sections C, D and H;
// Figures 14-18).
//
// Area classes become the skin: inside every grid triangle the skin
// polygons tile the triangle exactly (CGAL Boolean operations on exact
// coordinates), the highest-rank class winning where features overlap and
// the table's default area class filling the rest. Line classes are widened
// to their width with mitred or bevelled joins and square ends (one CGAL
// union per feature, so bends have neither gaps nor overlapping wedges),
// then clipped to the triangles as decals at the class priority. Every
// output vertex lies in its triangle's plane; vertices closer than the
// merge tolerance (seed: 0.1 m) are merged.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "sandtable/formats/materials.h"
#include "sandtable/formats/module.h"
#include "sandtable/formats/result.h"

namespace sandtable::convert {

/// The database frame the culture is placed in (from the grid).
struct CultureFrame {
  std::string crsWkt;         ///< the grid's projected CRS
  double originEasting = 0;   ///< north-west corner post
  double originNorthing = 0;
  double widthM = 0;          ///< (postsX - 1) * spacing
  double heightM = 0;         ///< (postsZ - 1) * spacing
};

struct CultureOptions {
  std::vector<std::string> sources;  ///< any OGR vector source (files; .osm/.pbf too)
  double mergeTolerance = 0.1;       ///< metres (seed: 0.1 m)
};

/// Per-class counts, for the build report and `info`.
struct ClassStats {
  std::uint64_t read = 0;       ///< features mapped to the class
  std::uint64_t dropped = 0;    ///< unusable (e.g. zero length, no area, outside)
  std::uint64_t repaired = 0;   ///< fixed (self-intersection, unclosed ring, duplicate points)
  std::uint64_t defaulted = 0;  ///< no rule matched; fell back to this default class
  double lengthKm = 0;          ///< line classes: centreline length inside the database
  double areaKm2 = 0;           ///< area classes: area inside the database
};

struct CultureStats {
  std::map<std::string, ClassStats> perClass;  ///< by class name
  std::uint64_t featuresRead = 0;
  std::uint64_t warnings = 0;
  std::vector<std::string> messages;  ///< first few warnings, for the report
};

/// Counts from decaling one module level.
struct DecalStats {
  std::uint64_t skinPolygons = 0;   ///< polygons (before triangulation) in the skin
  std::uint64_t decalPolygons = 0;  ///< decal polygons
  std::uint64_t triangles = 0;
};

/// One module level's lattice: where its posts are and their elevations.
struct LevelLattice {
  double moduleX = 0;  ///< world X of the module's NW corner (metres east of the grid origin)
  double moduleZ = 0;  ///< world Z of the module's NW corner (metres south of the grid origin)
  std::vector<double> xs;   ///< module-local x of each lattice column (size squaresX + 1)
  std::vector<double> zs;   ///< module-local z of each lattice row (size squaresZ + 1)
  std::vector<float> heights;  ///< (squaresZ + 1) * (squaresX + 1), row-major, from the grid
  double spacing = 0;  ///< nominal spacing of the level
};

/// Loaded, classified and transformed culture; immutable after load, so
/// decalLevel may run on many threads at once.
class Culture {
 public:
  /// Reads every source, classifies with `table`, transforms into `frame`,
  /// repairs or drops invalid geometry (counted), clips to the database.
  static Result<std::shared_ptr<const Culture>> load(const CultureOptions& options,
                                                      const materials::Table& table,
                                                      const CultureFrame& frame);
  virtual ~Culture() = default;
  virtual const CultureStats& stats() const = 0;
  /// Fills `out` (vertices, indices, groups sorted by priority, square,
  /// half, material) with the skin and decals of one level. Leaves
  /// maxHeight and skirts to the caller. Thread-safe.
  virtual DecalStats decalLevel(const LevelLattice& lattice, module::Level& out) const = 0;
};

}  // namespace sandtable::convert
