#pragma once
// The view triangle and terrain selection (seed chapter IX, Figures 76-78).
//
// The view volume is projected onto the ground plane as a triangle: the
// apex sits at the eye pulled back one post spacing along the reverse look
// vector, and the two far vertices lie along heading -/+ half the field of
// view. The grid squares under the triangle are found row by row and grown
// by one square each way; every selected row span is drawn as one triangle
// strip.
//
// Everything here is pure math on the world frame (seed Figure 6): X east,
// Z south, metres from the north-west corner post. Grid square (i, j) is
// the square whose north-west post is post (i, j); it covers
// X in [i, i+1] * spacing and Z in [j, j+1] * spacing.
//
// Thread safety: free functions without state; call from any thread.
#include <cstdint>
#include <vector>

namespace sandtable::paging {

/// A point on the ground plane, world metres.
struct GroundPoint {
  double x = 0;  ///< east of the north-west corner post
  double z = 0;  ///< south of the north-west corner post
};

/// The view triangle: apex behind the eye, left and right far vertices.
struct ViewTriangle {
  GroundPoint apex, left, right;
};

/// What the triangle is built from.
struct ViewTriangleParams {
  double eyeX = 0, eyeZ = 0;   ///< eye position, world metres
  double headingDeg = 0;       ///< clockwise from grid north (-Z)
  double halfAngleDeg = 30;    ///< half the horizontal angle covered, (0, 89]
  double viewDistance = 10000; ///< metres; everything nearer than this is covered
  double pullback = 0;         ///< metres the apex moves back (one post spacing)
};

/// Unit look vector on the ground for a heading: 0 = north (-Z), 90 = east (+X).
GroundPoint headingVector(double headingDeg);

/// The horizontal half angle the triangle must span so that a camera with
/// this horizontal/vertical field of view and pitch sees nothing outside it.
/// A pitched camera's screen corners fan out wider on the ground than
/// hfov/2, so this is max over the four corner rays of their azimuth,
/// capped at `maxDeg`.
double groundHalfAngleDeg(double hfovDeg, double vfovDeg, double pitchDeg, double maxDeg = 80);

/// Vertical field of view that keeps the aspect ratio (seed: the ratio of
/// the angles follows the window's width and height).
double verticalFovDeg(double hfovDeg, double aspect);

/// Builds the triangle. The far vertices lie (viewDistance + pullback) /
/// cos(halfAngle) from the apex, so the whole disc sector of radius
/// viewDistance around the eye lies inside (fog is full at that radius).
ViewTriangle makeViewTriangle(const ViewTriangleParams& p);

/// Squares [firstI, lastI] (inclusive) in row j of grid squares.
struct RowSpan {
  std::uint32_t j = 0;
  std::uint32_t firstI = 0;
  std::uint32_t lastI = 0;
  std::uint32_t squares() const { return lastI - firstI + 1; }
};

/// Bounding box of the triangle in grid squares (seed Figure 77), clipped
/// to the grid. empty is true when the triangle misses the grid entirely.
struct SquareBox {
  std::int64_t minI = 0, maxI = -1, minJ = 0, maxJ = -1;
  bool empty() const { return minI > maxI || minJ > maxJ; }
};
SquareBox boundingSquares(const ViewTriangle& t, double spacing, std::uint32_t squaresX,
                          std::uint32_t squaresZ);

/// The grid squares touched by the triangle, grown by `grow` squares each
/// way (seed: one), clipped to the grid of squaresX x squaresZ squares
/// (postsX - 1 by postsZ - 1). One span per row, rows ascending (north to
/// south). Every square that the triangle overlaps at all is included.
std::vector<RowSpan> selectSquares(const ViewTriangle& t, double spacing, std::uint32_t squaresX,
                                   std::uint32_t squaresZ, std::uint32_t grow = 1);

/// Sum of squares over the spans (each square is two triangles).
std::uint64_t countSquares(const std::vector<RowSpan>& spans);

}  // namespace sandtable::paging
