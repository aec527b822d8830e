#pragma once
// Culture: 2-D vector features (roads, rivers, lakes, forest, land use,
// soil) read through OGR, classified by the material table, transformed
// into the database frame, repaired, and decaled onto the terrain
// triangles of one module level (seed chapter V, sections C, D and H;
// Figures 14-18). The pipeline and the renderer's contract for decals are
// in docs/CULTURE.md.
//
// Area classes become the skin: inside every grid triangle the skin
// polygons tile the triangle exactly, the highest-rank class winning where
// features overlap and the table's default area class filling the rest.
// Line classes are widened to their width with mitred or bevelled joins and
// flat ends (one exact CGAL union per feature, at load, so bends have
// neither gaps nor overlapping wedges), united per class and module, and
// cut to the triangles as decals at the class priority. Each module's
// partition into classes is computed once, exactly (CGAL arrangement and
// constrained triangulation into convex pieces), and reused by all its
// levels; the pieces are cut to each level's triangles in double precision
// (triangles no boundary crosses are single triangles). Every output
// vertex lies in its triangle's plane; vertices closer than the merge
// tolerance (seed: 0.1 m) are merged without leaving the triangle's edges.
#include <time.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "sandtable/formats/materials.h"
#include "sandtable/formats/module.h"
#include "sandtable/meshing/lattice.h"
#include "sandtable/base/result.h"

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
  std::vector<std::string> sources;  ///< any OGR vector source (files; .osm/.osm.gz/.pbf, .zip too)
  double mergeTolerance = 0.1;       ///< metres (seed: 0.1 m)
  /// Culture vertices are placed on multiples of this in module
  /// coordinates (metres; a power of two from 2^-20 to 1, or 0 for float
  /// precision) wherever the level's lattice lines are on it, so the
  /// module format stores them as small integers (docs/CULTURE.md,
  /// "Vertex step"). 2^-7 m = 7.8 mm, under a tenth of the seed's merge
  /// tolerance (2^-5 moved decal areas by more than 0.1%).
  double vertexStep = 1.0 / 128.0;
  int threads = 0;                   ///< widening at load; 0 = all cores
  /// Module partitions kept between decalLevel calls (one per module, all
  /// levels share it); 0 = four per hardware thread. Call every level of a
  /// module before moving on, as buildModules does, so each is built once.
  std::size_t cacheModules = 0;
  /// Size rule for line features (docs/CULTURE.md, "Bounded work"): the
  /// centreline is simplified (Douglas-Peucker) at max(mergeTolerance,
  /// width / 100); if a feature still has more vertices than this, the
  /// tolerance is doubled until it fits (counted in CultureStats::coarsened).
  std::size_t maxLineVertices = 20000;
  /// fraction in [0, 1] of loading, and the stage ("reading culture",
  /// "widening lines"), from load's threads, one call at a time. May be empty.
  std::function<void(double, const std::string&)> progress;
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

/// Features load dropped, repaired, defaulted or ignored for one reason
/// (docs/CULTURE.md, "What load reports"): nothing is lost in silence.
struct ReasonStats {
  std::uint64_t count = 0;
  std::string action;    ///< "dropped", "repaired", "defaulted" or "ignored"
  std::string text;      ///< the reason in words
  std::string sample;    ///< the first such feature: "SOURCE layer L feature FID"
  bool warning = true;   ///< false for the expected ones: outside the database, an ignore rule
};

struct CultureStats {
  std::map<std::string, ClassStats> perClass;  ///< by class name
  /// By reason key (unmatched_line, no_rule_default, self_intersecting_line,
  /// outside, ...; the list is in docs/CULTURE.md). A feature counts once per
  /// reason that applies to it.
  std::map<std::string, ReasonStats> reasons;
  std::uint64_t featuresRead = 0;  ///< line and area features (points are not culture)
  std::uint64_t pointsPlaced = 0;  ///< point features a `place` line matched, inside the database
  std::uint64_t buildings = 0;     ///< footprints of extruded classes kept as buildings
  std::uint64_t featuresLanded = 0;   ///< of those, on the database (kept, or default-class areas inside it)
  std::uint64_t featuresOutside = 0;  ///< of those, wholly outside the database (dropped, not a warning)
  std::uint64_t lineVerticesRead = 0;  ///< centreline vertices of the kept line features, as read (clipped)
  std::uint64_t lineVerticesKept = 0;  ///< and after simplification (what is widened)
  std::uint64_t coarsened = 0;  ///< line features simplified beyond the base tolerance to fit maxLineVertices
  std::uint64_t ignored = 0;       ///< matched an ignore rule ("-"), or an unmatched line with default-line none
  std::uint64_t warnings = 0;      ///< defaulted, repaired and dropped features (unmatched lines too), unreadable layers
  std::vector<std::string> messages;  ///< first few warnings, for the report
  double seconds = 0;              ///< wall time of load()
};

/// Counts from decaling one module level.
struct DecalStats {
  std::uint64_t skinPolygons = 0;   ///< polygons (before triangulation) in the skin
  std::uint64_t decalPolygons = 0;  ///< decal polygons
  std::uint64_t triangles = 0;
  std::uint64_t slowTriangles = 0;  ///< grid triangles a culture boundary crosses (cut, not one triangle)
  std::uint64_t unmerged = 0;       ///< point pairs left closer than the merge tolerance (a merge would fold a polygon)
  /// Never expected: the module's exact partition failed (default skin, no
  /// decals), or a triangle's cut skin did not tile it (it keeps one skin
  /// triangle).
  std::uint64_t failures = 0;
  /// Extruded footprints drawn on this level (docs/CULTURE.md,
  /// "Buildings"), and the wall and roof triangles they added.
  std::uint64_t buildings = 0, buildingTriangles = 0;
  /// CPU seconds of the calling thread (threadCpuSeconds) spent in this
  /// call, by stage, for the build's profile (docs/CULTURE.md, "Profile").
  /// The partition is built by the first call for a module; a call that
  /// waited for another thread's partition counts none of it.
  double partitionSeconds = 0;    ///< the module's partition, all of it:
  double gatherSeconds = 0;       ///<   candidate features clipped to the module
  double arrangementSeconds = 0;  ///<   the CGAL arrangement and its face windings
  double piecesSeconds = 0;       ///<   label boundaries, constrained triangulation, convex pieces
  double cutSeconds = 0;          ///< cutting to this level's triangles, merging, writing
};

/// CPU time of the calling thread, seconds (CLOCK_THREAD_CPUTIME_ID): stage
/// timers that a machine shared with other work does not inflate.
inline double threadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

/// One module level's lattice (sandtable/meshing/lattice.h): the decaler's
/// input.
using meshing::LevelLattice;

/// A point feature that a `place` line of the material table matched, in
/// the database frame (metres east and south of the north-west post).
struct PointFeature {
  double x = 0, z = 0;
  std::uint32_t place = 0;  ///< index into Table::places
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
  /// Point features matched by `place` lines, inside the database, in read order.
  virtual const std::vector<PointFeature>& points() const = 0;
  /// Fills `out` (vertices, indices, groups sorted by priority, square,
  /// half, material; spacing and squares counts) with the skin and decals
  /// of one level, replacing what it held. Leaves maxHeight, skirtDepth and
  /// skirts to the caller. The first vertices are the lattice posts, row
  /// by row ((squaresX + 1) * (squaresZ + 1), y = the lattice height bit for
  /// bit), shared by every skin triangle with a corner there. Triangles are
  /// counter-clockwise seen from above (+y). Thread-safe.
  virtual DecalStats decalLevel(const LevelLattice& lattice, module::Level& out) const = 0;
};

}  // namespace sandtable::convert
