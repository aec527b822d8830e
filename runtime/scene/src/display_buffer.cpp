#include "sandtable/scene/display_buffer.h"

#include <algorithm>
#include <array>
#include <chrono>

namespace sandtable::scene {
namespace {

/// Grid material index -> water (1) or not (0).
using WaterTable = std::array<float, 256>;

TerrainVertex vertexAt(const grid::HeightField& g, std::uint32_t i, std::uint32_t j, double originX,
                       double originZ, const WaterTable& water) {
  const double s = g.spacing();
  const auto n = g.normal(i, j);
  return {static_cast<float>(i * s - originX), g.elevation(i, j),
          static_cast<float>(j * s - originZ), n[0], n[1], n[2], water[g.material(i, j)]};
}

/// Appends the strip for one row span: posts i = first..last+1 along rows
/// j and j+1, north post first, so the strip's triangles are NW-SW-NE and
/// SW-NE-SE, i.e. the upper and lower triangles of each square.
void appendStrip(const grid::HeightField& g, const paging::RowSpan& span, const WaterTable& water,
                 DisplayBuffer& out) {
  const auto first = static_cast<std::int32_t>(out.vertices.size());
  for (std::uint32_t i = span.firstI; i <= span.lastI + 1; ++i) {
    out.vertices.push_back(vertexAt(g, i, span.j, out.originX, out.originZ, water));
    out.vertices.push_back(vertexAt(g, i, span.j + 1, out.originX, out.originZ, water));
  }
  out.firsts.push_back(first);
  out.counts.push_back(static_cast<std::int32_t>(out.vertices.size()) - first);
  out.triangles += 2ull * span.squares();
}

}  // namespace

double Camera::vfovDeg() const { return paging::verticalFovDeg(hfovDeg, aspect); }

paging::ViewTriangle viewTriangleFor(const Camera& cam, double spacing) {
  paging::ViewTriangleParams p;
  p.eyeX = cam.x;
  p.eyeZ = cam.z;
  p.headingDeg = cam.headingDeg;
  p.halfAngleDeg = paging::groundHalfAngleDeg(cam.hfovDeg, cam.vfovDeg(), cam.pitchDeg);
  p.viewDistance = cam.viewDistance;
  p.pullback = spacing;  // seed: one post spacing behind the eye
  return paging::makeViewTriangle(p);
}

void fillDisplayBuffer(const grid::HeightField& g, const Camera& cam, std::uint64_t frame,
                       DisplayBuffer& out, const std::vector<std::uint8_t>& waterMaterials) {
  const auto start = std::chrono::steady_clock::now();
  out.frame = frame;
  out.camera = cam;
  out.originX = cam.x;
  out.originZ = cam.z;
  out.triangle = viewTriangleFor(cam, g.spacing());
  out.spans = paging::selectSquares(out.triangle, g.spacing(), g.postsX() - 1, g.postsZ() - 1);
  out.vertices.clear();
  out.firsts.clear();
  out.counts.clear();
  out.triangles = 0;
  out.vertices.reserve(2 * (paging::countSquares(out.spans) + out.spans.size()));
  WaterTable water{};
  for (const std::uint8_t m : waterMaterials) water[m] = 1.0f;
  for (const auto& span : out.spans) appendStrip(g, span, water, out);
  out.cpuMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace sandtable::scene
