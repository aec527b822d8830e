#include "sandtable/world/ground.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace sandtable::runtime {
namespace {

/// One lattice interval [a, b] of grid posts holding post coordinate u.
struct Interval {
  std::uint32_t a = 0, b = 0;
  double f = 0;  ///< (u - a) / (b - a)
};

/// The interval of a level's lattice (step `step` from the module's first
/// post `first`, and the module's last post `last`) that holds u.
Interval intervalOf(double u, std::uint32_t first, std::uint32_t last, std::uint32_t step) {
  Interval iv;
  const double k = std::floor((u - first) / step);
  std::uint32_t a = first + static_cast<std::uint32_t>(std::max(0.0, k)) * step;
  if (a >= last) a = first + ((last - first - 1) / step) * step;
  iv.a = a;
  iv.b = std::min(a + step, last);
  iv.f = std::clamp((u - a) / double(iv.b - a), 0.0, 1.0);
  return iv;
}

/// Barycentric weights of (fx, fz) over a square's corners NW, NE, SW, SE
/// split along the SW-NE diagonal (terrain.h).
std::array<double, 4> cornerWeights(double fx, double fz) {
  if (fx + fz <= 1.0) return {1.0 - fx - fz, fx, fz, 0.0};
  return {0.0, 1.0 - fz, 1.0 - fx, fx + fz - 1.0};
}

}  // namespace

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
  const auto firstPost = [&](double w, std::uint32_t maxPost) {
    const auto k = std::min(static_cast<std::uint32_t>(w / squares), (maxPost - 1) / squares);
    return k * squares;
  };
  const std::uint32_t i0 = firstPost(u, maxI), j0 = firstPost(v, maxJ);
  const Interval ix = intervalOf(u, i0, std::min(i0 + squares, maxI), step);
  const Interval iz = intervalOf(v, j0, std::min(j0 + squares, maxJ), step);
  Square q;
  q.weights = cornerWeights(ix.f, iz.f);
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

}  // namespace sandtable::runtime
