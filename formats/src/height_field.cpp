// The terrain's posts behind an interface (height_field.h).
#include "sandtable/formats/height_field.h"

#include <algorithm>
#include <cmath>

#include "sandtable/formats/terrain_rule.h"

namespace sandtable::grid {

std::uint64_t HeightField::subscribe(ChangeFn fn) const {
  std::lock_guard lock(listenersMutex_);
  const std::uint64_t token = nextToken_++;
  listeners_.emplace_back(token, std::move(fn));
  return token;
}

void HeightField::unsubscribe(std::uint64_t token) const {
  std::lock_guard lock(listenersMutex_);
  std::erase_if(listeners_, [token](const auto& l) { return l.first == token; });
}

void HeightField::notifyChanged(const HeightChange& change) const {
  std::lock_guard lock(listenersMutex_);
  for (const auto& [token, fn] : listeners_) fn(change);
}

namespace {

PostLayout layoutOf(const GridFile& g) {
  const Header& h = g.header();
  return {h.postsX, h.postsZ, h.spacing, h.originEasting, h.originNorthing};
}

}  // namespace

GridHeightField::GridHeightField(std::shared_ptr<const GridFile> grid)
    : owned_(std::move(grid)), grid_(owned_.get()), layout_(layoutOf(*grid_)) {}

GridHeightField::GridHeightField(const GridFile& grid) : grid_(&grid), layout_(layoutOf(grid)) {}

std::pair<float, float> GridHeightField::elevationBounds() const {
  return {grid_->header().minElevation, grid_->header().maxElevation};
}

std::shared_ptr<const HeightField> heightField(std::shared_ptr<const GridFile> grid) {
  if (!grid) return nullptr;
  return std::make_shared<const GridHeightField>(std::move(grid));
}


double refinedHeight(const RefinedSquare& r, double fx, double fz, bool& inside) {
  const double u = std::clamp(fx, 0.0, 1.0) * double(r.cells), v = std::clamp(fz, 0.0, 1.0) * double(r.cells);
  inside = u >= double(r.a0) && u <= double(r.a1) && v >= double(r.b0) && v <= double(r.b1);
  if (!inside) return 0;
  // The fine square holding (u, v), the last one on the patch's far edges.
  const auto a = std::min(std::uint32_t(std::floor(u)), r.a1 - 1);
  const auto b = std::min(std::uint32_t(std::floor(v)), r.b1 - 1);
  return terrain::planeHeight(u - double(a), v - double(b), double(r.at(a, b)), double(r.at(a + 1, b)),
                              double(r.at(a, b + 1)), double(r.at(a + 1, b + 1)));
}

}  // namespace sandtable::grid
