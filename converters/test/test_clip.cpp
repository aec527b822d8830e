// Liang-Barsky clipping (clip.h) against clips worked out by hand.
#include <gtest/gtest.h>

#include <vector>

#include "sandtable/converters/clip.h"

using namespace sandtable::convert;

namespace {

struct XZ {  // the culture loader's axes
  double x = 0, z = 0;
  bool operator==(const XZ&) const = default;
};
struct XY {  // synth's axes, with another member to carry
  double x = 0, y = 0;
  int tag = 0;
  bool operator==(const XY&) const = default;
};

const clip::Rect kBox{0, 0, 4, 4};

std::vector<std::vector<XZ>> clipXZ(const std::vector<XZ>& pts) { return clip::polyline(pts, kBox, &XZ::x, &XZ::z); }

}  // namespace

TEST(Clip, segmentParameters) {
  // (-1,2)-(5,2) enters at x = 0 (t = 1/6) and leaves at x = 4 (t = 5/6).
  auto s = clip::segment(-1, 2, 5, 2, kBox);
  ASSERT_TRUE(s);
  EXPECT_DOUBLE_EQ(s->t0, 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(s->t1, 5.0 / 6.0);
  // Inside: the whole segment.
  s = clip::segment(1, 1, 3, 2, kBox);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->t0, 0.0);
  EXPECT_EQ(s->t1, 1.0);
  // Outside, parallel to an edge, and touching a corner only: nothing.
  EXPECT_FALSE(clip::segment(5, 5, 6, 6, kBox));
  EXPECT_FALSE(clip::segment(-1, 1, -1, 3, kBox));
  EXPECT_FALSE(clip::segment(-1, 1, 1, -1, kBox));
  // Along the border: inside (the rectangle is closed).
  s = clip::segment(0, 1, 0, 3, kBox);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->t0, 0.0);
  EXPECT_EQ(s->t1, 1.0);
}

TEST(Clip, polylineParts) {
  using Parts = std::vector<std::vector<XZ>>;
  EXPECT_EQ(clipXZ({{1, 1}, {2, 2}, {3, 1}}), (Parts{{{1, 1}, {2, 2}, {3, 1}}}));
  EXPECT_EQ(clipXZ({{-2, 1}, {2, 1}}), (Parts{{{0, 1}, {2, 1}}}));
  EXPECT_EQ(clipXZ({{-1, -1}, {5, 5}}), (Parts{{{0, 0}, {4, 4}}}));
  // Out through the east edge and back in: two parts.
  EXPECT_EQ(clipXZ({{1, 1}, {6, 1}, {6, 3}, {1, 3}}), (Parts{{{1, 1}, {4, 1}}, {{4, 3}, {1, 3}}}));
  // A vertex on the border does not split the line.
  EXPECT_EQ(clipXZ({{2, 2}, {4, 2}, {2, 3}}), (Parts{{{2, 2}, {4, 2}, {2, 3}}}));
  // Outside, or touching at one corner: no part.
  EXPECT_TRUE(clipXZ({{5, 5}, {6, 6}, {8, 5}}).empty());
  EXPECT_TRUE(clipXZ({{-1, 1}, {1, -1}}).empty());
  EXPECT_TRUE(clipXZ({{1, 1}}).empty());
}

TEST(Clip, otherAxesAndMembersCarried) {
  // y is the second axis here; the interpolated point copies the other
  // members from the segment's start, kept points are the inputs exactly.
  const std::vector<XY> pts{{-2, -2, 1}, {2, 2, 2}, {2, 6, 3}};
  const auto parts = clip::polyline(pts, clip::Rect{-1, -1, 1, 4}, &XY::x, &XY::y);
  // (-2,-2)-(2,2) is inside from (-1,-1) to (1,1); (2,2)-(2,6) is outside.
  ASSERT_EQ(parts.size(), 1u);
  EXPECT_EQ(parts[0], (std::vector<XY>{{-1, -1, 1}, {1, 1, 1}}));
}
