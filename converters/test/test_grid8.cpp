// grid8::forEachNeighbour against neighbour lists worked out by hand.
#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "sandtable/converters/grid8.h"

using namespace sandtable::convert;

namespace {

using Steps = std::vector<std::pair<int, std::size_t>>;

Steps neighbours(int nx, int ny, std::size_t c) {
  Steps out;
  grid8::forEachNeighbour(nx, ny, c, [&](int k, std::size_t n) { out.push_back({k, n}); });
  return out;
}

}  // namespace

TEST(Grid8, neighboursInStepOrderInsideTheGrid) {
  // 3 x 3, cells numbered row by row:  0 1 2 / 3 4 5 / 6 7 8.
  EXPECT_EQ(neighbours(3, 3, 4), (Steps{{0, 5}, {1, 3}, {2, 7}, {3, 1}, {4, 8}, {5, 2}, {6, 6}, {7, 0}}));
  EXPECT_EQ(neighbours(3, 3, 0), (Steps{{0, 1}, {2, 3}, {4, 4}}));
  EXPECT_EQ(neighbours(3, 3, 8), (Steps{{1, 7}, {3, 5}, {7, 4}}));
  EXPECT_EQ(neighbours(3, 3, 5), (Steps{{1, 4}, {2, 8}, {3, 2}, {6, 7}, {7, 1}}));
  // One column: only north and south; one cell: none.
  EXPECT_EQ(neighbours(1, 3, 1), (Steps{{2, 2}, {3, 0}}));
  EXPECT_TRUE(neighbours(1, 1, 0).empty());
  // Wide rows do not wrap: the east end of row 0 has no east neighbour.
  EXPECT_EQ(neighbours(4, 2, 3), (Steps{{1, 2}, {2, 7}, {6, 6}}));
  for (int k = 0; k < 8; ++k) EXPECT_EQ(grid8::diagonal(k), k >= 4);
}

TEST(Grid8, floodReachesDiagonalCells) {
  // Open cells (1) touch only at corners; an 8-connected flood from the
  // top-left reaches all four, a 4-connected one would reach one.
  //   1 0 0
  //   0 1 0
  //   0 0 1   and (2,0) through (1,1).
  const int nx = 3, ny = 3;
  const std::vector<int> open{1, 0, 1, 0, 1, 0, 0, 0, 1};
  std::vector<int> seen(9, 0);
  std::vector<std::size_t> stack{0};
  seen[0] = 1;
  int reached = 0;
  while (!stack.empty()) {
    const std::size_t c = stack.back();
    stack.pop_back();
    ++reached;
    grid8::forEachNeighbour(nx, ny, c, [&](int, std::size_t n) {
      if (open[n] && !seen[n]) seen[n] = 1, stack.push_back(n);
    });
  }
  EXPECT_EQ(reached, 4);
}
