#include "sandtable/world/terrain.h"

#include <algorithm>
#include <cmath>

#include "sandtable/formats/terrain_rule.h"

namespace sandtable::world {

Terrain::Terrain(std::shared_ptr<const grid::HeightField> heights) : grid_(std::move(heights)) {}

Terrain::Terrain(std::shared_ptr<const grid::GridFile> grid) : Terrain(grid::heightField(std::move(grid))) {}

std::optional<TerrainSample> Terrain::sampleEN(double easting, double northing) const {
  return sampleXZ(easting - grid_->originEasting(), grid_->originNorthing() - northing);
}

std::optional<TerrainSample> Terrain::sampleXZ(double x, double z) const {
  const double s = grid_->spacing();
  const double u = x / s, v = z / s;
  const auto maxI = static_cast<double>(grid_->postsX() - 1);
  const auto maxJ = static_cast<double>(grid_->postsZ() - 1);
  // A small tolerance keeps points on the far edges inside.
  constexpr double eps = 1e-9;
  if (!(u >= -eps && v >= -eps && u <= maxI + eps && v <= maxJ + eps)) return std::nullopt;
  const terrain::SquarePoint q = terrain::squareAt(u, v, grid_->postsX(), grid_->postsZ());
  const std::uint32_t i = q.i, j = q.j;
  const double nw = grid_->elevation(i, j), ne = grid_->elevation(i + 1, j);
  const double sw = grid_->elevation(i, j + 1), se = grid_->elevation(i + 1, j + 1);
  TerrainSample out;
  out.upperTriangle = terrain::halfAt(q.fx, q.fz) == module::Half::upper;
  out.elevation = terrain::planeHeight(q.fx, q.fz, nw, ne, sw, se);
  // A refined square (a crater smaller than a post) is its fine lattice
  // inside the patch's rectangle, its planes outside it.
  if (grid_->anyRefined()) {
    if (const auto r = grid_->refined(i, j)) {
      bool inside = false;
      const double h = grid::refinedHeight(*r, q.fx, q.fz, inside);
      if (inside) out.elevation = h;
    }
  }
  const auto ni = static_cast<std::uint32_t>(std::lround(std::clamp(u, 0.0, maxI)));
  const auto nj = static_cast<std::uint32_t>(std::lround(std::clamp(v, 0.0, maxJ)));
  out.material = grid_->material(ni, nj);
  return out;
}

}  // namespace sandtable::world
