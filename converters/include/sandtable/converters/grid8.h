#pragma once
// The 8 neighbours of a cell of a row-major grid, for the floods and
// least-cost searches over synth's analysis grid (depression filling,
// drainage, breaching, road routing): one loop instead of one per search.
//
// Thread safety: pure functions.
#include <cstddef>

namespace sandtable::convert::grid8 {

/// Neighbour steps: 0..3 the edge neighbours (E, W, S, N; length 1),
/// 4..7 the diagonals (SE, NE, SW, NW; length sqrt 2).
inline constexpr int kDi[8] = {1, -1, 0, 0, 1, 1, -1, -1};
inline constexpr int kDj[8] = {0, 0, 1, -1, 1, -1, 1, -1};
inline constexpr bool diagonal(int k) { return k >= 4; }

/// Calls f(k, neighbour) for each neighbour of cell c (index j * nx + i)
/// of an nx x ny grid that lies inside the grid, in step order k = 0..7.
template <typename F>
void forEachNeighbour(int nx, int ny, std::size_t c, F&& f) {
  const int i = static_cast<int>(c % static_cast<std::size_t>(nx));
  const int j = static_cast<int>(c / static_cast<std::size_t>(nx));
  for (int k = 0; k < 8; ++k) {
    const int ni = i + kDi[k], nj = j + kDj[k];
    if (ni < 0 || nj < 0 || ni >= nx || nj >= ny) continue;
    f(k, static_cast<std::size_t>(nj) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(ni));
  }
}

}  // namespace sandtable::convert::grid8
