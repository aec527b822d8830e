#pragma once
// The shape of each height edit (docs/DYNAMIC.md, "Profiles"): the new
// height at a point as a function of the edit's parameters and the height
// there before it. The one place these formulas live: the overlay
// (heights.h) applies them at posts and at refined posts, the tests
// integrate them, docs/DYNAMIC.md derives their volumes.
//
// Every function is a pure function of doubles, evaluated in the same
// order on every machine (no fused multiply-add: built with
// -ffp-contract=off), so two processes get bit-identical heights.
//
// Thread safety: pure functions.
#include <cstdint>

#include "sandtable/formats/edit.h"

namespace sandtable::edits {

/// Crater rim: the rim crest stands kRimFraction * depth above the ground
/// before, at `radius`; the rim's outer foot is at kRimOuter * radius.
inline constexpr double kRimFraction = 0.25;
inline constexpr double kRimOuter = 2.0;

/// The seed's crater sizes (small, medium, large) as defaults for a
/// munition that names none: rim crest radius and centre depth, metres.
struct CraterSize {
  double radius = 0, depth = 0;
};
inline constexpr CraterSize kCraterSmall{1.0, 0.5};
inline constexpr CraterSize kCraterMedium{3.0, 1.2};
inline constexpr CraterSize kCraterLarge{7.5, 2.5};

/// An axis-aligned rectangle in the database frame (x east, z south).
struct Box {
  double x0 = 0, z0 = 0, x1 = 0, z1 = 0;
  bool empty() const { return !(x0 < x1 && z0 < z1); }
};

/// Where a crater, berm or ditch changes heights: outside it the new height
/// equals the old exactly. Flatten's reach depends on the heights; the
/// overlay widens its polygon's box by flattenReach.
Box support(const edit::Edit& e);

/// How far outside its polygon a flatten to `height` reaches when the
/// ground under the polygon's box differs from it by at most `maxGap`
/// metres: maxGap / sideSlope.
double flattenReach(const edit::Edit& e, double maxGap);

/// Height after edit `e` at (x, z), where it was `before`. Height edits
/// only (edit::changesHeights).
double newHeight(const edit::Edit& e, double x, double z, double before);

/// The crater's change at distance r from its centre (negative below).
double craterDelta(double radius, double depth, double r);
/// Volume a crater removes below the ground before (its bowl under the
/// old surface), cubic metres: pi r0^2 depth / 2, r0 = radius sqrt(depth / (depth + rim)).
double craterVolumeRemoved(double radius, double depth);
/// Volume its rim adds above the ground before, cubic metres.
double craterVolumeAdded(double radius, double depth);

/// Refinement for an edit on a grid of `spacing` metres: 0 when the posts
/// carry it (its smallest feature is at least two posts across), else the
/// number of fine cells per grid square edge, a power of two in 2..256,
/// so the fine spacing is the largest spacing / 2^k not over a quarter of
/// the feature and not under kFinestSpacing (as near as 256 cells allow).
inline constexpr double kFinestSpacing = 0.5;
inline constexpr std::uint32_t kMaxCells = 256;
std::uint32_t refineCells(const edit::Edit& e, double spacing);

/// Distance from (x, z) to the polyline `points` (at least one point).
double distanceToPolyline(const std::vector<std::array<double, 2>>& points, double x, double z);
/// True when (x, z) is inside the polygon (even-odd rule; closed implicitly).
bool insidePolygon(const std::vector<std::array<double, 2>>& points, double x, double z);

}  // namespace sandtable::edits
