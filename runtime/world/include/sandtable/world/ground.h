#pragma once
// The one ground clamp (seed Figure 23: no flying tanks, no tunnelling
// aircraft). Whatever stands on or flies over the terrain takes its ground
// from the surface that is DRAWN there, not from the finest grid: a load
// module drawn at level l shows the lattice of every 2^l-th post (docs/
// FORMAT.md, load modules), morphed by m towards level l + 1 (lod.h), and
// an eye 2 m above the finest grid would sit inside a coarse hill.
//
// Surface of level l at (x, z): the module's level-l lattice (posts
// i0, i0 + 2^l, ... and the module's last post; the same rows), each
// square split along its SW-NE diagonal as the grid's are (terrain.h).
// Morphed: every lattice vertex moves by m times the gap to level l + 1's
// surface under it, and the triangle between stays planar, so the height
// is (1 - m) h_l + m * (level-l interpolation of h_{l+1} at its corners).
// Level 0 with no morph is the grid itself (Terrain::sampleXZ).
//
// The lattice rule must match the module builder's (meshing/); the end-
// to-end test GroundClamp.* compares this clamp against the built modules.
//
// The posts come from a HeightField (formats/height_field.h), read at the
// time of each query, so a changed patch is under the next query.
//
// Thread safety: surface*() are const and thread-safe. ground*() and
// setDrawn() keep state (the last ground seen, the level drawn under the
// eye): one GroundClamp per main thread.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/height_field.h"

namespace sandtable::world {

/// What is drawn at a point: a module level and its morph towards the next.
struct DrawnLevel {
  std::uint32_t level = 0;
  float morph = 0;  ///< 0 = this level, 1 = the next coarser one
};

class GroundClamp {
 public:
  /// `moduleSquares` (pack::IndexHeader) = 0 or `levels` = 1: the grid
  /// mesh is drawn, every level is level 0.
  explicit GroundClamp(std::shared_ptr<const grid::HeightField> heights, std::uint32_t moduleSquares = 0,
                       std::uint32_t levels = 1);
  /// Over the grid file's posts (a GridHeightField).
  explicit GroundClamp(std::shared_ptr<const grid::GridFile> grid, std::uint32_t moduleSquares = 0,
                       std::uint32_t levels = 1);

  /// Height of the surface drawn as `drawn` at world (x east, z south of
  /// the grid origin), metres; nullopt off the grid.
  std::optional<double> surfaceXZ(double x, double z, DrawnLevel drawn = {}) const;
  /// The same at projected (easting, northing).
  std::optional<double> surfaceEN(double easting, double northing, DrawnLevel drawn = {}) const;

  /// The level drawn under the eye; the flight sets it after each
  /// selection, the ground queries below use it.
  void setDrawn(DrawnLevel d) { drawn_ = d; }
  DrawnLevel drawn() const { return drawn_; }

  /// Ground under (easting, northing) at the drawn level. Off the grid:
  /// the last ground returned, so flying past the edge neither drops nor
  /// lifts the eye (0 before any).
  double groundEN(double easting, double northing);
  /// Remembers `ground` as the last ground seen (a caller that sampled it).
  void holdGround(double ground) { last_ = ground; }
  double lastGround() const { return last_; }

  /// The eye's elevation over `ground`: ground following (no altitude)
  /// puts it max(heightAgl, minAgl) above; free flight keeps `altitude`
  /// but never lower than minAgl above the ground.
  static double eyeElevation(double ground, double heightAgl, std::optional<double> altitude,
                             double minAgl);

  std::uint32_t levels() const { return levels_; }

 private:
  /// The level-`level` lattice square holding (x, z): its corners' grid
  /// posts (NW, NE, SW, SE) and their barycentric weights.
  struct Square {
    std::array<double, 4> weights{};
    std::array<std::uint32_t, 4> i{}, j{};
  };
  Square squareAt(std::uint32_t level, double x, double z) const;
  double latticeHeight(std::uint32_t level, double x, double z) const;

  std::shared_ptr<const grid::HeightField> grid_;
  std::uint32_t squares_ = 0, levels_ = 1;
  DrawnLevel drawn_;
  double last_ = 0;
};

}  // namespace sandtable::world
