#pragma once
// The CPU half of drawing a load module (module_draw.cpp): one level's
// vertices, indices and node blocks, built from the pager's decoded level,
// with morph deltas, grid normals and water weights, skirt facings and
// colours, and the skirt feet raised once every level is resident.
//
// Where it runs (docs/VIEWER.md, "Module draws"). The viewer installs
// moduleLevelPreparer (renderer.h) as the pager's PagerOptions::prepareLevel,
// so a loader thread builds each level's LevelMesh as it publishes the level
// (the worker phase, as cesium-native splits a tile load), and the render
// thread only copies it into the GPU arena (ModuleRenderer::upload). A level
// that comes without a mesh built for the renderer's settings (no hook, or
// other settings) is built on the render thread by the same functions, so
// both paths give the same bytes.
//
// Thread contract: buildLevelMesh and raiseSkirtFeet are pure functions of
// their arguments (scratch is per thread); a LevelMesh is written only by
// the thread that builds it, before the pager publishes its level.
#include <Eigen/Dense>
#include <bitset>
#include <cstdint>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include "sandtable/paging/pager.h"
#include "sandtable/render/renderer.h"
#include "terrain_shading.h"

namespace sandtable::render::detail {

// 32 bytes each.
struct GpuVertex {
  float x, y, z;
  float morphDelta;     ///< next coarser level's surface minus this level's, here
  std::uint32_t rgba;   ///< GL_UNSIGNED_BYTE x 4, normalized; alpha: SurfaceKind (terrain_shading.h)
  std::uint32_t normal; ///< GL_INT_2_10_10_10_REV, normalized
  float s, t;           ///< roads: S along in road widths, T across 0..1 (docs/CULTURE.md 8)
};
static_assert(sizeof(GpuVertex) == 32, "vertex layout is shared with the shader");

/// Pseudo priorities of blocks that are not module priorities.
inline constexpr std::uint8_t kSkirtPriority = 254;
inline constexpr std::uint8_t kUnderlayPriority = 255;
/// Node sides, towards -z, +z, -x, +x (module-local).
inline constexpr std::uint32_t kSideNorth = 0, kSideSouth = 1, kSideWest = 2, kSideEast = 3;

/// The triangles of one priority, bucketed by quadtree node: node m's
/// indices are [start[m], start[m + 1]) (Morton order, lod.h), relative
/// to the level's first index.
struct MeshBlock {
  std::uint8_t priority = 1;
  std::vector<std::uint32_t> start;
  bool roads = false;  ///< some triangle has a road kind: drawn with the road program
  /// The skirts: start[4 m + s] for node m's side s (kSide*) instead of start[m].
  bool sides = false;
};

/// What a level's mesh depends on besides the level: the render settings
/// it reads and the module layout.
struct MeshSettings {
  bool flat = false;  ///< Shading::flat
  decltype(RenderSettings::grid) grid;  ///< RenderSettings::grid, compared by pointer
  std::vector<std::uint8_t> waterMaterials;
  std::vector<MaterialColour> palette;
  std::uint16_t uncoveredMaterial = 0;
  std::uint32_t nodeSquares = 4;  ///< DisplayBuffer::nodeSquares
  double moduleSize = 0;          ///< DisplayBuffer::moduleSize
};
MeshSettings meshSettings(const RenderSettings& s, std::uint32_t nodeSquares, double moduleSize);
bool sameMeshSettings(const MeshSettings& a, const MeshSettings& b);

/// One level ready for the GPU arena.
struct LevelMesh final : paging::LevelExtra {
  std::shared_ptr<const MeshSettings> settings;  ///< what it was built with
  std::vector<GpuVertex> vertices;               ///< heights as the level stores them
  std::vector<std::uint32_t> indices;
  std::vector<MeshBlock> blocks;  ///< ascending priority
  std::bitset<256> priorities;
  std::uint32_t underlayMissing = 0;  ///< RenderStats::underlayMissing
  /// Per vertex: the level vertex it copies (raiseSkirtFeet).
  std::vector<std::uint32_t> source;
  /// The skirt feet raised once every level is resident (raiseSkirtFeet):
  /// vertex index and height. Valid when `raised`; the render thread reads
  /// them only through a reference whose finestLevel() is 0.
  std::vector<std::pair<std::uint32_t, float>> feet;
  bool raised = false;
};

/// Builds level `level` of `m` (it and the next coarser one written) into
/// `out` (its vectors keep their capacity); out.settings is left as it is.
void buildLevelMesh(const paging::ResidentModule& m, std::uint32_t level, const MeshSettings& s, LevelMesh& out);
/// Fills `feet` of each non-null meshes[l] (built from level l of `m`) and
/// marks it raised. Needs every level of `m` written.
void raiseSkirtFeet(const paging::ResidentModule& m, const std::vector<LevelMesh*>& meshes);

std::uint32_t packColour(Rgb c, SurfaceKind kind);
std::uint32_t packNormal(const Eigen::Vector3f& n);

}  // namespace sandtable::render::detail
