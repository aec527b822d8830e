#include "sandtable/world/terrain.h"

#include <algorithm>
#include <cmath>

namespace sandtable::runtime {

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
  const double uc = std::clamp(u, 0.0, maxI), vc = std::clamp(v, 0.0, maxJ);
  const auto i = static_cast<std::uint32_t>(std::min(std::floor(uc), maxI - 1));
  const auto j = static_cast<std::uint32_t>(std::min(std::floor(vc), maxJ - 1));
  const double fx = uc - i, fz = vc - j;
  const double nw = grid_->elevation(i, j), ne = grid_->elevation(i + 1, j);
  const double sw = grid_->elevation(i, j + 1), se = grid_->elevation(i + 1, j + 1);
  TerrainSample out;
  out.upperTriangle = fx + fz <= 1.0;
  out.elevation = out.upperTriangle ? nw + fx * (ne - nw) + fz * (sw - nw)
                                    : se + (1.0 - fx) * (sw - se) + (1.0 - fz) * (ne - se);
  const auto ni = static_cast<std::uint32_t>(std::lround(uc));
  const auto nj = static_cast<std::uint32_t>(std::lround(vc));
  out.material = grid_->material(ni, nj);
  return out;
}

}  // namespace sandtable::runtime
