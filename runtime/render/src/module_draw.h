#pragma once
// Drawing load modules on the render thread. Private to the renderer;
// every call on the render thread. Design: docs/VIEWER.md, "Module draws".
// The class's parts live by concern: the GPU cache and uploads
// (module_cache.cpp), LoD resolution with the upload budget's fallback
// (module_lod.cpp), command lists and passes (module_passes.cpp), the road
// texture (road_texture.cpp) and the arena (gpu_arena.h). The CPU meshing
// of a level (module_mesh.h) runs on the pager's loader threads.
//
// Memory. Every resident (module, level) is one Entry: its vertices and
// its u32 indices (relative to its first vertex) sub-allocated from one
// persistent, coherent, mapped GL buffer (GpuArena: a first-fit free list
// that coalesces, grown by doubling with a GPU copy that keeps every
// offset). An upload is a memcpy into the mapping; a released block is
// reused only once the GPU has passed a fence set after its last frame.
// Entries are copied from the levels' meshes (LevelMesh, built on a loader
// thread, or here when a level comes without one) the first time a frame
// lists them (within RenderSettings::uploadBudgetBytes a frame) and
// released when the pager frees or replaces the module.
//
// Draws. Each pass is one glMultiDrawElementsIndirect: one command per
// node range (NodeDraw) and block, written into a mapped ring of command
// buffers; the node's module offset and morph factor are a per-draw
// vertex attribute (divisor 1, the command's baseInstance). No GL state
// changes between nodes and no per-frame allocation (scratch vectors keep
// their capacity).
//
// Programs: the tint, light and fog are per vertex (terrain_shading.h);
// the module program is built with and without the road texture, and a
// list takes the textured one only when one of its blocks has a road
// triangle (Block::roads): llvmpipe pays for a texture fetch at every
// fragment of a program that may sample it.
//
// Shading::smooth: indexed triangles; a module vertex is copied only where
// triangles of different colours meet. Its normal and water weight are the
// grid's, interpolated at the vertex (so every level, skirt and cut piece
// is lit like the grid mesh), computed once per level mesh. Shading::flat (the
// seed's look): three vertices per triangle with its face normal and its
// half's colour.
//
// Decals (docs/CULTURE.md, section 9): the skin (priority 1) of every
// module is drawn first with depth writes; then each decal priority in
// ascending order, depth writes off, depth test GEQUAL (reversed Z) and a
// polygon offset growing with the priority, so a decal wins against its
// own coplanar skin but not against terrain in front of it.
//
// Seams (docs/VIEWER.md, "Seams"): skirts face out of their node and the
// terrain pass culls back faces (CCW front); skirts and the plain lattice
// under culture-cut squares are drawn after the skin with a polygon offset
// away from the eye, so they show only through cracks and pinholes. Skirt
// feet are raised from the file's module-wide depth to what their own
// stretch of edge needs (LevelMesh::feet, written into the arena at upload),
// when every level is resident.
#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <array>
#include <bitset>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/render/gl_program.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/display_buffer.h"
#include "gpu_arena.h"
#include "module_mesh.h"

namespace sandtable::render::detail {

/// The GPU cache's key of a module's level.
inline std::uint64_t cacheKey(std::uint32_t kx, std::uint32_t kz, std::uint32_t level) {
  return std::uint64_t(kx) | (std::uint64_t(kz) << 20) | (std::uint64_t(level) << 40);
}

/// A plain indexed grid drawn with the module program (Renderer::measureIndexedGrid).
struct PlainGridRun {
  std::uint64_t triangles = 0;
  std::uint32_t draws = 0;
  std::vector<double> frameMs;
};

class ModuleRenderer {
 public:
  ModuleRenderer() = default;
  ~ModuleRenderer();
  ModuleRenderer(const ModuleRenderer&) = delete;
  ModuleRenderer& operator=(const ModuleRenderer&) = delete;

  /// Compiles the program and makes the road texture.
  Status create(const RenderSettings& s);
  /// One frame, in the renderer's pass order: prepare() uploads what is
  /// missing (within the budget) and builds the frame's draw commands,
  /// drawTerrain() the skin, then skirts and underlay (terrain pass),
  /// drawDecals() the decal priorities and the modules' own object
  /// polygons (decals pass), finishFrame() releases what the pager let go.
  void prepare(const scene::DisplayBuffer& buf, RenderStats& stats);
  void drawTerrain(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, RenderStats& stats);
  void drawDecals(const scene::DisplayBuffer& buf, RenderStats& stats);
  void finishFrame(const scene::DisplayBuffer& buf, RenderStats& stats);

  /// Draws `frames` frames of a plain grid of squares x squares (one
  /// vertex per post, two triangles a square, nodes of nodeSquares squares
  /// as in a module) seen by `camera`, through the same program, buffers
  /// and draw path as the modules; times each frame to the GPU's finish.
  /// `beginFrame` binds and clears the target before each frame.
  /// The level and morph the terrain of buf.modules[module] is drawn with
  /// at module-local (x, z) this frame (after the upload budget's
  /// fallback); false where none of it is drawn. Valid from prepare() to
  /// finishFrame().
  bool drawnAt(std::uint32_t module, double x, double z, std::uint32_t& level, float& morph) const;

  PlainGridRun drawPlainGrid(const scene::Camera& camera, std::uint32_t squares, double spacing,
                             std::uint32_t nodeSquares, std::uint32_t frames,
                             const std::function<void()>& beginFrame);

 private:
  /// Node blocks relative to the entry's first index (module_mesh.h).
  using Block = MeshBlock;
  struct Entry {
    std::uint64_t generation = 0;
    bool resident = false;
    std::uint64_t vertexOffset = 0, vertexBytes = 0;  ///< arena block of the vertices
    std::uint64_t indexOffset = 0, indexBytes = 0;    ///< arena block of the indices
    std::vector<Block> blocks;  ///< ascending priority
    std::bitset<256> priorities;
    std::uint64_t lastFrame = 0;
    std::uint64_t bytes = 0;
  };
  /// glMultiDrawElementsIndirect's command.
  struct Command {
    GLuint count, instanceCount, firstIndex;
    GLint baseVertex;
    GLuint baseInstance;
  };
  /// The per-draw attribute: module offset (x, z) from the buffer origin, morph.
  struct DrawData {
    float ox, oz, morph, pad;
  };
  /// One node range as drawn this frame (after the upload budget's fallback).
  struct Drawn {
    const Entry* entry;
    std::uint32_t level, first, last;
    float morph;
    std::uint32_t module;
    std::uint32_t cells = 0, side0 = 0;  ///< its module's finest-level Cells in cells_, and their side
  };
  /// What a frame draws over one node of a module's finest level.
  struct Cell {
    std::uint32_t level = UINT32_MAX;  ///< none
    float morph = 0;
  };

  Entry* ready(std::uint64_t key);
  /// The level's mesh built on a loader thread for these settings (raised
  /// feet too when `raise`), or null.
  const LevelMesh* preparedMesh(const paging::ResidentRef& ref, std::uint32_t level, bool raise);
  void upload(const scene::ModuleDraw& d, std::uint32_t level, Entry& e, RenderStats& stats);
  void storeEntry(Entry& e, const std::vector<GpuVertex>& vertices, const std::vector<std::uint32_t>& indices);
  void freeEntry(Entry& e);
  void release(RenderStats& stats, const scene::DisplayBuffer& buf);
  void resolveModule(const scene::DisplayBuffer& buf, std::size_t first, std::size_t last, RenderStats& stats);
  void buildCommands(const scene::DisplayBuffer& buf);
  /// The skirt on `side` of node `node` (dr's level) can show: a neighbour
  /// across it is another module's, not drawn, or drawn at another level
  /// or morph. Same level and morph share the edge exactly: no crack.
  bool skirtNeeded(const Drawn& dr, std::uint32_t node, std::uint32_t side) const;
  /// The commands of a Block::sides block for dr: the needed sides, runs merged.
  void appendSkirts(const Drawn& dr, const Block& b, GLuint firstIndex, GLint baseVertex, GLuint instance);
  void multiDraw(std::size_t list, RenderStats& stats);
  void bindArena();

  void createRoadTexture();

  RenderSettings settings_;
  /// program_ samples the road texture; plainProgram_, for the lists with
  /// no road triangle this frame (roadLists_), does not.
  GlProgram program_, plainProgram_;
  const GlProgram* used_ = nullptr;  ///< bound since drawTerrain()
  GLuint vao_ = 0, roadTexture_ = 0;
  GpuArena arena_;
  GLuint boundArena_ = 0;
  /// Command and per-draw rings: kRing frames of room, each frame's slice
  /// fenced, grown when a frame needs more.
  static constexpr std::uint32_t kRing = 3;
  GLuint commandBuffer_ = 0, drawBuffer_ = 0;
  Command* commandMap_ = nullptr;
  DrawData* drawMap_ = nullptr;
  std::uint64_t ringCommands_ = 0, ringDraws_ = 0;  ///< per slice
  std::uint32_t ringSlot_ = 0;
  std::array<GLsync, kRing> ringFence_{};
  void ensureRing(std::uint64_t commands, std::uint64_t draws);

  std::unordered_map<std::uint64_t, Entry> cache_;
  std::uint64_t gpuBytes_ = 0;
  std::uint32_t nodeSquares_ = 4;
  double moduleSize_ = 0;  ///< metres along a module edge (DisplayBuffer::moduleSize)
  /// What this renderer's level meshes are built with (prepare()), and the
  /// last loader-built settings found equal to it.
  std::shared_ptr<const MeshSettings> meshSettings_;
  const MeshSettings* matchedSettings_ = nullptr;
  LevelMesh ownMesh_;  ///< a level built here (no matching LevelMesh came with it)

  // Per-frame scratch (capacity kept).
  std::vector<Drawn> drawn_;
  std::vector<Cell> cells_;  ///< per drawn module, side0 x side0 (Drawn::cells)
  /// Per buf.modules index: its first Cell in cells_ and their side (none: side 0).
  std::vector<std::pair<std::uint32_t, std::uint32_t>> moduleCells_;
  struct Span {
    std::uint32_t level;
    std::uint64_t f, t;  ///< finest-grid Morton range
    float morph;
    bool fallback;
  };
  std::vector<Span> spans_;
  std::vector<DrawData> drawData_;
  /// Command lists: [0] skin, [1] skirts and underlay, [2 + p] decal
  /// priority p (2..98), [101] objects (99..253).
  static constexpr std::size_t kLists = 102;
  std::array<std::vector<Command>, kLists> lists_;
  std::array<std::uint64_t, kLists> listOffset_{};  ///< bytes into the command buffer
  std::bitset<256> framePriorities_;
  std::bitset<kLists> roadLists_;
};

}  // namespace sandtable::render::detail
