#include "sandtable/scene/lod.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "sandtable/formats/terrain_rule.h"

namespace sandtable::scene {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
/// Rings morph over this outer fraction of each bin.
constexpr double kRingMorphFraction = 0.25;

double ringEdge(const LodOptions& o, std::uint32_t level, double viewDistance,
                std::uint32_t levels) {
  if (!o.rings.empty()) {
    return level < o.rings.size() ? o.rings[level] : std::max(o.rings.back(), viewDistance);
  }
  return viewDistance * double(level + 1) / double(std::max<std::uint32_t>(levels, 1));
}

}  // namespace

const char* lodModeName(LodMode m) {
  switch (m) {
    case LodMode::rings: return "rings";
    case LodMode::sse: return "sse";
    case LodMode::full: return "full";
  }
  return "?";
}

std::uint32_t nodeOfSquare(const module::Level& level, std::uint32_t square,
                           std::uint32_t nodeSquares, std::uint32_t nodesPerSide) {
  const std::uint32_t nx = std::max<std::uint32_t>(level.squaresX, 1);
  const std::uint32_t n = std::max<std::uint32_t>(nodeSquares, 1);
  const std::uint32_t a = std::min((square % nx) / n, nodesPerSide - 1);
  const std::uint32_t b = std::min((square / nx) / n, nodesPerSide - 1);
  return mortonIndex(a, b);
}

bool needsUnderlay(const module::Level& level) {
  std::uint64_t skin = 0;
  for (const auto& g : level.groups) {
    if (g.priority == module::kPrioritySkin && g.half != module::Half::skirt) skin += g.indexCount / 3;
  }
  return skin > 2ull * level.squaresX * level.squaresZ;
}

std::vector<std::uint64_t> nodeTrianglePrefix(const module::Level& level, std::uint32_t nodeSquares,
                                              std::uint32_t nodesPerSide) {
  const std::size_t nodes = std::size_t(nodesPerSide) * nodesPerSide;
  std::vector<std::uint64_t> count(nodes + 1, 0);
  for (const auto& g : level.groups) {
    count[nodeOfSquare(level, g.square, nodeSquares, nodesPerSide)] += g.indexCount / 3;
  }
  if (needsUnderlay(level)) {
    for (std::uint32_t q = 0; q < level.squaresX * level.squaresZ; ++q) {
      count[nodeOfSquare(level, q, nodeSquares, nodesPerSide)] += 2;
    }
  }
  std::uint64_t run = 0;
  for (auto& c : count) {
    const std::uint64_t n = c;
    c = run;
    run += n;
  }
  return count;
}

std::string checkLodOptions(const LodOptions& o) {
  for (std::size_t k = 0; k < o.rings.size(); ++k) {
    if (!(o.rings[k] > 0) || !std::isfinite(o.rings[k])) return "LodOptions::rings must be positive metres";
    if (k > 0 && !(o.rings[k] > o.rings[k - 1])) return "LodOptions::rings must be strictly ascending";
  }
  if (!(o.pixelError > 0) || !std::isfinite(o.pixelError)) return "LodOptions::pixelError must be positive";
  return {};
}

std::optional<double> levelHeightAt(const module::Level& level, double x, double z) {
  const std::uint32_t nx = level.squaresX, nz = level.squaresZ;
  const std::size_t posts = std::size_t(nx + 1) * (nz + 1);
  if (nx == 0 || nz == 0 || level.vertices.size() < posts || !(level.spacing > 0)) {
    return std::nullopt;
  }
  const std::uint32_t column = terrain::latticeCell(x, level.spacing, nx);
  const std::uint32_t row = terrain::latticeCell(z, level.spacing, nz);
  const auto post = [&](std::uint32_t c, std::uint32_t r) -> const module::Vertex& {
    return level.vertices[std::size_t(r) * (nx + 1) + c];
  };
  const module::Vertex& nw = post(column, row);
  const module::Vertex& ne = post(column + 1, row);
  const module::Vertex& sw = post(column, row + 1);
  const module::Vertex& se = post(column + 1, row + 1);
  const double w = std::max(double(ne.x - nw.x), 1e-9), h = std::max(double(sw.z - nw.z), 1e-9);
  const double u = std::clamp((x - nw.x) / w, 0.0, 1.0), v = std::clamp((z - nw.z) / h, 0.0, 1.0);
  return terrain::planeHeight(u, v, nw.y, ne.y, sw.y, se.y);
}

std::vector<double> levelErrors(std::span<const module::Level> levels, std::uint32_t finest) {
  std::vector<double> errors(levels.size(), 0.0);
  if (finest >= levels.size()) return errors;
  const module::Level& base = levels[finest];
  const std::size_t posts = std::size_t(base.squaresX + 1) * (base.squaresZ + 1);
  const std::size_t n = std::min(posts, base.vertices.size());
  for (std::size_t l = finest + 1; l < levels.size(); ++l) {
    double worst = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const module::Vertex& v = base.vertices[k];
      if (auto y = levelHeightAt(levels[l], v.x, v.z)) worst = std::max(worst, std::abs(*y - v.y));
    }
    // A coarser level is never credited with less error than a finer one,
    // so the SSE choice is monotonic in distance.
    errors[l] = std::max(worst, errors[l - 1]);
  }
  return errors;
}

namespace {

/// Cells [lo, hi] (inclusive) an interval [x0, x1] of metres touches.
std::pair<std::uint32_t, std::uint32_t> cellSpan(double x0, double x1, double cell,
                                                 std::uint32_t side) {
  const double eps = 1e-3;
  const auto clampCell = [&](double v) {
    return std::uint32_t(std::clamp(std::floor(v / cell), 0.0, double(side - 1)));
  };
  return {clampCell(x0 - eps), clampCell(x1 + eps)};
}

}  // namespace

std::vector<std::vector<double>> cellErrors(std::span<const module::Level> levels,
                                            std::uint32_t finest, double cellSize,
                                            std::uint32_t cellsPerSide) {
  const std::size_t cells = std::size_t(cellsPerSide) * cellsPerSide;
  std::vector<std::vector<double>> errors(levels.size(), std::vector<double>(cells, 0.0));
  if (finest >= levels.size() || !(cellSize > 0)) return errors;
  const module::Level& base = levels[finest];
  const std::size_t posts = std::size_t(base.squaresX + 1) * (base.squaresZ + 1);
  const std::size_t n = std::min(posts, base.vertices.size());
  for (std::size_t l = finest + 1; l < levels.size(); ++l) {
    for (std::size_t k = 0; k < n; ++k) {
      const module::Vertex& v = base.vertices[k];
      const auto y = levelHeightAt(levels[l], v.x, v.z);
      if (!y) continue;
      const double e = std::abs(*y - v.y);
      const auto [a0, a1] = cellSpan(v.x, v.x, cellSize, cellsPerSide);
      const auto [b0, b1] = cellSpan(v.z, v.z, cellSize, cellsPerSide);
      for (std::uint32_t b = b0; b <= b1; ++b) {
        for (std::uint32_t a = a0; a <= a1; ++a) {
          double& c = errors[l][mortonIndex(a, b)];
          c = std::max(c, e);
        }
      }
    }
    for (std::size_t c = 0; c < cells; ++c) errors[l][c] = std::max(errors[l][c], errors[l - 1][c]);
  }
  return errors;
}

std::vector<float> cellMaxHeights(std::span<const module::Level> levels, std::uint32_t finest,
                                  double cellSize, std::uint32_t cellsPerSide) {
  std::vector<float> top(std::size_t(cellsPerSide) * cellsPerSide,
                         -std::numeric_limits<float>::infinity());
  for (std::size_t l = finest; l < levels.size(); ++l) {
    const module::Level& level = levels[l];
    if (level.maxHeight.size() < std::size_t(level.squaresX) * level.squaresZ) continue;
    for (std::uint32_t sz = 0; sz < level.squaresZ; ++sz) {
      const auto [b0, b1] = cellSpan(sz * level.spacing, (sz + 1) * level.spacing, cellSize, cellsPerSide);
      for (std::uint32_t sx = 0; sx < level.squaresX; ++sx) {
        const float h = level.maxHeight[std::size_t(sz) * level.squaresX + sx];
        const auto [a0, a1] =
            cellSpan(sx * level.spacing, (sx + 1) * level.spacing, cellSize, cellsPerSide);
        for (std::uint32_t b = b0; b <= b1; ++b) {
          for (std::uint32_t a = a0; a <= a1; ++a) {
            float& t = top[mortonIndex(a, b)];
            t = std::max(t, h);
          }
        }
      }
    }
  }
  return top;
}

double pixelsPerRadian(double vfovDeg, std::uint32_t imageHeight) {
  return double(imageHeight) / (2.0 * std::tan(vfovDeg * kDegToRad / 2.0));
}

double projectedError(double errorMetres, double distance, double pixelsPerRadian) {
  return errorMetres * pixelsPerRadian / std::max(distance, 1.0);
}

std::uint32_t ringLevel(const LodOptions& o, double distance, double viewDistance,
                        std::uint32_t levels) {
  if (levels <= 1) return 0;
  for (std::uint32_t l = 0; l + 1 < levels; ++l) {
    if (!o.rings.empty() && l >= o.rings.size()) return l;  // beyond the last bin: next level
    if (distance <= ringEdge(o, l, viewDistance, levels)) return l;
  }
  return levels - 1;
}

std::uint32_t sseLevel(std::span<const double> errors, double distance, double pixelsPerRadian,
                       double pixelError, std::uint32_t finest) {
  std::uint32_t best = finest;
  for (std::uint32_t l = finest; l < errors.size(); ++l) {
    if (projectedError(errors[l], distance, pixelsPerRadian) <= pixelError) best = l;
    else break;
  }
  return best;
}

double ringMorph(const LodOptions& o, std::uint32_t level, double distance, double viewDistance,
                 std::uint32_t levels) {
  if (level + 1 >= levels) return 0;
  if (!o.rings.empty() && level >= o.rings.size()) return 0;
  const double outer = ringEdge(o, level, viewDistance, levels);
  const double inner = level == 0 ? 0.0 : ringEdge(o, level - 1, viewDistance, levels);
  const double band = std::max(kRingMorphFraction * (outer - inner), 1e-6);
  return std::clamp((distance - (outer - band)) / band, 0.0, 1.0);
}

double sseMorph(std::span<const double> errors, std::uint32_t level, double distance,
                double pixelsPerRadian, double pixelError) {
  if (level + 1 >= errors.size()) return 0;
  const double allowed = pixelError * std::max(distance, 1.0) / pixelsPerRadian;  // metres
  const double el = errors[level], ec = errors[level + 1];
  if (ec <= allowed) return 1;
  if (!(ec > el)) return 0;
  return std::clamp((allowed - el) / (ec - el), 0.0, 1.0);
}

}  // namespace sandtable::scene
