#pragma once
// One shader-program helper for every GL program of the renderer and the
// window: compile and link with the driver's info log in the error, and
// uniforms by name. Also the one full-screen-triangle vertex shader that
// the sky, the HUD pass and the window's blit share.
//
// Thread safety: a GlProgram belongs to the GL context that was current
// when it was built; use and destroy it with that context current.
#include <cstdint>
#include <string>

#include "sandtable/base/result.h"

namespace sandtable::render {

/// Problem::file of shader compile and link failures.
inline constexpr const char* kShaderProblem = "shader";

/// "#version 450 core": one triangle covering the viewport from
/// gl_VertexID (draw 3 vertices, no attributes); `vNdc` is the pixel's
/// normalised device position, -1..1 both ways.
inline constexpr const char* kFullScreenVertexGlsl = R"(#version 450 core
out vec2 vNdc;
void main() {
  vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
  vNdc = p;
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

class GlProgram {
 public:
  /// Compiles both stages and links them. `what` names the program in the
  /// error ("terrain shader: fragment stage: <info log>").
  static Result<GlProgram> build(const std::string& what, const std::string& vertexSource,
                                 const std::string& fragmentSource);
  GlProgram() = default;
  ~GlProgram();
  GlProgram(GlProgram&& other) noexcept;
  GlProgram& operator=(GlProgram&& other) noexcept;
  GlProgram(const GlProgram&) = delete;
  GlProgram& operator=(const GlProgram&) = delete;

  std::uint32_t id() const { return id_; }
  explicit operator bool() const { return id_ != 0; }
  /// glUseProgram.
  void use() const;
  /// The uniform's location; -1 when the program has none by that name
  /// (the driver may drop one the shader never reads), which set* ignore.
  int uniform(const char* name) const;
  void set(const char* name, int v) const;
  void set(const char* name, float v) const;
  void set(const char* name, float x, float y) const;
  void set(const char* name, float x, float y, float z) const;
  /// A column-major 4 x 4 matrix.
  void setMatrix4(const char* name, const float* columnMajor) const;
  /// Deletes the program (the context must be current).
  void reset();
  /// Forgets the program without deleting it: its context is gone.
  void abandon() { id_ = 0; }

 private:
  explicit GlProgram(std::uint32_t id) : id_(id) {}
  std::uint32_t id_ = 0;
};

}  // namespace sandtable::render
