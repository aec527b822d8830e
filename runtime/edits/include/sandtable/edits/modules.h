#pragma once
// Re-meshed load modules (docs/DYNAMIC.md, "Re-meshing"): the modules as
// built (the pack) with every module that an edit touched rebuilt from the
// edited heights, at every level, and published as a newer generation
// through the pager's ModuleSource contract (module_source.h).
//
// A module is touched by a change when its level-0 window (posts
// kx * squares .. kx * squares + squares, both ends: edge posts are shared,
// so both neighbours) holds a changed post, or holds a changed refined
// square or the square beside one (a refined square's fine edge depends on
// its neighbours). A touched module is rebuilt from its base module (read
// once from the base source and kept decoded) and the edited heights:
//  - every skin, decal and object vertex where its level's lattice plane
//    moved (terrain_rule.h's halfPlane on the group's half for skin and
//    decals, planeHeight at the point for objects) follows it: a vertex on
//    the old ground but for the pack's height rounding goes exactly onto
//    the new ground (moving it by the change would carry the rounding into
//    the next encoding, up to a whole step off), any other moves by the
//    change; where the plane did not move nothing moves, so skin and decals
//    lie on the new planes (module_check's planarity) and the ground where
//    nothing changed keeps its bytes;
//  - a refined square (height_field.h's RefinedSquare) at level 0 becomes
//    the fine lattice inside its patch and a constrained triangulation of
//    the rest of the square (CGAL) that follows the square's diagonal and
//    the patch's border; decal triangles there are clipped against the new
//    triangles (CGAL's Triangle_2 intersection); fine posts on an edge
//    beside an unrefined square are dropped (no T-junction), those beside a
//    refined one kept, with the neighbour's edge points added, so both
//    squares carry the same vertices (docs/DYNAMIC.md). A coarser level's
//    lattice square takes the patch where its detail departs from the
//    square's planes by more than the level's own error (the levels' error
//    rule), drawn on that level's planes plus the detail, on a fine lattice
//    2^level times coarser than the patch's; elsewhere the level is
//    re-draped onto its lattice. Only a patch's detail rectangle is drawn
//    fine (RefinedSquare): its other fine posts lie on two planes, which
//    the rest triangles draw exactly;
//  - skirts are rebuilt along every node edge (through the fine edge
//    vertices), as deep as every level's edges need, fine points included;
//    maxHeight, normals (meshing::fillNormals' rule; the fine surface's
//    own inside a patch) and every object's objectY (module::placeBases)
//    follow.
//
// Thread contract: ModuleSource's. remesh() and editObject() are the one
// writer (the editor's thread, never the render thread); every
// ModuleSource member may be called from any thread meanwhile. A rebuilt
// module is published whole (one shared pointer swapped under a short
// lock), then its generation is stored (release), then changes() is
// bumped, so a reader that sees the new generation reads the new module.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/edit.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/formats/module.h"
#include "sandtable/paging/module_source.h"
#include "sandtable/paging/world.h"

namespace sandtable::edits {

struct RemeshOptions {
  /// Material class id given to skin triangles inside a refined patch whose
  /// centre lies more than kCraterFloorDepth below the ground the base
  /// modules were built on (a crater's floor shows soil, not the grass
  /// around it). The caller picks the class from its material table (an
  /// area class); none keeps the skin's own class there.
  std::optional<std::uint16_t> craterMaterial;
  /// Bounding cylinder (radius, height) of each icon at scale 1, indexed by
  /// icon (icons.pack): the size an added or switched object takes. An icon
  /// past the end: an added object gets 0 x 0, a switched one keeps its size.
  std::vector<std::array<float, 2>> iconCylinders;
};

/// The options a database implies: the crater floor's class (the
/// materials table's "crater" class, else its "soil"; none without either)
/// and every icon's bounding cylinder from icons.pack.
RemeshOptions remeshOptionsFor(const paging::World& world);

/// How far below the ground before a refined triangle must lie to take
/// RemeshOptions::craterMaterial, metres.
inline constexpr double kCraterFloorDepth = 0.01;

/// What one remesh() did.
struct RemeshReport {
  std::vector<paging::ModuleKey> modules;  ///< rebuilt and published, row-major
  /// Triangles of every rebuilt module per level (skin, decals, objects
  /// and skirts), finest first.
  std::vector<std::uint64_t> triangles;
  std::uint64_t refinedSquares = 0;  ///< level-0 squares meshed from a refined patch
  /// Per level, lattice squares meshed from refined patches (level 0's are
  /// refinedSquares; a coarser level's where the detail matters to it).
  std::vector<std::uint64_t> patchSquares;
  double seconds = 0;                ///< CPU seconds of the calling thread, rebuild and publish
};

class EditedModules final : public paging::ModuleSource {
 public:
  /// `base`: the modules as built, which never change (generation 0
  /// everywhere: the PackSource); `groundBefore`: the posts they were built
  /// from (the grid); `heights`: the edited posts (the heights overlay over
  /// that grid), with the same layout. The layout's module squares and
  /// levels are the base's header's.
  EditedModules(std::shared_ptr<const paging::ModuleSource> base, std::shared_ptr<const grid::HeightField> groundBefore,
                std::shared_ptr<const grid::HeightField> heights, RemeshOptions options = {});
  ~EditedModules() override;

  /// Rebuilds and publishes every module touched by a change of the posts
  /// `changedPosts` (half-open) and of the refined squares
  /// `changedRefinedSquares` (grid square (i, j)), from the heights now.
  /// Problems: a base module that does not read (nothing is published).
  Result<RemeshReport> remesh(const grid::PostRect& changedPosts,
                              std::span<const std::pair<std::uint32_t, std::uint32_t>> changedRefinedSquares);

  /// One change of the heights for the list form of remesh().
  struct Change {
    grid::PostRect posts;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> squares;
  };
  /// Every module any of `changes` touches, each rebuilt once (a burst of
  /// craters over many modules costs one rebuild per module, not one per
  /// crater), row-major. Problems as above.
  Result<RemeshReport> remesh(std::span<const Change> changes);

  /// An object edit (edit::Kind addObject, removeObject, switchObject,
  /// scaleObject) on its module, published as a newer generation: add at
  /// points[0] (an explicit object, heading and scale as given, id one past
  /// the module's largest explicit id) with its base on every level; remove
  /// object `object` of module (moduleX, moduleZ); switch its icon; scale it
  /// (scale, radius and height times `scale`). Object edits persist through
  /// later re-meshing. Problems: not an object edit, an invalid edit, no
  /// such module or object.
  Status editObject(const edit::Edit& e);

  /// The modules a change touches (see the file comment), row-major.
  std::vector<paging::ModuleKey> touched(const grid::PostRect& changedPosts,
                                         std::span<const std::pair<std::uint32_t, std::uint32_t>> changedRefinedSquares) const;

  const std::shared_ptr<const grid::HeightField>& heights() const { return heights_; }

  // ModuleSource.
  const pack::IndexHeader& header() const override { return base_->header(); }
  paging::ModuleInfo info(std::uint32_t kx, std::uint32_t kz) const override;
  std::uint64_t generation(std::uint32_t kx, std::uint32_t kz) const override;
  /// The published module (copied into `into`, reusing its capacity), or
  /// the base's read where none is published.
  Result<std::uint64_t> read(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  std::uint32_t coarseLevel() const override { return base_->coarseLevel(); }
  Result<std::uint64_t> readCoarse(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  /// The fine levels of the module published now: when a newer generation
  /// came out since readCoarse, the pager sees it in changes() and reloads.
  Status readFine(std::uint32_t kx, std::uint32_t kz, module::Module& into) const override;
  void willNeed(std::span<const paging::ModuleKey> keys, bool fine) const override { base_->willNeed(keys, fine); }
  bool missing(std::uint32_t kx, std::uint32_t kz) const override;
  std::uint64_t changes() const override { return changes_.load(std::memory_order_acquire); }
  std::uint64_t changedSince(std::uint64_t since, std::vector<paging::ModuleKey>& out) const override;

 private:
  struct Published;
  struct State;

  std::size_t index(std::uint32_t kx, std::uint32_t kz) const { return std::size_t(kz) * header().modulesX + kx; }
  std::shared_ptr<const Published> published(std::uint32_t kx, std::uint32_t kz) const;
  /// The module's writer-side state, its base read and decoded on first use.
  Result<State*> state(std::uint32_t kx, std::uint32_t kz);
  /// Makes `p` module (kx, kz)'s published generation (its generation
  /// stored before the log entry); commit() then bumps changes().
  void publish(std::uint32_t kx, std::uint32_t kz, std::shared_ptr<const Published> p);
  void commit();

  std::shared_ptr<const paging::ModuleSource> base_;
  std::shared_ptr<const grid::HeightField> before_, heights_;
  RemeshOptions options_;

  // Writer side (remesh, editObject): one thread at a time.
  std::unordered_map<std::size_t, std::unique_ptr<State>> states_;
  std::uint64_t nextGeneration_ = 1;

  // Reader side.
  mutable std::mutex mu_;  ///< guards published_ and log_
  std::unordered_map<std::size_t, std::shared_ptr<const Published>> published_;
  std::vector<paging::ModuleKey> log_;
  std::unique_ptr<std::atomic<std::uint64_t>[]> generations_;  ///< per module, row-major
  std::atomic<std::uint64_t> changes_{0};
};

}  // namespace sandtable::edits
