#include "sandtable/render/icon_sheet.h"

#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <numbers>

#include "icon_textures.h"
#include "object_draw.h"
#include "sandtable/render/egl_context.h"
#include "sandtable/render/gl_program.h"
#include "sandtable/render/hud.h"

namespace sandtable::render {
namespace {

const char* kSheetVertex = R"(#version 450 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColour;
layout(location = 5) in vec2 aUv;
layout(location = 6) in float aLayer;
uniform mat4 uViewProjection;
out vec3 vColour;
out vec3 vNormal;
out vec2 vUv;
flat out float vLayer;
void main() {
  gl_Position = uViewProjection * vec4(aPosition, 1.0);
  vColour = aColour.rgb;
  vNormal = aNormal;
  vUv = aUv;
  vLayer = aLayer;
}
)";

// After "#version", the texture define and kIconTextureGlsl. Two-sided:
// imported models need not be closed nor consistently wound.
const char* kSheetFragmentMain = R"(
in vec3 vColour;
in vec3 vNormal;
in vec2 vUv;
flat in float vLayer;
uniform vec3 uSun;
out vec4 fragColor;
void main() {
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing && dot(n, uSun) < 0.0) n = -n;
  float light = 0.35 + 0.65 * max(dot(n, uSun), 0.0);
  vec3 colour;
  if (!iconColour(vColour, vUv, vLayer, colour)) discard;
  fragColor = vec4(colour * light, 1.0);
}
)";

constexpr double kDegrees = std::numbers::pi / 180.0;

/// The eye's frame for one icon: the same for all its levels.
struct CellCamera {
  Eigen::Matrix4f viewProjection;
  Eigen::Vector3f sun;
};

CellCamera cameraFor(const iconpack::Icon& icon, const IconSheetOptions& o) {
  const auto& b = icon.bounds;
  const Eigen::Vector3d lo(b[0], b[1], b[2]), hi(b[3], b[4], b[5]);
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double radius = std::max(0.5 * (hi - lo).norm(), 1e-3);
  const double half = 0.5 * double(o.fovDegrees) * kDegrees;
  const double distance = radius / std::sin(half);
  const double az = double(o.azimuthDegrees) * kDegrees, el = double(o.elevationDegrees) * kDegrees;
  // X east, Y up, Z south; the bearing is clockwise from north (-Z).
  const Eigen::Vector3d back(std::sin(az) * std::cos(el), std::sin(el), -std::cos(az) * std::cos(el));
  const Eigen::Vector3d eye = centre + distance * back;
  const Eigen::Vector3d f = -back;
  const Eigen::Vector3d s = f.cross(Eigen::Vector3d::UnitY()).normalized();
  const Eigen::Vector3d u = s.cross(f);
  Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
  view.block<1, 3>(0, 0) = s.transpose();
  view.block<1, 3>(1, 0) = u.transpose();
  view.block<1, 3>(2, 0) = -f.transpose();
  view(0, 3) = -s.dot(eye);
  view(1, 3) = -u.dot(eye);
  view(2, 3) = f.dot(eye);
  const double zNear = std::max(distance - 1.5 * radius, 0.01 * distance);
  const double zFar = distance + 1.5 * radius;
  const double t = 1.0 / std::tan(half);
  Eigen::Matrix4d proj = Eigen::Matrix4d::Zero();
  proj(0, 0) = t;  // square cells
  proj(1, 1) = t;
  proj(2, 2) = (zFar + zNear) / (zNear - zFar);
  proj(2, 3) = 2.0 * zFar * zNear / (zNear - zFar);
  proj(3, 2) = -1.0;
  // The sun over the eye's left shoulder, high.
  const Eigen::Vector3d sun = (back - 0.6 * s + 1.2 * Eigen::Vector3d::UnitY()).normalized();
  return {(proj * view).cast<float>(), sun.cast<float>()};
}

/// The GL objects of one sheet; destroyed with the context current.
struct SheetGl {
  GlProgram program;
  GLuint vao = 0, vertices = 0, indices = 0, fbo = 0, colour = 0, depth = 0, textures = 0;
  ~SheetGl() {
    program.reset();
    glDeleteTextures(1, &textures);
    glDeleteFramebuffers(1, &fbo);
    glDeleteRenderbuffers(1, &colour);
    glDeleteRenderbuffers(1, &depth);
    glDeleteVertexArrays(1, &vao);
    glDeleteBuffers(1, &vertices);
    glDeleteBuffers(1, &indices);
  }
};

Status setUp(SheetGl& gl, const iconpack::Pack& pack, const detail::IconMeshes& meshes, std::uint32_t cell,
             std::vector<std::string>& warnings) {
  gl.textures = detail::uploadIconTextures(pack, warnings);
  const std::string fragment = std::string("#version 450 core\n") +
                               (gl.textures ? "#define SANDTABLE_ICON_TEXTURE\n" : "") + detail::kIconTextureGlsl +
                               kSheetFragmentMain;
  auto program = GlProgram::build("icon sheet shader", kSheetVertex, fragment);
  if (!program) return program.problems();
  gl.program = std::move(program.value());
  if (gl.textures) {
    gl.program.use();
    gl.program.set("uIconTextures", 2);
    glBindTextureUnit(2, gl.textures);
  }
  glCreateBuffers(1, &gl.vertices);
  glNamedBufferStorage(gl.vertices,
                       GLsizeiptr(std::max<std::size_t>(1, meshes.vertices.size()) * sizeof(detail::IconVertex)),
                       meshes.vertices.empty() ? nullptr : meshes.vertices.data(), 0);
  glCreateBuffers(1, &gl.indices);
  glNamedBufferStorage(gl.indices, GLsizeiptr(std::max<std::size_t>(1, meshes.indices.size()) * sizeof(std::uint32_t)),
                       meshes.indices.empty() ? nullptr : meshes.indices.data(), 0);
  glCreateVertexArrays(1, &gl.vao);
  glVertexArrayVertexBuffer(gl.vao, 0, gl.vertices, 0, sizeof(detail::IconVertex));
  glVertexArrayElementBuffer(gl.vao, gl.indices);
  detail::bindIconVertex(gl.vao);
  glCreateRenderbuffers(1, &gl.colour);
  glNamedRenderbufferStorage(gl.colour, GL_RGBA8, GLsizei(cell), GLsizei(cell));
  glCreateRenderbuffers(1, &gl.depth);
  glNamedRenderbufferStorage(gl.depth, GL_DEPTH_COMPONENT24, GLsizei(cell), GLsizei(cell));
  glCreateFramebuffers(1, &gl.fbo);
  glNamedFramebufferRenderbuffer(gl.fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, gl.colour);
  glNamedFramebufferRenderbuffer(gl.fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, gl.depth);
  if (glCheckNamedFramebufferStatus(gl.fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
    return Problem{kShaderProblem, 0, "icon sheet: the driver refused a framebuffer of " + std::to_string(cell) +
                                          " pixels (IconSheetOptions::cell)"};
  }
  return {};
}

/// Draws one cell and copies it into `page` at (x, y), top row first.
void drawCell(const SheetGl& gl, const detail::IconLevelRange& r, const CellCamera& cam, const IconSheetOptions& o,
              Image& page, std::uint32_t x, std::uint32_t y, std::vector<std::uint8_t>& scratch) {
  const std::uint32_t n = o.cell;
  glBindFramebuffer(GL_FRAMEBUFFER, gl.fbo);
  glViewport(0, 0, GLsizei(n), GLsizei(n));
  glClearColor(o.background.r / 255.0f, o.background.g / 255.0f, o.background.b / 255.0f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  if (r.count > 0) {
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    gl.program.use();
    gl.program.setMatrix4("uViewProjection", cam.viewProjection.data());
    gl.program.set("uSun", cam.sun.x(), cam.sun.y(), cam.sun.z());
    glBindVertexArray(gl.vao);
    glDrawElementsBaseVertex(GL_TRIANGLES, GLsizei(r.count), GL_UNSIGNED_INT,
                             reinterpret_cast<const void*>(std::uintptr_t(r.firstIndex) * sizeof(std::uint32_t)),
                             r.baseVertex);
    glBindVertexArray(0);
  }
  scratch.resize(std::size_t(n) * n * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, GLsizei(n), GLsizei(n), GL_RGBA, GL_UNSIGNED_BYTE, scratch.data());
  for (std::uint32_t row = 0; row < n; ++row) {
    const std::uint8_t* src = &scratch[std::size_t(n - 1 - row) * n * 4];  // GL is bottom-up
    std::copy(src, src + std::size_t(n) * 4, &page.rgba[(std::size_t(y + row) * page.width + x) * 4]);
  }
}

std::string format(const char* fmt, double a, double b = 0, double c = 0) {
  char line[96];
  std::snprintf(line, sizeof line, fmt, a, b, c);
  return line;
}

std::string headerLine(const iconpack::Icon& icon) {
  const auto& b = icon.bounds;
  std::string s = icon.name;
  s += format("  %.1f X %.1f X %.1f M", double(b[3] - b[0]), double(b[4] - b[1]), double(b[5] - b[2]));
  s += format("  CYLINDER R %.1f H %.1f M", double(icon.cylinderRadius), double(icon.cylinderHeight));
  return s;
}

void fill(Image& img, Rgb c) {
  for (std::size_t k = 0; k < img.rgba.size(); k += 4) {
    img.rgba[k] = c.r;
    img.rgba[k + 1] = c.g;
    img.rgba[k + 2] = c.b;
    img.rgba[k + 3] = 255;
  }
}

}  // namespace

Result<IconSheet> renderIconSheet(const iconpack::Pack& pack, std::size_t first, std::size_t count,
                                  const IconSheetOptions& o) {
  IconSheet sheet;
  first = std::min(first, pack.icons.size());
  count = std::min(count, pack.icons.size() - first);
  if (count == 0) return sheet;
  std::size_t columns = 1;
  for (std::size_t i = first; i < first + count; ++i) columns = std::max(columns, pack.icons[i].ranges.size());
  const std::uint32_t rowHeight = kIconSheetHeader + o.cell + kIconSheetFooter;
  sheet.image.width = 2 * kIconSheetMargin + std::uint32_t(columns) * (o.cell + kIconSheetMargin);
  sheet.image.height = kIconSheetMargin + std::uint32_t(count) * rowHeight;
  sheet.image.rgba.assign(std::size_t(sheet.image.width) * sheet.image.height * 4, 0);
  fill(sheet.image, {246, 246, 244});

  auto egl = EglContext::create();
  if (!egl) return egl.problems();
  const detail::IconMeshes meshes = detail::flattenIcons(pack);
  std::vector<std::uint8_t> scratch;
  {
    SheetGl gl;
    if (Status st = setUp(gl, pack, meshes, o.cell, sheet.warnings); !st.ok()) return st.problems();
    for (std::size_t i = first; i < first + count; ++i) {
      const iconpack::Icon& icon = pack.icons[i];
      const CellCamera cam = cameraFor(icon, o);
      const std::uint32_t top = kIconSheetMargin + std::uint32_t(i - first) * rowHeight;
      drawText(sheet.image, int(kIconSheetMargin), int(top + 4), headerLine(icon), 2, o.label);
      for (std::size_t l = 0; l < icon.ranges.size(); ++l) {
        const std::uint32_t x = kIconSheetMargin + std::uint32_t(l) * (o.cell + kIconSheetMargin);
        const std::uint32_t y = top + kIconSheetHeader;
        drawCell(gl, meshes.ranges[i][l], cam, o, sheet.image, x, y, scratch);
        const std::uint64_t tris = iconpack::triangleCount(icon, l);
        drawText(sheet.image, int(x), int(y + o.cell + 4), format("L%.0f  %.0f TRIS", double(l), double(tris)), 2,
                 o.label);
        const double near = l == 0 ? 0.0 : double(icon.ranges[l - 1]);
        drawText(sheet.image, int(x), int(y + o.cell + 4 + 2 * kLineAdvance),
                 format("%.0f-%.0f M", near, double(icon.ranges[l])), 2, o.label);
        sheet.cells.push_back({std::uint32_t(i), std::uint32_t(l), x, y, tris});
      }
    }
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  }
  return sheet;
}

}  // namespace sandtable::render
