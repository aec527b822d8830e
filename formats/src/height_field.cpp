// The terrain's posts behind an interface (height_field.h).
#include "sandtable/formats/height_field.h"

#include <algorithm>

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

}  // namespace sandtable::grid
