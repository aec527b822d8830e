#pragma once
// Drawing load modules on the render thread: a cache of one vertex buffer
// per resident (module, level), built from the pager's decoded levels the
// first time a frame lists them and released when the pager frees or
// replaces the module (its generation changes, or it leaves the pager's
// window). Private to the renderer; every call on the render thread.
//
// Decals (docs/_culture.md, section 9): the skin (priority 1) of every
// module is drawn first with depth writes; then each decal priority in
// ascending order, depth writes off, depth test GEQUAL (reversed Z) and a
// polygon offset growing with the priority, so a decal wins against its
// own coplanar skin but not against terrain in front of it.
#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "sandtable/runtime/display_buffer.h"
#include "sandtable/runtime/renderer.h"

namespace sandtable::runtime::detail {

/// Compiles and links a program (renderer.cpp); 0 and `error` on failure.
GLuint linkProgram(const char* vertexSource, const char* fragmentSource, std::string& error);

// Colour per vertex means one vertex per triangle corner: the upper and
// lower halves of a square share posts but not colours. 24 bytes each.
struct GpuVertex {
  float x, y, z;
  float morphDelta;     ///< next coarser level's surface minus this level's, here
  std::uint32_t rgba;   ///< GL_UNSIGNED_BYTE x 4, normalized
  std::uint32_t normal; ///< GL_INT_2_10_10_10_REV, normalized
};
static_assert(sizeof(GpuVertex) == 24, "vertex layout is shared with the shader");

class ModuleRenderer {
 public:
  ModuleRenderer() = default;
  ~ModuleRenderer();
  ModuleRenderer(const ModuleRenderer&) = delete;
  ModuleRenderer& operator=(const ModuleRenderer&) = delete;

  /// Compiles the program; "" or the error.
  std::string create(const RenderSettings& s, const Eigen::Vector3f& sun);
  /// Uploads what is missing, draws, then releases what the pager let go.
  void draw(const DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, RenderStats& stats);

 private:
  /// The triangles of one priority, bucketed by quadtree node: node m's
  /// vertices are [start[m], start[m + 1]) (Morton order, lod.h).
  struct Block {
    std::uint8_t priority = 1;
    std::vector<GLint> start;
  };
  struct Entry {
    std::uint64_t generation = 0;
    GLuint vbo = 0;
    std::vector<Block> blocks;  ///< ascending priority; the underlay last
    std::uint64_t lastFrame = 0;
    std::uint64_t bytes = 0;
  };
  /// Range priority of the lattice underlay (not a module priority).
  static constexpr std::uint8_t kUnderlayPriority = 255;
  Entry& entryFor(const ModuleDraw& d, std::uint32_t level, std::uint64_t frame, RenderStats& stats);
  void upload(const ModuleDraw& d, std::uint32_t level, std::uint32_t nodeSquares, Entry& e);
  void release(RenderStats& stats, const DisplayBuffer& buf);
  void drawPriority(const DisplayBuffer& buf, std::uint8_t lo, std::uint8_t hi,
                    const std::vector<Entry*>& entries);

  RenderSettings settings_;
  GLuint program_ = 0, vao_ = 0;
  GLint uViewProjection_ = -1, uOffset_ = -1, uMorph_ = -1, uEye_ = -1, uFogDensity_ = -1, uFogStart_ = -1;
  std::unordered_map<std::uint64_t, Entry> cache_;
  std::uint64_t gpuBytes_ = 0;
  std::uint32_t nodeSquares_ = 4;
};

}  // namespace sandtable::runtime::detail
