#include "sandtable/world/ground.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "sandtable/formats/terrain_rule.h"

namespace sandtable::world {

GroundClamp::GroundClamp(std::shared_ptr<const grid::HeightField> heights, std::uint32_t moduleSquares,
                         std::uint32_t levels)
    : grid_(std::move(heights)), squares_(moduleSquares), levels_(moduleSquares ? std::max(1u, levels) : 1u) {}

GroundClamp::GroundClamp(std::shared_ptr<const grid::GridFile> grid, std::uint32_t moduleSquares,
                         std::uint32_t levels)
    : GroundClamp(grid::heightField(std::move(grid)), moduleSquares, levels) {}

GroundClamp::Square GroundClamp::squareAt(std::uint32_t level, double x, double z) const {
  const grid::HeightField& g = *grid_;
  const double sp = g.spacing();
  const std::uint32_t maxI = g.postsX() - 1, maxJ = g.postsZ() - 1;
  const double u = std::clamp(x / sp, 0.0, double(maxI)), v = std::clamp(z / sp, 0.0, double(maxJ));
  const std::uint32_t squares = squares_ ? squares_ : std::max(maxI, maxJ);
  const std::uint32_t step = 1u << std::min(level, 30u);
  const std::uint32_t i0 = terrain::moduleFirstPost(u, squares, maxI);
  const std::uint32_t j0 = terrain::moduleFirstPost(v, squares, maxJ);
  const terrain::LatticeSpan ix = terrain::latticeSpan(u, i0, terrain::moduleLastPost(i0, squares, maxI), step);
  const terrain::LatticeSpan iz = terrain::latticeSpan(v, j0, terrain::moduleLastPost(j0, squares, maxJ), step);
  Square q;
  q.weights = terrain::cornerWeights(ix.fraction(u), iz.fraction(v));
  q.i = {ix.a, ix.b, ix.a, ix.b};
  q.j = {iz.a, iz.a, iz.b, iz.b};
  return q;
}

double GroundClamp::latticeHeight(std::uint32_t level, double x, double z) const {
  const Square q = squareAt(level, x, z);
  double h = 0;
  for (int c = 0; c < 4; ++c) h += q.weights[c] * grid_->elevation(q.i[c], q.j[c]);
  return h;
}

std::optional<double> GroundClamp::surfaceXZ(double x, double z, DrawnLevel drawn) const {
  const double s = grid_->spacing();
  constexpr double eps = 1e-9;  // as Terrain::sampleXZ: the far edges are inside
  const double u = x / s, v = z / s;
  if (!(u >= -eps && v >= -eps && u <= grid_->postsX() - 1 + eps && v <= grid_->postsZ() - 1 + eps)) {
    return std::nullopt;
  }
  const std::uint32_t level = std::min(drawn.level, levels_ - 1);
  const Square q = squareAt(level, x, z);
  double here = 0, next = 0;
  const bool morphs = drawn.morph > 0 && level + 1 < levels_;
  for (int c = 0; c < 4; ++c) {
    if (q.weights[c] == 0) continue;
    here += q.weights[c] * grid_->elevation(q.i[c], q.j[c]);
    if (morphs) next += q.weights[c] * latticeHeight(level + 1, q.i[c] * s, q.j[c] * s);
  }
  // Level 0 draws a refined square's patch (dynamic terrain); the coarser
  // levels draw their lattices (docs/DYNAMIC.md, "Edits smaller than a post").
  if (level == 0 && grid_->anyRefined()) {
    if (const auto r = grid_->refined(q.i[0], q.j[0])) {
      bool inside = false;
      const double h = grid::refinedHeight(*r, (u - q.i[0]), (v - q.j[0]), inside);
      if (inside) here = h;
    }
  }
  if (!morphs) return here;
  const double m = std::clamp(double(drawn.morph), 0.0, 1.0);
  return (1.0 - m) * here + m * next;
}

std::optional<double> GroundClamp::surfaceEN(double easting, double northing, DrawnLevel drawn) const {
  return surfaceXZ(easting - grid_->originEasting(), grid_->originNorthing() - northing, drawn);
}

double GroundClamp::groundEN(double easting, double northing) {
  if (auto h = surfaceEN(easting, northing, drawn_)) last_ = *h;
  return last_;
}

double GroundClamp::eyeElevation(double ground, double heightAgl, std::optional<double> altitude,
                                 double minAgl) {
  if (altitude) return std::max(*altitude, ground + minAgl);
  return ground + std::max(heightAgl, minAgl);
}

}  // namespace sandtable::world
