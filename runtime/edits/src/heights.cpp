// The heights overlay (heights.h; docs/DYNAMIC.md, "Heights overlay").
// Built -ffp-contract=off (runtime/CMakeLists.txt), as profile.cpp and the
// build's normal rule: every height here rounds alike on every machine.
#include "sandtable/edits/heights.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>

#include "sandtable/base/hash.h"
#include "sandtable/edits/profile.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::edits {

namespace {

constexpr std::uint32_t kTile = grid::kBlockPosts;  // tiles are the grid's blocks
constexpr std::uint32_t kTilePosts = kTile * kTile;

std::uint32_t local(std::uint32_t i, std::uint32_t j) { return (j % kTile) * kTile + i % kTile; }

/// A normal in one word, so that a reader never sees half of one: x, y, z
/// snorm in bits 0..47 and kOwnNormal set; a zero word is "the base's".
constexpr std::uint64_t kOwnNormal = 1ull << 48;
std::uint64_t packNormal(const grid::PostNormal& n) {
  return std::uint64_t(std::uint16_t(n[0])) | std::uint64_t(std::uint16_t(n[1])) << 16 |
         std::uint64_t(std::uint16_t(n[2])) << 32 | kOwnNormal;
}
std::array<float, 3> unpackNormal(std::uint64_t w) {
  return {grid::fromSnorm(std::int16_t(std::uint16_t(w))), grid::fromSnorm(std::int16_t(std::uint16_t(w >> 16))),
          grid::fromSnorm(std::int16_t(std::uint16_t(w >> 32)))};
}

/// The position along one axis of fine post `a` of square `k` split into
/// `c` cells, metres. Dyadic fractions make it exact at the square's
/// corners (a = 0 or c gives k * s or (k + 1) * s) and the same number from
/// either square that shares an edge, whatever their cells: a point shared
/// by two squares gets the same profile value in both. A grid post is
/// finePos(k, 0, 1, s).
double finePos(std::uint32_t k, std::uint32_t a, std::uint32_t c, double s) {
  return (double(k) + double(a) / double(c)) * s;
}

/// The first index in [0, n) where the monotone `pred` holds; n if none.
template <typename Pred>
std::uint32_t firstWhere(std::uint32_t n, const Pred& pred) {
  std::uint32_t lo = 0, hi = n;
  while (lo < hi) {
    const std::uint32_t mid = lo + (hi - lo) / 2;
    if (pred(mid)) hi = mid;
    else lo = mid + 1;
  }
  return lo;
}

/// A half-open index range.
struct Range {
  std::uint32_t lo = 0, hi = 0;
  bool empty() const { return lo >= hi; }
};

/// Indices a in [0, n) whose position pos(a) lies strictly between x0 and x1.
template <typename Pos>
Range strictlyInside(std::uint32_t n, const Pos& pos, double x0, double x1) {
  return {firstWhere(n, [&](std::uint32_t a) { return pos(a) > x0; }),
          firstWhere(n, [&](std::uint32_t a) { return pos(a) >= x1; })};
}

/// Squares k in [0, n - 1) (between posts k and k + 1) whose open extent
/// meets the open interval (x0, x1).
Range squaresMeeting(std::uint32_t n, double s, double x0, double x1) {
  if (n < 2) return {};
  const auto pos = [s](std::uint32_t k) { return finePos(k, 0, 1, s); };
  return {firstWhere(n - 1, [&](std::uint32_t k) { return pos(k + 1) > x0; }),
          firstWhere(n - 1, [&](std::uint32_t k) { return pos(k) >= x1; })};
}

/// The fine posts of square k (cells c) that cover [x0, x1] within it,
/// snapped outward: [a0, a1] inclusive, the last post at or before x0 to
/// the first at or after x1, clamped to the square.
std::array<std::uint32_t, 2> snapOutward(std::uint32_t k, std::uint32_t c, double s, double x0, double x1) {
  const auto pos = [&](std::uint32_t a) { return finePos(k, a, c, s); };
  const std::uint32_t above = firstWhere(c + 1, [&](std::uint32_t a) { return pos(a) > x0; });
  const std::uint32_t a0 = above > 0 ? above - 1 : 0;
  const std::uint32_t a1 = std::min(c, firstWhere(c + 1, [&](std::uint32_t a) { return pos(a) >= x1; }));
  return {a0, std::max(a1, a0 + 1)};
}

/// A square's corner elevations (NW, NE, SW, SE) in double, as
/// Terrain::sampleXZ reads them.
using Corners = std::array<double, 4>;

double plane(const Corners& c, std::uint32_t a, std::uint32_t b, std::uint32_t cells) {
  return terrain::planeHeight(double(a) / double(cells), double(b) / double(cells), c[0], c[1], c[2], c[3]);
}

/// `old` on a lattice of `cells` (a multiple of its own): its fine posts
/// kept, the ones between them on its fine surface (grid::refinedHeight).
grid::RefinedSquare resample(const grid::RefinedSquare& old, std::uint32_t cells) {
  if (old.cells == cells) return old;
  const std::uint32_t k = cells / old.cells;
  grid::RefinedSquare p;
  p.i = old.i, p.j = old.j, p.cells = cells;
  p.a0 = old.a0 * k, p.b0 = old.b0 * k, p.a1 = old.a1 * k, p.b1 = old.b1 * k;
  p.da0 = old.da0 * k, p.db0 = old.db0 * k, p.da1 = old.da1 * k, p.db1 = old.db1 * k;
  p.heights.resize(std::size_t(p.b1 - p.b0 + 1) * p.width());
  std::size_t n = 0;
  for (std::uint32_t b = p.b0; b <= p.b1; ++b) {
    for (std::uint32_t a = p.a0; a <= p.a1; ++a) {
      if (a % k == 0 && b % k == 0) {
        p.heights[n++] = old.at(a / k, b / k);
      } else {
        bool inside = false;
        p.heights[n++] = float(grid::refinedHeight(old, double(a) / double(cells), double(b) / double(cells), inside));
        assert(inside);
      }
    }
  }
  return p;
}

/// Grows `p`'s rectangle to hold [a0, a1] x [b0, b1]; the new fine posts
/// start on the square's planes over `corners` (so the surface is as it
/// was). A patch with no cells yet gets `cells` and just that rectangle.
void grow(grid::RefinedSquare& p, std::uint32_t cells, std::array<std::uint32_t, 4> r, const Corners& corners) {
  grid::RefinedSquare q;
  q.i = p.i, q.j = p.j, q.cells = cells;
  const bool had = p.cells != 0;
  q.a0 = had ? std::min(p.a0, r[0]) : r[0];
  q.a1 = had ? std::max(p.a1, r[1]) : r[1];
  q.b0 = had ? std::min(p.b0, r[2]) : r[2];
  q.b1 = had ? std::max(p.b1, r[3]) : r[3];
  if (had && q.a0 == p.a0 && q.a1 == p.a1 && q.b0 == p.b0 && q.b1 == p.b1) return;
  q.heights.resize(std::size_t(q.b1 - q.b0 + 1) * q.width());
  std::size_t n = 0;
  for (std::uint32_t b = q.b0; b <= q.b1; ++b) {
    for (std::uint32_t a = q.a0; a <= q.a1; ++a) {
      const bool old = had && a >= p.a0 && a <= p.a1 && b >= p.b0 && b <= p.b1;
      q.heights[n++] = old ? p.at(a, b) : float(plane(corners, a, b, cells));
    }
  }
  p = std::move(q);
}

float& at(grid::RefinedSquare& p, std::uint32_t a, std::uint32_t b) {
  return p.heights[std::size_t(b - p.b0) * p.width() + (a - p.a0)];
}
bool holds(const grid::RefinedSquare& p, std::uint32_t a, std::uint32_t b) {
  return a >= p.a0 && a <= p.a1 && b >= p.b0 && b <= p.b1;
}

/// The float a post reads back as after storing `to` as a delta over
/// `base` (what elevation() returns), and that delta.
struct Stored {
  float delta = 0, value = 0;
};
Stored store(float base, float to) {
  const float d = to - base;
  return {d, d == 0.0f ? base : base + d};
}

/// True when a berm or ditch reaches no point of square (i, j): the
/// square's centre is further from the line than the profile's reach (what
/// support() widened the points' box by) and half the square's diagonal.
/// A long diagonal line's box holds many such squares; they would come out
/// unchanged, so skipping them only saves evaluating the profile there.
bool beyondReach(const edit::Edit& e, std::uint32_t i, std::uint32_t j, double s) {
  if (e.kind != edit::Kind::berm && e.kind != edit::Kind::ditch) return false;
  double east = e.points.front()[0];
  for (const auto& p : e.points) east = std::max(east, p[0]);
  const double reach = support(e).x1 - east;
  const double d = distanceToPolyline(e.points, (double(i) + 0.5) * s, (double(j) + 0.5) * s);
  return d > reach + s * std::sqrt(0.5) + 1e-6 * s;
}

std::string describe(const edit::Edit& e) {
  return std::string(edit::kindName(e.kind)) + " " + std::to_string(e.id);
}

}  // namespace

/// One tile of 64 x 64 posts: its posts' deltas and normals (made on the
/// first post edited in it) and its refined squares.
struct EditedHeights::Tile {
  struct Posts {
    std::array<std::atomic<float>, kTilePosts> delta{};
    std::array<std::atomic<std::uint64_t>, kTilePosts> normal{};
  };
  /// Patches sorted by local square index.
  using Patches = std::vector<std::shared_ptr<const grid::RefinedSquare>>;

  std::atomic<Posts*> posts{nullptr};
  /// Bit local(i, j) set when square (i, j) has a patch: a reader of an
  /// unrefined square never takes the lock below.
  std::array<std::atomic<std::uint64_t>, kTilePosts / 64> refinedBits{};

  /// A copy of the list (reset, hashing, statistics).
  Patches patchList() const {
    std::lock_guard lock(patchesMutex_);
    return patches_;
  }
  /// Puts `fresh` in, replacing a square's patch, in place under the lock:
  /// a change costs its own patches, not a copy of the tile's list (a copy
  /// on write made a replay quadratic in the patches of a tile).
  void upsert(std::vector<std::shared_ptr<const grid::RefinedSquare>>& fresh) {
    std::lock_guard lock(patchesMutex_);
    for (auto& p : fresh) {
      const std::uint32_t key = local(p->i, p->j);
      const auto it = std::lower_bound(patches_.begin(), patches_.end(), key,
                                       [](const auto& x, std::uint32_t v) { return local(x->i, x->j) < v; });
      if (it != patches_.end() && local((*it)->i, (*it)->j) == key) *it = std::move(p);
      else patches_.insert(it, std::move(p));
    }
  }
  void clearPatches() {
    std::lock_guard lock(patchesMutex_);
    patches_.clear();
  }
  /// Square (i, j)'s patch, or null; the lock is held for the search and
  /// one reference count increment.
  std::shared_ptr<const grid::RefinedSquare> find(std::uint32_t i, std::uint32_t j) const {
    const std::uint32_t key = local(i, j);
    std::lock_guard lock(patchesMutex_);
    const auto it = std::lower_bound(patches_.begin(), patches_.end(), key,
                                     [](const auto& p, std::uint32_t k) { return local(p->i, p->j) < k; });
    return it != patches_.end() && (*it)->i == i && (*it)->j == j ? *it : nullptr;
  }

  ~Tile() { delete posts.load(std::memory_order_relaxed); }

 private:
  mutable std::mutex patchesMutex_;
  Patches patches_;
};

/// Everything one apply() will publish, computed before any of it is.
struct EditedHeights::Plan {
  /// Changed grid posts (j, i) -> what they read back as, and the delta.
  std::map<SquareIndex, Stored> posts;
  /// New patches.
  std::map<SquareIndex, grid::RefinedSquare> patches;
};

EditedHeights::EditedHeights(std::shared_ptr<const grid::HeightField> base) : base_(std::move(base)) {
  assert(base_);
  tilesX_ = (base_->postsX() + kTile - 1) / kTile;
  tilesZ_ = (base_->postsZ() + kTile - 1) / kTile;
  const std::size_t n = std::size_t(tilesX_) * tilesZ_;
  tiles_ = std::make_unique<std::atomic<Tile*>[]>(n);
  tileGenerations_ = std::make_unique<std::atomic<std::uint64_t>[]>(n);
  const auto [lo, hi] = base_->elevationBounds();
  minElevation_.store(lo);
  maxElevation_.store(hi);
}

EditedHeights::~EditedHeights() {
  for (std::size_t k = 0, n = std::size_t(tilesX_) * tilesZ_; k < n; ++k) delete tiles_[k].load();
}

const EditedHeights::Tile* EditedHeights::tileAt(std::uint32_t i, std::uint32_t j) const {
  return tiles_[std::size_t(j / kTile) * tilesX_ + i / kTile].load(std::memory_order_acquire);
}

EditedHeights::Tile& EditedHeights::tileForWrite(std::uint32_t i, std::uint32_t j) {
  std::atomic<Tile*>& slot = tiles_[std::size_t(j / kTile) * tilesX_ + i / kTile];
  Tile* t = slot.load(std::memory_order_relaxed);
  if (!t) {
    t = new Tile;
    slot.store(t, std::memory_order_release);
  }
  return *t;
}

float EditedHeights::elevation(std::uint32_t i, std::uint32_t j) const {
  const float b = base_->elevation(i, j);
  const Tile* t = tileAt(i, j);
  const Tile::Posts* p = t ? t->posts.load(std::memory_order_acquire) : nullptr;
  if (!p) return b;
  // Acquire: a reader that sees a change's post sees the bounds that hold it.
  const float d = p->delta[local(i, j)].load(std::memory_order_acquire);
  return d == 0.0f ? b : b + d;
}

std::array<float, 3> EditedHeights::normal(std::uint32_t i, std::uint32_t j) const {
  const Tile* t = tileAt(i, j);
  const Tile::Posts* p = t ? t->posts.load(std::memory_order_acquire) : nullptr;
  const std::uint64_t w = p ? p->normal[local(i, j)].load(std::memory_order_acquire) : 0;
  return w & kOwnNormal ? unpackNormal(w) : base_->normal(i, j);
}

std::pair<float, float> EditedHeights::elevationBounds() const {
  return {minElevation_.load(std::memory_order_acquire), maxElevation_.load(std::memory_order_acquire)};
}

std::uint64_t EditedHeights::regionGeneration(const grid::PostRect& r) const {
  if (generation() == 0 || r.empty()) return 0;
  const std::uint32_t i1 = std::min(r.i1, postsX()), j1 = std::min(r.j1, postsZ());
  if (r.i0 >= i1 || r.j0 >= j1) return 0;
  std::uint64_t g = 0;
  for (std::uint32_t tz = r.j0 / kTile; tz <= (j1 - 1) / kTile; ++tz) {
    for (std::uint32_t tx = r.i0 / kTile; tx <= (i1 - 1) / kTile; ++tx) {
      g = std::max(g, tileGenerations_[std::size_t(tz) * tilesX_ + tx].load(std::memory_order_acquire));
    }
  }
  return g;
}

std::shared_ptr<const grid::RefinedSquare> EditedHeights::refined(std::uint32_t i, std::uint32_t j) const {
  if (!anyRefined()) return nullptr;
  const Tile* t = tileAt(i, j);
  if (!t) return nullptr;
  const std::uint32_t k = local(i, j);
  if (!((t->refinedBits[k / 64].load(std::memory_order_acquire) >> (k % 64)) & 1u)) return nullptr;
  return t->find(i, j);
}

// ------------------------------------------------------------------ apply

Result<HeightsChange> EditedHeights::apply(const edit::Edit& e) {
  const std::string stage = "edits: EditedHeights::apply: ";
  if (const std::string why = edit::checkEdit(e); !why.empty()) return Problem{"", 0, stage + why};
  if (!edit::changesHeights(e.kind)) {
    return Problem{"", 0, stage + describe(e) + " does not change heights (crater, berm, ditch and flatten do)"};
  }
  std::lock_guard lock(writer_);
  const double s = spacing();
  const std::uint32_t W = postsX(), H = postsZ();
  const auto current = [this](const SquareIndex& q) {
    return Corners{elevation(q.i, q.j), elevation(q.i + 1, q.j), elevation(q.i, q.j + 1), elevation(q.i + 1, q.j + 1)};
  };

  // Where the edit may change heights: its support; a flatten's reaches as
  // far out as its side slope needs to meet the ground under its polygon.
  Box box = support(e);
  if (e.kind == edit::Kind::flatten) {
    double gap = 0;
    const Range si = squaresMeeting(W, s, box.x0, box.x1), sj = squaresMeeting(H, s, box.z0, box.z1);
    for (std::uint32_t j = sj.lo; j < sj.hi; ++j) {
      for (std::uint32_t i = si.lo; i < si.hi; ++i) {
        for (const double h : current({i, j})) gap = std::max(gap, std::abs(h - e.height));
        if (const auto p = refined(i, j)) {
          for (const float h : p->heights) gap = std::max(gap, std::abs(double(h) - e.height));
        }
      }
    }
    const double reach = flattenReach(e, gap);
    box = {box.x0 - reach, box.z0 - reach, box.x1 + reach, box.z1 + reach};
  }
  const double maxX = finePos(W - 1, 0, 1, s), maxZ = finePos(H - 1, 0, 1, s);
  if (!(box.x0 < maxX && box.x1 > 0 && box.z0 < maxZ && box.z1 > 0)) {
    char where[200];
    std::snprintf(where, sizeof where, " changes x %.2f..%.2f, z %.2f..%.2f m: wholly outside the grid (x 0..%.2f, z 0..%.2f m)",
                  box.x0, box.x1, box.z0, box.z1, maxX, maxZ);
    return Problem{"", 0, stage + describe(e) + where};
  }

  Plan plan;
  // Grid posts strictly inside the box: outside it the profiles change
  // nothing, so neither posts nor fine posts on its edge move.
  const auto post = [s](std::uint32_t k) { return finePos(k, 0, 1, s); };
  const Range pi = strictlyInside(W, post, box.x0, box.x1), pj = strictlyInside(H, post, box.z0, box.z1);
  for (std::uint32_t j = pj.lo; j < pj.hi; ++j) {
    for (std::uint32_t i = pi.lo; i < pi.hi; ++i) {
      const float old = elevation(i, j);
      const float to = float(newHeight(e, post(i), post(j), double(old)));
      const Stored st = store(base_->elevation(i, j), to);
      if (st.value != old) plan.posts[{i, j}] = st;
    }
  }
  const auto cornerChanged = [&](const SquareIndex& q) {
    for (std::uint32_t c = 0; c < 4; ++c) {
      if (plan.posts.count({q.i + (c & 1u), q.j + (c >> 1)})) return true;
    }
    return false;
  };
  const auto after = [&](const SquareIndex& q) {
    Corners c = current(q);
    for (std::uint32_t k = 0; k < 4; ++k) {
      if (const auto it = plan.posts.find({q.i + (k & 1u), q.j + (k >> 1)}); it != plan.posts.end()) c[k] = it->second.value;
    }
    return c;
  };

  // Sub-post detail: every square the box meets (but those a line cannot
  // reach), on one lattice (the finest any of them has, at least the
  // edit's), so that squares sharing an edge carry the same fine posts
  // along it.
  const std::uint32_t cells = refineCells(e, s);
  if (cells > 0) {
    const Range si = squaresMeeting(W, s, box.x0, box.x1), sj = squaresMeeting(H, s, box.z0, box.z1);
    std::uint32_t lattice = cells;
    for (std::uint32_t j = sj.lo; j < sj.hi; ++j) {
      for (std::uint32_t i = si.lo; i < si.hi; ++i) {
        const auto p = refined(i, j);
        if (p && !beyondReach(e, i, j, s)) lattice = std::max(lattice, p->cells);
      }
    }
    for (std::uint32_t j = sj.lo; j < sj.hi; ++j) {
      for (std::uint32_t i = si.lo; i < si.hi; ++i) {
        if (beyondReach(e, i, j, s)) continue;
        const SquareIndex q{i, j};
        const Corners before = current(q);
        grid::RefinedSquare p;
        p.i = i, p.j = j;
        if (const auto old = refined(i, j)) p = resample(*old, lattice);
        // The patch covers the box within the square, snapped outward to
        // the fine lattice; the whole square when a corner moves, since
        // the square's planes move with it.
        const bool moved = cornerChanged(q);
        const auto ra = snapOutward(i, lattice, s, box.x0, box.x1), rb = snapOutward(j, lattice, s, box.z0, box.z1);
        const std::array<std::uint32_t, 4> boxFine{ra[0], ra[1], rb[0], rb[1]};
        const bool had = p.cells != 0;
        const std::array<std::uint32_t, 4> detailWas = p.detail();
        grow(p, lattice, moved ? std::array<std::uint32_t, 4>{0, lattice, 0, lattice} : boxFine, before);
        // The detail: what it was and the box. Outside it the fine posts
        // are the ground before, on the planes of the corners before (the
        // rest planes), however far the patch reaches.
        p.da0 = had ? std::min(detailWas[0], boxFine[0]) : boxFine[0];
        p.db0 = had ? std::min(detailWas[1], boxFine[2]) : boxFine[2];
        p.da1 = had ? std::max(detailWas[2], boxFine[1]) : boxFine[1];
        p.db1 = had ? std::max(detailWas[3], boxFine[3]) : boxFine[3];
        const auto xa = [&](std::uint32_t a) { return finePos(i, a, lattice, s); };
        const auto zb = [&](std::uint32_t b) { return finePos(j, b, lattice, s); };
        const Range fa = strictlyInside(lattice + 1, xa, box.x0, box.x1);
        const Range fb = strictlyInside(lattice + 1, zb, box.z0, box.z1);
        bool changed = moved;
        for (std::uint32_t b = fb.lo; b < fb.hi; ++b) {
          for (std::uint32_t a = fa.lo; a < fa.hi; ++a) {
            float& h = at(p, a, b);
            const float to = float(newHeight(e, xa(a), zb(b), double(h)));
            changed = changed || to != h;
            h = to;
          }
        }
        if (changed) plan.patches[q] = std::move(p);
      }
    }
  }
  // A refined square whose corner moved and that the edit did not refine
  // (it is carried by the posts): its detail rides on the planes' change.
  for (const auto& [pt, st] : plan.posts) {
    for (std::uint32_t c = 0; c < 4; ++c) {
      if (pt.i + (c & 1u) < 1 || pt.j + (c >> 1) < 1) continue;
      const SquareIndex q{pt.i + (c & 1u) - 1, pt.j + (c >> 1) - 1};
      if (q.i + 1 >= W || q.j + 1 >= H || plan.patches.count(q)) continue;
      const auto old = refined(q.i, q.j);
      if (!old) continue;
      const Corners from = current(q), to = after(q);
      grid::RefinedSquare p = *old;
      for (std::uint32_t b = p.b0; b <= p.b1; ++b) {
        for (std::uint32_t a = p.a0; a <= p.a1; ++a) {
          float& h = at(p, a, b);
          h = float(double(h) + (plane(to, a, b, p.cells) - plane(from, a, b, p.cells)));
        }
      }
      plan.patches[q] = std::move(p);
    }
  }
  // A patch's corners are the grid posts, exactly; where two new patches
  // share an edge, the west (or north) one's fine posts are the edge's, so
  // both sides carry the same numbers.
  for (auto& [q, p] : plan.patches) {
    const Corners c = after(q);
    for (std::uint32_t k = 0; k < 4; ++k) {
      const std::uint32_t a = (k & 1u) * p.cells, b = (k >> 1) * p.cells;
      if (holds(p, a, b)) at(p, a, b) = float(c[k]);
    }
  }
  for (auto& [q, p] : plan.patches) {
    if (const auto east = plan.patches.find({q.i + 1, q.j}); east != plan.patches.end() && p.a1 == p.cells) {
      grid::RefinedSquare& o = east->second;
      if (o.a0 == 0 && o.cells == p.cells) {
        for (std::uint32_t b = std::max(p.b0, o.b0); b <= std::min(p.b1, o.b1); ++b) at(o, 0, b) = at(p, p.cells, b);
      }
    }
    if (const auto south = plan.patches.find({q.i, q.j + 1}); south != plan.patches.end() && p.b1 == p.cells) {
      grid::RefinedSquare& o = south->second;
      if (o.b0 == 0 && o.cells == p.cells) {
        for (std::uint32_t a = std::max(p.a0, o.a0); a <= std::min(p.a1, o.a1); ++a) at(o, a, 0) = at(p, a, p.cells);
      }
    }
  }

  HeightsChange out;
  if (plan.posts.empty() && plan.patches.empty()) return out;
  publish(plan, out);
  return out;
}

void EditedHeights::publish(Plan& plan, HeightsChange& out) {
  const std::uint64_t g = generation_.load(std::memory_order_relaxed) + 1;
  const std::uint32_t W = postsX(), H = postsZ();

  // Bounds first: they only widen, so they hold for every post at any time.
  float lo = minElevation_.load(std::memory_order_relaxed), hi = maxElevation_.load(std::memory_order_relaxed);
  for (const auto& [q, st] : plan.posts) lo = std::min(lo, st.value), hi = std::max(hi, st.value);
  for (const auto& [q, p] : plan.patches) {
    for (const float h : p.heights) lo = std::min(lo, h), hi = std::max(hi, h);
  }
  minElevation_.store(lo, std::memory_order_release);
  maxElevation_.store(hi, std::memory_order_release);

  // Posts, then the normals of the posts and their neighbours.
  std::set<SquareIndex> normals;
  for (const auto& [q, st] : plan.posts) {
    Tile& t = tileForWrite(q.i, q.j);
    if (!t.posts.load(std::memory_order_relaxed)) t.posts.store(new Tile::Posts, std::memory_order_release);
    t.posts.load(std::memory_order_relaxed)->delta[local(q.i, q.j)].store(st.delta, std::memory_order_release);
    normals.insert(q);
    if (q.i > 0) normals.insert({q.i - 1, q.j});
    if (q.i + 1 < W) normals.insert({q.i + 1, q.j});
    if (q.j > 0) normals.insert({q.i, q.j - 1});
    if (q.j + 1 < H) normals.insert({q.i, q.j + 1});
  }
  const auto elev = [this](std::uint32_t i, std::uint32_t j) { return elevation(i, j); };
  grid::PostRect posts{W, H, 0, 0};
  for (const SquareIndex& q : normals) {
    Tile& t = tileForWrite(q.i, q.j);
    if (!t.posts.load(std::memory_order_relaxed)) t.posts.store(new Tile::Posts, std::memory_order_release);
    const grid::PostNormal n = grid::postNormal(elev, q.i, q.j, W, H, spacing());
    t.posts.load(std::memory_order_relaxed)->normal[local(q.i, q.j)].store(packNormal(n), std::memory_order_release);
    posts = {std::min(posts.i0, q.i), std::min(posts.j0, q.j), std::max(posts.i1, q.i + 1), std::max(posts.j1, q.j + 1)};
  }
  out.posts = normals.empty() ? grid::PostRect{} : posts;

  // Patches, a tile's list replaced whole.
  grid::PostRect region = out.posts;
  std::map<std::size_t, std::vector<std::shared_ptr<const grid::RefinedSquare>>> byTile;
  for (auto& [q, p] : plan.patches) {
    p.generation = g;
    byTile[std::size_t(q.j / kTile) * tilesX_ + q.i / kTile].push_back(
        std::make_shared<const grid::RefinedSquare>(std::move(p)));
    out.squares.push_back(q);
    const grid::PostRect corners{q.i, q.j, q.i + 2, q.j + 2};
    region = region.empty() ? corners
                            : grid::PostRect{std::min(region.i0, corners.i0), std::min(region.j0, corners.j0),
                                             std::max(region.i1, corners.i1), std::max(region.j1, corners.j1)};
  }
  for (auto& [k, fresh] : byTile) {
    Tile& t = tileForWrite(fresh.front()->i, fresh.front()->j);
    std::vector<std::uint32_t> keys;
    for (const auto& p : fresh) keys.push_back(local(p->i, p->j));
    t.upsert(fresh);
    // After the patch is in: a reader that sees the bit finds it.
    for (const std::uint32_t key : keys) {
      t.refinedBits[key / 64].fetch_or(std::uint64_t(1) << (key % 64), std::memory_order_release);
    }
  }
  if (!plan.patches.empty()) anyRefined_.store(true, std::memory_order_release);

  // Generations (release): a reader that sees g sees all of the above.
  region = {region.i0, region.j0, std::min(region.i1, W), std::min(region.j1, H)};
  for (std::uint32_t tz = region.j0 / kTile; tz <= (region.j1 - 1) / kTile; ++tz) {
    for (std::uint32_t tx = region.i0 / kTile; tx <= (region.i1 - 1) / kTile; ++tx) {
      tileGenerations_[std::size_t(tz) * tilesX_ + tx].store(g, std::memory_order_release);
    }
  }
  generation_.store(g, std::memory_order_release);
  out.region = region;
  out.generation = g;
  notifyChanged({region, g});
}

// ----------------------------------------------------------------- reset

HeightsChange EditedHeights::reset() {
  std::lock_guard lock(writer_);
  const std::uint64_t g = generation_.load(std::memory_order_relaxed) + 1;
  const std::uint32_t W = postsX(), H = postsZ();
  HeightsChange out;
  grid::PostRect region;
  const auto unite = [&region](const grid::PostRect& r) {
    region = region.empty() ? r
                            : grid::PostRect{std::min(region.i0, r.i0), std::min(region.j0, r.j0),
                                             std::max(region.i1, r.i1), std::max(region.j1, r.j1)};
  };
  for (std::uint32_t tz = 0; tz < tilesZ_; ++tz) {
    for (std::uint32_t tx = 0; tx < tilesX_; ++tx) {
      Tile* t = tiles_[std::size_t(tz) * tilesX_ + tx].load(std::memory_order_relaxed);
      if (!t) continue;
      const grid::PostRect whole{tx * kTile, tz * kTile, std::min((tx + 1) * kTile, W), std::min((tz + 1) * kTile, H)};
      if (Tile::Posts* p = t->posts.load(std::memory_order_relaxed)) {
        bool edited = false;
        for (std::uint32_t k = 0; k < kTilePosts; ++k) {
          edited |= p->delta[k].load(std::memory_order_relaxed) != 0.0f ||
                    p->normal[k].load(std::memory_order_relaxed) != 0;
          p->delta[k].store(0.0f, std::memory_order_release);
          p->normal[k].store(0, std::memory_order_release);
        }
        if (edited) unite(whole);
      }
      if (const auto list = t->patchList(); !list.empty()) {
        for (const auto& q : list) {
          out.squares.push_back({q->i, q->j});
          unite({q->i, q->j, std::min(q->i + 2, W), std::min(q->j + 2, H)});
        }
        for (auto& bits : t->refinedBits) bits.store(0, std::memory_order_release);
        t->clearPatches();
      }
    }
  }
  if (region.empty()) return out;
  std::sort(out.squares.begin(), out.squares.end());
  for (std::uint32_t tz = region.j0 / kTile; tz <= (region.j1 - 1) / kTile; ++tz) {
    for (std::uint32_t tx = region.i0 / kTile; tx <= (region.i1 - 1) / kTile; ++tx) {
      tileGenerations_[std::size_t(tz) * tilesX_ + tx].store(g, std::memory_order_release);
    }
  }
  generation_.store(g, std::memory_order_release);
  out.posts = region;
  out.region = region;
  out.generation = g;
  notifyChanged({region, g});
  return out;
}

// ------------------------------------------------------------- read back

std::uint64_t EditedHeights::contentHash() const {
  std::uint64_t h = hash::mix(std::uint64_t(postsX()) << 32 | postsZ());
  const auto add = [&h](std::uint64_t v) { h = hash::mix(h ^ v); };
  for (std::uint32_t tz = 0; tz < tilesZ_; ++tz) {
    for (std::uint32_t tx = 0; tx < tilesX_; ++tx) {
      const Tile* t = tiles_[std::size_t(tz) * tilesX_ + tx].load(std::memory_order_acquire);
      if (!t) continue;
      if (const Tile::Posts* p = t->posts.load(std::memory_order_acquire)) {
        for (std::uint32_t k = 0; k < kTilePosts; ++k) {
          const float d = p->delta[k].load(std::memory_order_relaxed);
          if (d == 0.0f) continue;  // an unedited post hashes as if no tile held it
          add(std::uint64_t(tx * kTile + k % kTile) << 32 | (tz * kTile + k / kTile));
          add(std::bit_cast<std::uint32_t>(d));
        }
      }
      for (const auto& p : t->patchList()) {
        add(std::uint64_t(p->i) << 32 | p->j);
        add(std::uint64_t(p->cells) << 32 | p->a0);
        add(std::uint64_t(p->b0) << 32 | p->a1);
        add(p->b1);
        for (const float v : p->heights) add(std::bit_cast<std::uint32_t>(v));
      }
    }
  }
  return h;
}

HeightsStats EditedHeights::stats() const {
  HeightsStats st;
  const std::size_t slots = std::size_t(tilesX_) * tilesZ_;
  st.bytes = sizeof(*this) + slots * (sizeof(std::atomic<Tile*>) + sizeof(std::atomic<std::uint64_t>));
  for (std::size_t k = 0; k < slots; ++k) {
    const Tile* t = tiles_[k].load(std::memory_order_acquire);
    if (!t) continue;
    st.bytes += sizeof(Tile);
    if (t->posts.load(std::memory_order_acquire)) {
      ++st.tiles;
      st.bytes += sizeof(Tile::Posts);
    }
    if (const auto list = t->patchList(); !list.empty()) {
      st.bytes += sizeof(Tile::Patches) + list.size() * sizeof(list.front());
      for (const auto& p : list) {
        ++st.refinedSquares;
        st.finePosts += p->heights.size();
        // make_shared: one block for the control block and the square.
        st.bytes += sizeof(grid::RefinedSquare) + 2 * sizeof(void*) + p->heights.capacity() * sizeof(float);
      }
    }
  }
  return st;
}

}  // namespace sandtable::edits
