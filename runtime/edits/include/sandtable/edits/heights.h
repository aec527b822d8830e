#pragma once
// The heights overlay (dynamic terrain, issue 37; docs/DYNAMIC.md, "Heights
// overlay"): a HeightField over a base HeightField (the memory-mapped grid)
// that crater, berm, ditch and flatten edits change.
//
// Posts: sparse tiles of 64 x 64 posts (the grid's blocks) hold float
// deltas over the base's elevations and the normals recomputed at edited
// posts and their neighbours by the build's rule (grid::postNormal).
// Materials are the base's. Each tile has a generation (regionGeneration).
//
// Sub-post detail: an edit whose features are smaller than two posts
// (profile.h, refineCells) refines the grid squares its support touches
// into RefinedSquare patches (height_field.h): the patch carries the edit
// at the fine posts, the square's planes carry the rest. An edit the posts
// carry changes posts only; the fine posts of a refined square it touches
// ride on the change of the square's planes. docs/DYNAMIC.md gives the
// rules, and why there is no step at a patch's border or between squares.
//
// Determinism: apply() is a function of the edit and the heights under it,
// computed in a fixed order with no fused multiply-add (built
// -ffp-contract=off, as profile.cpp): the same edits in the same order give
// bit-identical heights in any process, and the same contentHash().
//
// Thread contract: height_field.h's. One writer calls apply() (it takes a
// lock, so a second writer waits rather than races); any number of readers
// call the const queries meanwhile, lock-free but for refined() of a
// refined square (a per-tile lock held for a search and a reference count).
// A change writes its posts (atomically, per value: a reader never sees
// half a float or half a normal; a reader that sees a post of a change
// sees the bounds that hold it), publishes its patches as new
// shared_ptr<const RefinedSquare> (the old ones stay valid for whoever
// holds them), then bumps the tile and field generations (release), then
// notifies listeners on the writer's thread with the writer's lock held:
// a listener must not call apply().
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/edit.h"
#include "sandtable/formats/height_field.h"

namespace sandtable::edits {

/// A grid square, named by its north-west post; ordered row by row (j, then i).
struct SquareIndex {
  std::uint32_t i = 0, j = 0;
  bool operator==(const SquareIndex&) const = default;
  auto operator<=>(const SquareIndex& o) const { return j != o.j ? j <=> o.j : i <=> o.i; }
};

/// What one apply() changed.
struct HeightsChange {
  /// Grid posts whose elevation or normal changed (a bounding rectangle;
  /// empty when no post changed).
  grid::PostRect posts;
  /// Refined squares published anew (new, grown, finer or with new
  /// heights), in (j, i) order.
  std::vector<SquareIndex> squares;
  /// `posts` and the corner posts of every square in `squares`: the
  /// rectangle listeners were told and regionGeneration covers.
  grid::PostRect region;
  /// The change's generation; 0 when the edit changed nothing (no
  /// generation, no notification).
  std::uint64_t generation = 0;
  bool empty() const { return generation == 0; }
};

/// The overlay's size, for tests and benchmarks.
struct HeightsStats {
  std::size_t tiles = 0;           ///< tiles holding post deltas
  std::size_t refinedSquares = 0;  ///< squares with a patch
  std::uint64_t finePosts = 0;     ///< fine posts over every patch
  std::size_t bytes = 0;           ///< memory the overlay holds (tables, tiles, patches), bytes
};

class EditedHeights final : public grid::HeightField {
 public:
  /// An overlay over `base` with no edits: it reads exactly as `base`.
  explicit EditedHeights(std::shared_ptr<const grid::HeightField> base);
  ~EditedHeights() override;

  const grid::HeightField& base() const { return *base_; }

  /// Applies a crater, berm, ditch or flatten. Errors (nothing changes):
  /// an invalid edit (edit::checkEdit's message), a kind that does not
  /// change heights, a support wholly outside the grid. Writer only.
  Result<HeightsChange> apply(const edit::Edit& e);

  /// Back to the base's heights: every delta, normal and patch dropped
  /// (the editor re-applies its edits in key order after an edit arrived
  /// out of order). Bounds stay as wide as they were. Writer only; the
  /// change covers every post and square that was edited.
  HeightsChange reset();

  /// A 64-bit hash of every edited post's delta and every patch, in grid
  /// order: equal in two processes that applied the same edits in the same
  /// order. Any thread.
  std::uint64_t contentHash() const;
  /// Counts and memory now. Any thread.
  HeightsStats stats() const;

  // grid::HeightField
  const grid::PostLayout& layout() const override { return base_->layout(); }
  float elevation(std::uint32_t i, std::uint32_t j) const override;
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const override;
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const override { return base_->material(i, j); }
  std::pair<float, float> elevationBounds() const override;
  std::uint64_t generation() const override { return generation_.load(std::memory_order_acquire); }
  std::uint64_t regionGeneration(const grid::PostRect& posts) const override;
  std::shared_ptr<const grid::RefinedSquare> refined(std::uint32_t i, std::uint32_t j) const override;
  bool anyRefined() const override { return anyRefined_.load(std::memory_order_acquire); }

 private:
  struct Tile;  // heights.cpp
  struct Plan;
  const Tile* tileAt(std::uint32_t i, std::uint32_t j) const;
  Tile& tileForWrite(std::uint32_t i, std::uint32_t j);
  void publish(Plan& plan, HeightsChange& out);

  std::shared_ptr<const grid::HeightField> base_;
  std::uint32_t tilesX_ = 0, tilesZ_ = 0;
  /// Dense table of tiles (null: never edited), and each tile's generation.
  std::unique_ptr<std::atomic<Tile*>[]> tiles_;
  std::unique_ptr<std::atomic<std::uint64_t>[]> tileGenerations_;
  std::atomic<std::uint64_t> generation_{0};
  std::atomic<bool> anyRefined_{false};
  std::atomic<float> minElevation_{0}, maxElevation_{0};
  std::mutex writer_;
};

}  // namespace sandtable::edits
