#pragma once
// Queries on the terrain skin that the renderer draws: elevation on the grid
// triangles (seed Figure 22) and the material under a point.
//
// Each grid square is split along its south-west to north-east diagonal
// into an upper (north-west) triangle NW-NE-SW and a lower (south-east)
// triangle NE-SE-SW. The renderer's triangle strips produce exactly these
// triangles, so sampled elevations lie on the drawn surface.
//
// The posts come from a HeightField (formats/height_field.h): the grid
// file, or a field that changes (dynamic terrain). A sample reads the posts
// as they are at the time of the call.
//
// Thread safety: every method is const and thread-safe (the HeightField's
// contract: a sample taken while a change is written may mix old and new
// posts of that change).
#include <cstdint>
#include <memory>
#include <optional>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/height_field.h"

namespace sandtable::world {

struct TerrainSample {
  double elevation = 0;       ///< metres above the vertical datum
  std::uint8_t material = 0;  ///< material index of the nearest post
  bool upperTriangle = true;  ///< true in the NW triangle of the square
};

class Terrain {
 public:
  explicit Terrain(std::shared_ptr<const grid::HeightField> heights);
  /// Over the grid file's posts (a GridHeightField).
  explicit Terrain(std::shared_ptr<const grid::GridFile> grid);

  /// Sample at projected coordinates; nullopt outside the grid.
  std::optional<TerrainSample> sampleEN(double easting, double northing) const;
  /// Sample at world X (east of origin) and Z (south of origin) in metres.
  std::optional<TerrainSample> sampleXZ(double x, double z) const;

  const grid::HeightField& heights() const { return *grid_; }
  const std::shared_ptr<const grid::HeightField>& heightsPtr() const { return grid_; }
  double widthMetres() const { return grid_->spacing() * (grid_->postsX() - 1); }
  double depthMetres() const { return grid_->spacing() * (grid_->postsZ() - 1); }

 private:
  std::shared_ptr<const grid::HeightField> grid_;
};

}  // namespace sandtable::world
