#pragma once
// A load module, version 1 (docs/FORMAT.md, "module"): one square of the
// database (seed chapter V.H: 1 km by default) holding, for each level of
// detail, everything the renderer and simulator need with no further
// computation: vertices, triangle indices grouped by grid square and
// priority (seed Figure 29's count and index arrays), material ids, texture
// coordinates, the highest vertex of each grid square, and skirts that hide
// cracks between modules and between levels.
//
// Frames. Vertex positions are module-local: x east and z south of the
// module's north-west corner, y up (metres above the vertical datum). The
// module's north-west corner lies at world X = kx * edge, Z = kz * edge,
// where edge = squares * spacing (manifest `module_size_m`).
//
// Grid triangles (seed Figures 14, 15). Every grid square is split along
// its SW-NE diagonal into the upper triangle (NW, NE, SW corners; the half
// that holds the NW corner) and the lower triangle (NE, SE, SW corners).
// This is the same diagonal the runtime sampler interpolates on.
//
// Levels. Level 0 is the finest and uses the grid spacing; level l uses
// posts every 2^l grid posts. A level's lattice is indexed by post columns
// and rows of the grid, clamped at the database's east and south edges, so
// a module at the edge may have narrower last squares at coarse levels.
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sandtable/formats/result.h"

namespace sandtable::module {

inline constexpr std::array<char, 8> kMagic = {'S', 'A', 'N', 'D', 'M', 'O', 'D', '1'};
inline constexpr std::uint32_t kVersion = 1;

/// Which part of a grid square a group of triangles belongs to.
enum class Half : std::uint8_t {
  upper = 0,  ///< NW, NE, SW corners
  lower = 1,  ///< NE, SE, SW corners
  skirt = 2,  ///< vertical seam skirt along a module edge (not in a grid triangle)
};

/// Draw priorities (seed Figure 18).
inline constexpr std::uint8_t kPrioritySkin = 1;
inline constexpr std::uint8_t kPriorityRoad = 10;
inline constexpr std::uint8_t kPriorityObject = 99;

struct Vertex {
  float x = 0, y = 0, z = 0;  ///< module-local metres (x east, y up, z south)
  float s = 0, t = 0;         ///< texture coordinates (roads: S along, T across, seed Figure 17)
};

/// One run of triangles with one material, priority and grid triangle.
struct Group {
  std::uint32_t square = 0;      ///< row-major square index in the level: sz * squaresX + sx
  Half half = Half::upper;
  std::uint8_t priority = kPrioritySkin;
  std::uint16_t material = 0;    ///< class id from the material table
  std::uint32_t firstIndex = 0;  ///< into Level::indices
  std::uint32_t indexCount = 0;  ///< a multiple of 3 (triangle list)
};

struct Level {
  double spacing = 0;               ///< nominal post spacing of this level, metres
  std::uint32_t squaresX = 0;       ///< squares across (may be fewer at the east edge)
  std::uint32_t squaresZ = 0;
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;
  /// Sorted by (priority, square, half, material): draw in order for
  /// priority order (skin first, roads last).
  std::vector<Group> groups;
  /// Highest vertex y in each square (skin and decals), row-major.
  std::vector<float> maxHeight;
  float skirtDepth = 0;  ///< how far skirts hang below the edge vertices, metres
};

struct Module {
  std::uint32_t kx = 0;  ///< column of the module, from the west edge
  std::uint32_t kz = 0;  ///< row of the module, from the north edge
  std::vector<Level> levels;  ///< [0] is the finest
};

/// Uncompressed bytes of a module (little-endian, layout in docs/FORMAT.md).
std::vector<std::byte> encode(const Module& m);
/// Decodes and checks structure: counts within the bytes, indices within
/// the vertices, groups within the indices. Never over-allocates: every
/// count is checked against the bytes that remain before anything is sized.
/// `file` and `baseOffset` name where the bytes came from in problems.
Result<Module> decode(std::span<const std::byte> bytes, const std::string& file,
                      std::uint64_t baseOffset = 0);

}  // namespace sandtable::module
