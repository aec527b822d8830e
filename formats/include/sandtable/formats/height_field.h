#pragma once
// The terrain's posts as an interface that can change (issue 34 item 3;
// dynamic terrain, issue 37, raises berms and digs craters while the viewer
// flies and the simulator drives). Every reader of elevation, normal or
// material at run time (GroundClamp, Terrain, SimWorld, the module
// assembly, the renderer's normal and water sampling, mesh mode, the map)
// reads a HeightField, never the grid file itself. The memory-mapped grid
// (GridFile) is one implementation (GridHeightField, which never changes);
// an overlay that changes posts is another.
//
// Posts and frame are the grid's (grid.h, docs/FORMAT.md): post (i, j) lies
// at world X = i * spacing east and Z = j * spacing south of the north-west
// post, easting originEasting + X, northing originNorthing - Z. The layout
// (post counts, spacing, origin) is fixed for a field's life; only the
// values at posts change. Interpolation between posts is the drawn
// surface's (the SW-NE split): Terrain::sampleXZ and GroundClamp (world)
// do it over these posts, so there is no second copy of that rule here.
//
// Generations: generation() counts changes, starting at 0 and never
// decreasing. regionGeneration(rect) is the generation of the newest
// change that touched any post of rect (0: never changed), so a reader
// that cached something derived from a rectangle compares one number to
// know whether to rebuild it.
//
// Thread contract: every query (elevation, normal, material, generation,
// regionGeneration, elevationBounds) is const and may be called from any
// thread at once. An implementation that changes posts writes them, then
// bumps its generations (release), then calls the listeners; a reader that
// sees generation g (acquire) sees every post of every change up to g.
// Posts read while a change is being written may mix old and new values of
// that change's rectangle: a reader that needs one version reads the
// rectangle's generation before and after and reads again when it moved.
// Listeners are called on the thread that made the change, after it is
// visible, one change at a time; they must be quick and must not subscribe
// or unsubscribe. subscribe/unsubscribe may be called from any thread.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "sandtable/formats/grid.h"

namespace sandtable::grid {

/// A rectangle of posts, half-open: i0 <= i < i1, j0 <= j < j1.
struct PostRect {
  std::uint32_t i0 = 0, j0 = 0, i1 = 0, j1 = 0;
  bool empty() const { return i0 >= i1 || j0 >= j1; }
  bool intersects(const PostRect& o) const {
    return !empty() && !o.empty() && i0 < o.i1 && o.i0 < i1 && j0 < o.j1 && o.j0 < j1;
  }
  bool contains(std::uint32_t i, std::uint32_t j) const { return i >= i0 && i < i1 && j >= j0 && j < j1; }
  bool operator==(const PostRect&) const = default;
};

/// One change: the posts whose elevation, normal or material changed and
/// the corner posts of every refined square whose patch changed (its
/// surface did; refined()), and the generation that holds them.
struct HeightChange {
  PostRect posts;
  std::uint64_t generation = 0;
};

/// Where the posts are: fixed for a field's life.
struct PostLayout {
  std::uint32_t postsX = 0, postsZ = 0;
  double spacing = 0;
  double originEasting = 0, originNorthing = 0;
};

/// Sub-post detail in one grid square (dynamic terrain: a crater smaller
/// than a post; docs/DYNAMIC.md). Square (i, j) (posts i..i+1, j..j+1) is
/// divided into `cells` x `cells` fine squares (a power of two, 2..256);
/// the patch holds fine posts a0..a1 (east) x b0..b1 (south), inclusive,
/// 0 <= a0 < a1 <= cells, row-major in `heights`. Inside that rectangle the
/// surface is the fine lattice, each fine square split SW-NE (the terrain
/// rule one step finer: the square's own diagonal runs along fine
/// diagonals, so every fine triangle lies in one half of the square);
/// outside it, the square's two planes over its corner posts. A fine post
/// on the rectangle's border that is not on the square's edge lies on those
/// planes, so the two surfaces meet without a step; along the square's
/// edges the neighbour square carries the same heights (its own patch, or
/// its planes where the patch's edge posts are on them).
/// The detail rectangle da0..da1 x db0..db1 (inside the patch's; unset,
/// da1 == 0, means the patch's own) holds every fine post that departs
/// from one pair of planes, the rest planes: each half of the square one
/// plane, through the square's corner posts where a corner lies outside
/// the detail rectangle. The patch is wider than its detail when a corner
/// post moved under it (a crater on a post): the square's planes moved, the
/// ground away from the crater did not, so the whole square is fine posts,
/// but a mesher draws those outside the detail as the rest planes.
/// Immutable once published: readers hold it by shared_ptr.
struct RefinedSquare {
  std::uint32_t i = 0, j = 0;
  std::uint32_t cells = 0;
  std::uint32_t a0 = 0, b0 = 0, a1 = 0, b1 = 0;
  std::uint32_t da0 = 0, db0 = 0, da1 = 0, db1 = 0;
  /// The detail rectangle {a0, b0, a1, b1}: the patch's own when unset.
  std::array<std::uint32_t, 4> detail() const {
    if (da1 > da0) return {da0, db0, da1, db1};
    return {a0, b0, a1, b1};
  }
  std::vector<float> heights;  ///< (b1 - b0 + 1) * (a1 - a0 + 1)
  std::uint64_t generation = 0;
  std::uint32_t width() const { return a1 - a0 + 1; }
  float at(std::uint32_t a, std::uint32_t b) const { return heights[std::size_t(b - b0) * width() + (a - a0)]; }
};

/// Height of `r`'s fine surface at fractions (fx, fz) in [0, 1] of its
/// square, or a negative `inside` when the point is outside the patch's
/// rectangle (the caller then uses the square's planes). The one place the
/// fine lattice is interpolated (Terrain::sampleXZ, the ground clamp, the
/// re-mesher's checks).
double refinedHeight(const RefinedSquare& r, double fx, double fz, bool& inside);

class HeightField {
 public:
  HeightField() = default;
  HeightField(const HeightField&) = delete;
  HeightField& operator=(const HeightField&) = delete;
  virtual ~HeightField() = default;

  virtual const PostLayout& layout() const = 0;
  std::uint32_t postsX() const { return layout().postsX; }
  std::uint32_t postsZ() const { return layout().postsZ; }
  double spacing() const { return layout().spacing; }
  double originEasting() const { return layout().originEasting; }
  double originNorthing() const { return layout().originNorthing; }
  /// The whole field as a rectangle.
  PostRect all() const { return {0, 0, postsX(), postsZ()}; }

  /// Elevation at post (i, j), metres; i < postsX, j < postsZ.
  virtual float elevation(std::uint32_t i, std::uint32_t j) const = 0;
  /// Unit normal at post (i, j) in the world frame (X east, Y up, Z south).
  virtual std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const = 0;
  /// Material index at post (i, j) (FORMAT.md: 0 ground, 1 water, 2 filled void).
  virtual std::uint8_t material(std::uint32_t i, std::uint32_t j) const = 0;
  /// Bounds of every post's elevation now: min <= every elevation <= max
  /// (not necessarily tight; the grid's are its header's).
  virtual std::pair<float, float> elevationBounds() const = 0;

  /// Changes so far; 0 for a field that never changed.
  virtual std::uint64_t generation() const = 0;
  /// The generation of the newest change that touched a post of `posts`;
  /// 0 when none did.
  virtual std::uint64_t regionGeneration(const PostRect& posts) const = 0;

  /// The refined patch of square (i, j) (i < postsX - 1, j < postsZ - 1),
  /// or null: the square is its two planes. A snapshot: a later change
  /// publishes a new patch and leaves this one valid.
  virtual std::shared_ptr<const RefinedSquare> refined(std::uint32_t /*i*/, std::uint32_t /*j*/) const {
    return nullptr;
  }
  /// False when no square is refined (readers skip the lookup); may turn
  /// true after a change, never back.
  virtual bool anyRefined() const { return false; }

  using ChangeFn = std::function<void(const HeightChange&)>;
  /// Calls `fn` after every later change until unsubscribe(token). Const:
  /// readers hold a const field and still listen.
  std::uint64_t subscribe(ChangeFn fn) const;
  void unsubscribe(std::uint64_t token) const;

 protected:
  /// For implementations: calls every listener with `change`, once the
  /// change's posts and generations are visible.
  void notifyChanged(const HeightChange& change) const;

 private:
  mutable std::mutex listenersMutex_;
  mutable std::vector<std::pair<std::uint64_t, ChangeFn>> listeners_;
  mutable std::uint64_t nextToken_ = 1;
};

/// The memory-mapped grid file as a HeightField: the file's posts, which
/// never change (generation 0 everywhere). The borrowing constructor keeps
/// no reference count: the grid must outlive the adapter.
class GridHeightField final : public HeightField {
 public:
  explicit GridHeightField(std::shared_ptr<const GridFile> grid);
  explicit GridHeightField(const GridFile& grid);

  const GridFile& grid() const { return *grid_; }

  const PostLayout& layout() const override { return layout_; }
  float elevation(std::uint32_t i, std::uint32_t j) const override { return grid_->elevation(i, j); }
  std::array<float, 3> normal(std::uint32_t i, std::uint32_t j) const override { return grid_->normal(i, j); }
  std::uint8_t material(std::uint32_t i, std::uint32_t j) const override { return grid_->material(i, j); }
  std::pair<float, float> elevationBounds() const override;
  std::uint64_t generation() const override { return 0; }
  std::uint64_t regionGeneration(const PostRect&) const override { return 0; }

 private:
  std::shared_ptr<const GridFile> owned_;
  const GridFile* grid_ = nullptr;
  PostLayout layout_;
};

/// A shared GridHeightField over `grid` (null for a null grid).
std::shared_ptr<const HeightField> heightField(std::shared_ptr<const GridFile> grid);

}  // namespace sandtable::grid
