#pragma once
// Drawing load modules on the render thread: a cache of one buffer per
// resident (module, level), vertices then u32 indices, built from the
// pager's decoded levels the first time a frame lists them and released
// when the pager frees or replaces the module (its generation changes, or
// it leaves the pager's window). Private to the renderer; every call on the
// render thread.
//
// Shading::smooth: indexed triangles; a module vertex is copied only where
// triangles of different colours meet. Its normal and water weight are the
// grid's, interpolated at the vertex (so every level, skirt and cut piece
// is lit like the grid mesh), computed once per upload. Shading::flat (the
// seed's look): three vertices per triangle with its face normal and its
// half's colour, indexed 0, 1, 2, ...
//
// Decals (docs/CULTURE.md, section 9): the skin (priority 1) of every
// module is drawn first with depth writes; then each decal priority in
// ascending order, depth writes off, depth test GEQUAL (reversed Z) and a
// polygon offset growing with the priority, so a decal wins against its
// own coplanar skin but not against terrain in front of it.
#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/render/gl_program.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/display_buffer.h"

namespace sandtable::runtime::detail {

// 32 bytes each.
struct GpuVertex {
  float x, y, z;
  float morphDelta;     ///< next coarser level's surface minus this level's, here
  std::uint32_t rgba;   ///< GL_UNSIGNED_BYTE x 4, normalized; alpha: SurfaceKind (terrain_shading.h)
  std::uint32_t normal; ///< GL_INT_2_10_10_10_REV, normalized
  float s, t;           ///< roads: S along in road widths, T across 0..1 (docs/CULTURE.md 8)
};
static_assert(sizeof(GpuVertex) == 32, "vertex layout is shared with the shader");

class ModuleRenderer {
 public:
  ModuleRenderer() = default;
  ~ModuleRenderer();
  ModuleRenderer(const ModuleRenderer&) = delete;
  ModuleRenderer& operator=(const ModuleRenderer&) = delete;

  /// Compiles the program and makes the road texture.
  Status create(const RenderSettings& s);
  /// One frame, in the renderer's pass order: prepare() uploads what is
  /// missing, drawTerrain() the skin and its underlay (terrain pass),
  /// drawDecals() the decal priorities and the modules' own object
  /// polygons (decals pass), finishFrame() releases what the pager let go.
  void prepare(const DisplayBuffer& buf, RenderStats& stats);
  void drawTerrain(const DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection);
  void drawDecals(const DisplayBuffer& buf);
  void finishFrame(const DisplayBuffer& buf, RenderStats& stats);

 private:
  /// The triangles of one priority, bucketed by quadtree node: node m's
  /// indices are [start[m], start[m + 1]) (Morton order, lod.h).
  /// Lowest and highest vertex a node's indices use (for glDrawRangeElements).
  using NodeRange = std::pair<std::uint32_t, std::uint32_t>;
  struct Block {
    std::uint8_t priority = 1;
    std::vector<GLint> start;
    std::vector<NodeRange> range;  ///< per node
  };
  struct Entry {
    std::uint64_t generation = 0;
    GLuint vbo = 0;                ///< vertices, then indices from indexOffset
    std::uint64_t indexOffset = 0; ///< bytes
    std::vector<Block> blocks;  ///< ascending priority; the underlay last
    std::uint64_t lastFrame = 0;
    std::uint64_t bytes = 0;
  };
  /// Range priority of the lattice underlay (not a module priority).
  static constexpr std::uint8_t kUnderlayPriority = 255;
  Entry& entryFor(const ModuleDraw& d, std::uint32_t level, std::uint64_t frame, RenderStats& stats);
  void upload(const ModuleDraw& d, std::uint32_t level, Entry& e);
  void release(RenderStats& stats, const DisplayBuffer& buf);
  void drawPriority(const DisplayBuffer& buf, std::uint8_t lo, std::uint8_t hi,
                    const std::vector<Entry*>& entries);

  void createRoadTexture();

  RenderSettings settings_;
  GlProgram program_;
  GLuint vao_ = 0, roadTexture_ = 0;
  GLint uOffset_ = -1, uMorph_ = -1;  ///< set per node: looked up once
  std::vector<Entry*> entries_;  ///< this frame's, one per buf.nodes entry
  std::unordered_map<std::uint64_t, Entry> cache_;
  std::uint64_t gpuBytes_ = 0;
  std::uint32_t nodeSquares_ = 4;
  double moduleSize_ = 0;  ///< metres along a module edge (DisplayBuffer::moduleSize)
};

}  // namespace sandtable::runtime::detail
