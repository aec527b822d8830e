#pragma once
// Drawing the load modules' static objects (module version 5) with the
// icons of icons.pack. Private to the renderer; every call on the render
// thread. Design: docs/VIEWER.md, "Objects".
//
// Meshes. At create() every icon's alive state is flattened into one
// vertex set in its body frame (each articulated part moved by its
// offsets; a static object never turns its turret), with the base colour
// of each vertex's material, and one index range per level of detail. All
// icons share one static vertex and one index buffer.
//
// Per frame. For every module the terrain pass drew, each object is kept
// when its icon's far range (capped at the view distance) reaches it, its
// ground point lies in the view triangle and its bounding sphere in the
// frustum. Its base is the elevation stored for the terrain level drawn
// under it, morphed as that level is (lod.h: the morph moves a level's
// surface linearly towards the next coarser one, and each level's objectY
// lies on that level's own triangle), so nothing floats or sinks when the
// terrain changes level. Its own level of detail is the icon's range bin
// (seed IX.B.1). Instances are bucketed by (icon, level) and drawn with
// one instanced draw each from a buffer streamed each frame.
//
// Fading: beyond the seed, an object fades in over the last
// RenderSettings::objectFade of its far range by a screen-door dither
// (ordered 4 x 4 pattern; discarded fragments): no blending, no sorting,
// no pop.
//
// Impostors: at create() each icon's full-detail alive state is rendered
// once from the south, orthographic, lit as the meshes are, into one layer
// of a texture array (kImpostorTexels square, mipmapped). An object whose
// projected size falls under RenderSettings::impostorPixels is drawn as
// one point sprite of that size with its icon's layer, alpha-tested: one
// vertex instead of the icon's coarsest mesh (the tree's 24 triangles),
// which is where llvmpipe spends a forest's frame time.
//
// Cells: the per-frame work is per cell, not per object, except for the
// objects a frame keeps. When a module is first drawn its objects are
// grouped once by the finest terrain node they stand on (one drawn level
// and morph each), each group in ascending order of its thinning hash over
// the square of its sprite's side (ObjectRenderer::ModuleObjects::key), with
// the bounds the tests need. A frame then rejects a whole cell out of range
// or view, and in a cell wholly in range and view whose objects are all
// sprites under the thinning size it visits only the prefix whose key can
// pass at the cell's nearest distance: the rest are counted thinned without
// being visited. A cell holds copies of its objects and of each drawn
// level's objectY in its order, so that the visits read memory in sequence.
// Only the objects visited get the exact per-object tests, so the frame
// keeps and counts the same objects as visiting them all would.
#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <array>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/formats/module.h"
#include "sandtable/render/gl_program.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/display_buffer.h"

namespace sandtable::render::detail {

class ModuleRenderer;

/// One icon vertex: 32 bytes.
struct IconVertex {
  float x, y, z;
  std::uint32_t normal;  ///< GL_INT_2_10_10_10_REV, normalized
  std::uint32_t rgba;    ///< the material's base colour
  float s, t;            ///< texture coordinates, bottom-left origin
  float layer;           ///< the material's texture: its layer in uploadIconTextures' array; -1: none
};
static_assert(sizeof(IconVertex) == 32, "vertex layout is shared with the shader");

/// GLSL for fragment stages after shadingHeaderGlsl(): bool iconColour(
/// base, uv, layer, out colour), the base colour times the icon texture
/// (uniform uIconTextures) where SANDTABLE_ICON_TEXTURE is defined and the
/// layer is >= 0, false for a cut-out texel; and bool fadedOut(fade), the
/// screen-door fade's discard.
extern const char* const kIconTextureGlsl;

/// shadingHeaderGlsl(), the texture switch, kIconTextureGlsl and `main`:
/// an icon program's fragment stage.
std::string iconFragmentGlsl(bool textured, const char* main);

/// Vertex `v` of mesh `m` of `icon`, moved by `offset` (its part's origin),
/// with its material's colour and texture layer; `textured` is set when it
/// samples a texture.
IconVertex iconVertex(const iconpack::Icon& icon, const iconpack::Mesh& m, std::size_t v,
                      const std::array<float, 3>& offset, bool& textured);

/// Binds IconVertex's attributes to binding 0 of `vao`: position 0,
/// normal 1, colour 2, texture coordinates 5, texture layer 6.
void bindIconVertex(GLuint vao);

/// One drawn object: 24 bytes, divisor 1. A sprite's (one point, place())
/// holds its square's centre in x, y, z, its impostor layer in heading and
/// the square's side times its scale in scale.
struct ObjectInstance {
  float x, y, z;   ///< base, relative to the buffer origin
  float heading;   ///< radians clockwise from north
  float scale;
  float fade;      ///< 1 opaque .. 0 gone (screen-door)
};
static_assert(sizeof(ObjectInstance) == 24, "instance layout is shared with the shader");

/// Where (icon, level) lies in the shared buffers.
struct IconLevelRange {
  std::uint32_t firstIndex = 0, count = 0;
  std::int32_t baseVertex = 0;
};

/// The flattened meshes of every icon of a pack: vertices and indices
/// (relative to each icon's first vertex), per icon and level. Pure CPU.
struct IconMeshes {
  std::vector<IconVertex> vertices;
  std::vector<std::uint32_t> indices;
  std::vector<std::vector<IconLevelRange>> ranges;  ///< [icon][level]
  std::vector<bool> textured;  ///< per icon: a material of its alive state has a texture
};
IconMeshes flattenIcons(const iconpack::Pack& pack);

/// An icon's sprite: the square the impostor covers, in the icon's units
/// (scaled by each object's scale). Its centre stands `centre` above the
/// base, on the icon's vertical axis.
struct IconSprite {
  float centre = 0;  ///< height of the square's centre above the origin
  float size = 0;    ///< the square's side: max(height, 2 * widest reach from the axis)
};
IconSprite spriteOf(const iconpack::Icon& icon);

/// Texels a side of each icon's impostor layer.
inline constexpr std::uint32_t kImpostorTexels = 64;

/// The icon level drawn at `distance` metres: the first whose far range
/// reaches past it; -1 beyond the last range or beyond `viewDistance`.
/// `fade` gets 1, or less inside the last `fadeFraction` of the far range.
int iconLevelAt(const iconpack::Icon& icon, double distance, double viewDistance, double fadeFraction,
                float& fade);

class ObjectRenderer {
 public:
  ObjectRenderer() = default;
  ~ObjectRenderer();
  ObjectRenderer(const ObjectRenderer&) = delete;
  ObjectRenderer& operator=(const ObjectRenderer&) = delete;

  /// Compiles the program and uploads every icon of s.icons (not null).
  Status create(const RenderSettings& s);
  /// The models pass's objects, after the terrain pass of the same frame
  /// (`modules` says which level is drawn where). Adds to stats' object counters.
  void draw(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, const ModuleRenderer& modules,
            RenderStats& stats);
  /// One tiny instance drawn into the warm-up frame, so that the driver
  /// compiles the program for this state before frame 0 (llvmpipe compiles
  /// at the first draw).
  void warmUp(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection);
  /// The objects of the last draw() that buf.dynamic.objectOverrides
  /// changed (knocked over, stumps, ruins), placed on the drawn ground, for
  /// the entity pass to draw with their dead model or lying down; destroyed
  /// ones are left out altogether.
  const std::vector<scene::DynamicInstance>& diverted() const { return diverted_; }
  /// The icon texture array (0: the pack has none), for the entity pass.
  GLuint textures() const { return textures_; }

 private:
  /// Streams the buckets and draws each (icon, level) with instances,
  /// then each icon's sprites.
  void submit(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, RenderStats& stats);
  /// Renders every icon's impostor layer (create(), with the icon buffers up).
  Status bakeImpostors();
  void drawSprites(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, GLuint firstInstance,
                   RenderStats& stats);
  void collect(const scene::DisplayBuffer& buf, const ModuleRenderer& modules, RenderStats& stats);
  /// What collect() sets up once a frame for the per-object tests (object_draw.cpp).
  struct Frame;
  /// One module's objects by the finest terrain node they stand on.
  struct ModuleObjects {
    const paging::ResidentModule* module = nullptr;
    std::uint64_t generation = 0;
    std::uint32_t side = 0;            ///< cells a side (the finest level's nodes)
    std::vector<std::uint32_t> order;  ///< object indices, cell after cell, each by ascending key
    /// order[k]'s thinning hash over the square of its sprite side times
    /// its scale: kept where key < (focal / (distance * thin pixels))^2.
    std::vector<double> key;
    struct Cell {
      std::uint32_t first = 0, count = 0;  ///< in order
      float minX = 0, maxX = 0, minZ = 0, maxZ = 0;  ///< objects' bases, module metres
      float maxRadius = 0;             ///< largest bounding sphere
      float minHalf = 0, maxHalf = 0;  ///< half heights (the centre above the base)
      float maxSprite = 0;             ///< largest sprite side times scale
      float minFar = 0, maxFar = 0;    ///< icons' last switch ranges (infinite: none)
    };
    std::vector<Cell> cells;
    std::vector<module::Object> objects;  ///< the objects of order, copied (read in sequence)
    /// Per level, per cell: least and greatest objectY; empty until needed.
    std::vector<std::vector<std::array<float, 2>>> y;
    /// Per level: objectY in order; empty until needed.
    std::vector<std::vector<float>> levelY;
    std::uint64_t lastFrame = 0;
  };
  /// The exact tests of object i of buf.modules[m] (drawn with `look`),
  /// then its bucket or the thinned count.
  void consider(const Frame& f, std::uint32_t m, std::size_t i, scene::ObjectLook look, RenderStats& stats);
  /// The tests after the drawn level's: object i (`o`) of module `d` on its
  /// base y0 of the drawn level, moved by `morph` towards *y1 (the next
  /// coarser level's) where y1 is not null.
  void place(const Frame& f, const scene::ModuleDraw& d, std::uint32_t i, const module::Object& o, float y0,
             const float* y1, float morph, scene::ObjectLook look, RenderStats& stats);
  /// Module m's objects by cell (built at its first draw, or again when its
  /// slot holds another generation); nullptr when it has none to cell.
  ModuleObjects* cellsOf(const scene::DisplayBuffer& buf, std::uint32_t m);
  /// The objects of one cell of module m: all of them, or the rejected,
  /// skipped and thinned in a block (see "Cells" above).
  void collectCell(const Frame& f, std::uint32_t m, ModuleObjects& mo, std::uint32_t cell, RenderStats& stats);
  /// Queues a changed object for the entity pass (world x, drawn base y, world z).
  void divert(const iconpack::Icon& icon, const module::Object& o, scene::ObjectLook look, double x, double y, double z);

  RenderSettings settings_;
  GlProgram program_, texturedProgram_;  ///< the second samples the icon textures
  GLuint textures_ = 0;                   ///< uploadIconTextures()
  std::vector<bool> textured_;            ///< per icon
  GLuint vao_ = 0, vertexBuffer_ = 0, indexBuffer_ = 0, instanceBuffer_ = 0;
  GlProgram spriteProgram_;
  GLuint spriteVao_ = 0, impostors_ = 0;  ///< impostors_: GL_TEXTURE_2D_ARRAY, one layer per icon
  std::vector<IconSprite> sprites_;        ///< per icon
  std::uint64_t instanceCapacity_ = 0;  ///< bytes
  std::vector<std::vector<IconLevelRange>> ranges_;  ///< [icon][level]
  std::vector<std::uint32_t> levelBase_;             ///< first bucket of each icon
  // Per-frame scratch (capacity kept).
  std::vector<std::vector<ObjectInstance>> buckets_;  ///< levelBase_[icon] + level
  std::vector<std::vector<ObjectInstance>> spriteBuckets_;  ///< per icon, drawn by one glDrawArrays
  std::vector<ObjectInstance> stream_;
  std::vector<double> farRange_;  ///< per icon, this frame
  std::vector<scene::DynamicInstance> diverted_;
  std::unordered_map<std::uint64_t, ModuleObjects> cells_;  ///< by module (kx << 32 | kz)
  std::uint64_t frame_ = 0;                                 ///< collect() calls, for evicting cells_
};

}  // namespace sandtable::render::detail
