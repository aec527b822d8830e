#include "sandtable/render/renderer.h"

#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>

#include "sandtable/scene/camera_math.h"
#include "egl_context.h"
#include "module_draw.h"
#include "terrain_shading.h"

namespace sandtable::runtime {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

const char* kTerrainVertexShader = R"(#version 450 core
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in float aWater;
uniform mat4 uViewProjection;
uniform vec3 uEye;
out vec3 vNormal;
out vec3 vPosition;
out float vWater;
void main() {
  gl_Position = uViewProjection * vec4(aPosition, 1.0);
  vNormal = aNormal;
  vPosition = aPosition;
  vWater = aWater;
}
)";

// Appended to detail::shadingGlsl(): the grid has no culture, so every
// point is water or tinted. Flat shading takes the triangle's own normal
// from the screen-space derivatives of the position.
const char* kTerrainFragmentMain = R"(
in vec3 vNormal;
in vec3 vPosition;
in float vWater;
uniform vec3 uEye;
uniform bool uFlat;
out vec4 fragColor;
void main() {
  vec3 n = vNormal;
  if (uFlat) {
    n = cross(dFdx(vPosition), dFdy(vPosition));
    if (n.y < 0.0) n = -n;
  }
  fragColor = shadeSurface(0, vec3(vWater, 0.0, 0.0), vec2(0.0), vPosition.y, n,
                           distance(vPosition, uEye));
}
)";

// A full-screen triangle from gl_VertexID; the colour follows the angle of
// each pixel's view ray above the horizon, so the horizon tracks the pitch.
const char* kSkyVertexShader = R"(#version 450 core
out vec2 vNdc;
void main() {
  vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
  vNdc = p;
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

const char* kSkyFragmentShader = R"(#version 450 core
in vec2 vNdc;
uniform vec2 uTanHalfFov;
uniform float uPitch;
uniform vec3 uHorizon;
uniform vec3 uZenith;
out vec4 fragColor;
void main() {
  vec3 ray = normalize(vec3(vNdc * uTanHalfFov, -1.0));
  float sinElevation = ray.y * cos(uPitch) - ray.z * sin(uPitch);
  fragColor = vec4(mix(uHorizon, uZenith, smoothstep(0.0, 0.6, sinElevation)), 1.0);
}
)";

std::string shaderLog(GLuint obj, bool program) {
  GLint len = 0;
  program ? glGetProgramiv(obj, GL_INFO_LOG_LENGTH, &len) : glGetShaderiv(obj, GL_INFO_LOG_LENGTH, &len);
  std::string log(std::size_t(std::max(len, 1)), '\0');
  program ? glGetProgramInfoLog(obj, len, nullptr, log.data())
          : glGetShaderInfoLog(obj, len, nullptr, log.data());
  return log.c_str();
}

GLuint compile(GLenum type, const char* source, std::string& error) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &source, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    error = "shader compile failed: " + shaderLog(s, false);
    glDeleteShader(s);
    return 0;
  }
  return s;
}

}  // namespace

GLuint detail::linkProgram(const char* vs, const char* fs, std::string& error) {
  const GLuint v = compile(GL_VERTEX_SHADER, vs, error);
  if (!v) return 0;
  const GLuint f = compile(GL_FRAGMENT_SHADER, fs, error);
  if (!f) {
    glDeleteShader(v);
    return 0;
  }
  const GLuint p = glCreateProgram();
  glAttachShader(p, v);
  glAttachShader(p, f);
  glLinkProgram(p);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    error = "shader link failed: " + shaderLog(p, true);
    glDeleteProgram(p);
    return 0;
  }
  return p;
}

void detail::setShadingUniforms(GLuint program, const RenderSettings& s, const Eigen::Vector3f& sun) {
  const Eigen::Vector3f fog(s.background.r / 255.0f, s.background.g / 255.0f, s.background.b / 255.0f);
  glProgramUniform3fv(program, glGetUniformLocation(program, "uSun"), 1, sun.data());
  glProgramUniform3fv(program, glGetUniformLocation(program, "uFogColor"), 1, fog.data());
  glProgramUniform1i(program, glGetUniformLocation(program, "uFog"), s.fog);
  glProgramUniform1i(program, glGetUniformLocation(program, "uHeightMode"), s.colour == ColourMode::height);
  glProgramUniform1i(program, glGetUniformLocation(program, "uRoad"), 0);
}

namespace {

GLuint link(const char* vs, const char* fs, std::string& error) {
  return detail::linkProgram(vs, fs, error);
}

Eigen::Vector3f toVec(Rgb c) { return {c.r / 255.0f, c.g / 255.0f, c.b / 255.0f}; }

/// Direction towards the fixed sun: azimuth 200 degrees (south-south-west,
/// so a northbound eye sees the slopes facing it lit), 40 degrees up.
Eigen::Vector3f sunDirection() {
  const double az = 200.0 * kDegToRad, el = 40.0 * kDegToRad;
  return Eigen::Vector3d(std::cos(el) * std::sin(az), std::sin(el), -std::cos(el) * std::cos(az))
      .cast<float>();
}

}  // namespace

struct Renderer::Impl {
  std::unique_ptr<EglContext> egl;
  RenderSettings settings;
  std::string rendererName, version;
  GLuint fbo = 0, colorRb = 0, depthRb = 0;
  GLuint resolveFbo = 0, resolveRb = 0;  ///< single-sample copy of a multisampled frame
  GLuint terrainProgram = 0, skyProgram = 0;
  GLuint terrainVao = 0, skyVao = 0, vbo = 0;
  std::vector<std::uint8_t> readback;
  std::unique_ptr<detail::ModuleRenderer> modules;
  RenderStats stats;

  ~Impl() {
    if (!egl) return;
    modules.reset();
    glDeleteProgram(terrainProgram);
    glDeleteProgram(skyProgram);
    glDeleteVertexArrays(1, &terrainVao);
    glDeleteVertexArrays(1, &skyVao);
    glDeleteBuffers(1, &vbo);
    glDeleteFramebuffers(1, &fbo);
    glDeleteRenderbuffers(1, &colorRb);
    glDeleteRenderbuffers(1, &depthRb);
    glDeleteFramebuffers(1, &resolveFbo);
    glDeleteRenderbuffers(1, &resolveRb);
  }

  std::string createTargets() {
    const auto w = GLsizei(settings.width), h = GLsizei(settings.height);
    const auto samples = GLsizei(settings.samples);
    glCreateRenderbuffers(1, &colorRb);
    glNamedRenderbufferStorageMultisample(colorRb, samples, GL_RGBA8, w, h);
    glCreateRenderbuffers(1, &depthRb);
    glNamedRenderbufferStorageMultisample(depthRb, samples, GL_DEPTH_COMPONENT32F, w, h);
    if (samples > 0) {
      // Read-back needs single samples: resolve into a plain colour buffer.
      glCreateRenderbuffers(1, &resolveRb);
      glNamedRenderbufferStorage(resolveRb, GL_RGBA8, w, h);
      glCreateFramebuffers(1, &resolveFbo);
      glNamedFramebufferRenderbuffer(resolveFbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, resolveRb);
    }
    glCreateFramebuffers(1, &fbo);
    glNamedFramebufferRenderbuffer(fbo, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colorRb);
    glNamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depthRb);
    const GLenum status = glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
      return "framebuffer " + std::to_string(w) + "x" + std::to_string(h) +
             " is incomplete (status " + std::to_string(status) + "); try a smaller RenderSettings::width/height";
    }
    return {};
  }

  void createGeometry() {
    glCreateBuffers(1, &vbo);
    glCreateVertexArrays(1, &terrainVao);
    glVertexArrayVertexBuffer(terrainVao, 0, vbo, 0, sizeof(TerrainVertex));
    glEnableVertexArrayAttrib(terrainVao, 0);
    glVertexArrayAttribFormat(terrainVao, 0, 3, GL_FLOAT, GL_FALSE, offsetof(TerrainVertex, x));
    glVertexArrayAttribBinding(terrainVao, 0, 0);
    glEnableVertexArrayAttrib(terrainVao, 1);
    glVertexArrayAttribFormat(terrainVao, 1, 3, GL_FLOAT, GL_FALSE, offsetof(TerrainVertex, nx));
    glVertexArrayAttribBinding(terrainVao, 1, 0);
    glEnableVertexArrayAttrib(terrainVao, 2);
    glVertexArrayAttribFormat(terrainVao, 2, 1, GL_FLOAT, GL_FALSE, offsetof(TerrainVertex, water));
    glVertexArrayAttribBinding(terrainVao, 2, 0);
    glCreateVertexArrays(1, &skyVao);  // the sky needs no attributes, but core GL needs a VAO
  }

  std::string createPrograms() {
    std::string error;
    const std::string terrainFragment = detail::shadingGlsl() + kTerrainFragmentMain;
    terrainProgram = link(kTerrainVertexShader, terrainFragment.c_str(), error);
    if (!terrainProgram) return "terrain " + error;
    skyProgram = link(kSkyVertexShader, kSkyFragmentShader, error);
    if (!skyProgram) return "sky " + error;
    modules = std::make_unique<detail::ModuleRenderer>();
    if (std::string e = modules->create(settings, sunDirection()); !e.empty()) return e;
    // Settings that never change over a flight.
    const Eigen::Vector3f fogColor = toVec(settings.background);
    detail::setShadingUniforms(terrainProgram, settings, sunDirection());
    glProgramUniform1i(terrainProgram, glGetUniformLocation(terrainProgram, "uFlat"),
                       settings.shading == Shading::flat);
    // The zenith is a deeper, bluer shade of the background colour.
    const Eigen::Vector3f zenith = fogColor.cwiseProduct(Eigen::Vector3f(0.55f, 0.72f, 0.95f));
    glProgramUniform3fv(skyProgram, glGetUniformLocation(skyProgram, "uHorizon"), 1, fogColor.data());
    glProgramUniform3fv(skyProgram, glGetUniformLocation(skyProgram, "uZenith"), 1, zenith.data());
    return {};
  }

  void drawSky(const Camera& cam) {
    const float tanH = float(std::tan(cam.hfovDeg * kDegToRad / 2.0));
    const float tanV = float(std::tan(cam.vfovDeg() * kDegToRad / 2.0));
    glProgramUniform2f(skyProgram, glGetUniformLocation(skyProgram, "uTanHalfFov"), tanH, tanV);
    glProgramUniform1f(skyProgram, glGetUniformLocation(skyProgram, "uPitch"),
                       float(cam.pitchDeg * kDegToRad));
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
    glUseProgram(skyProgram);
    glBindVertexArray(skyVao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDepthMask(GL_TRUE);
  }

  void drawTerrain(const DisplayBuffer& buf) {
    if (buf.vertices.empty()) return;
    const Camera& cam = buf.camera;
    const Eigen::Vector3f eyeF(float(cam.x - buf.originX), float(cam.y), float(cam.z - buf.originZ));
    const Eigen::Matrix4f viewProjection =
        detail::viewProjection(cam, buf.originX, buf.originZ).cast<float>();
    glProgramUniformMatrix4fv(terrainProgram, glGetUniformLocation(terrainProgram, "uViewProjection"),
                              1, GL_FALSE, viewProjection.data());
    glProgramUniform3fv(terrainProgram, glGetUniformLocation(terrainProgram, "uEye"), 1, eyeF.data());
    glProgramUniform1f(terrainProgram, glGetUniformLocation(terrainProgram, "uFogDensity"),
                       float(detail::fogDensityFor(cam.viewDistance)));
    glProgramUniform1f(terrainProgram, glGetUniformLocation(terrainProgram, "uFogStart"),
                       float(detail::kFogClearFraction * cam.viewDistance));
    // Re-specifying the store each frame orphans last frame's copy, so the
    // driver never waits for the GPU to finish with it.
    glNamedBufferData(vbo, GLsizeiptr(buf.vertices.size() * sizeof(TerrainVertex)),
                      buf.vertices.data(), GL_STREAM_DRAW);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);  // reversed Z
    // From above a height field only front faces can be the nearest surface.
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    glUseProgram(terrainProgram);
    glBindVertexArray(terrainVao);
    glMultiDrawArrays(GL_TRIANGLE_STRIP, buf.firsts.data(), buf.counts.data(),
                      GLsizei(buf.firsts.size()));
    glDisable(GL_CULL_FACE);
  }

  void renderInto(const DisplayBuffer& buf) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, GLsizei(settings.width), GLsizei(settings.height));
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
    glClearDepth(0.0);  // reversed Z: 0 is the far plane
    const Rgb c = settings.clearColour;
    glClearColor(c.r / 255.0f, c.g / 255.0f, c.b / 255.0f, 1.0f);
    glClear(GL_DEPTH_BUFFER_BIT | (settings.sky ? 0 : GL_COLOR_BUFFER_BIT));
    if (settings.sky) drawSky(buf.camera);
    stats = RenderStats{};
    if (buf.moduleMode) {
      const Eigen::Matrix4f vp = detail::viewProjection(buf.camera, buf.originX, buf.originZ).cast<float>();
      modules->draw(buf, vp, stats);
    } else {
      drawTerrain(buf);
    }
  }

  /// llvmpipe compiles shaders for the actual state on the first draw;
  /// doing one tiny frame here keeps that out of frame 0's timing.
  void warmUp() {
    DisplayBuffer b;
    b.camera.y = 10;
    b.camera.aspect = double(settings.width) / double(settings.height);
    b.vertices = {{-1, 0, -20, 0, 1, 0, 0}, {-1, 0, -19, 0, 1, 0, 0}, {1, 0, -20, 0, 1, 0, 0},
                  {1, 0, -19, 0, 1, 0, 0}};
    b.firsts = {0};
    b.counts = {4};
    renderInto(b);
    Image scratch;
    readFrame(scratch);
  }

  void readFrame(Image& out) {
    const std::uint32_t w = settings.width, h = settings.height;
    const std::size_t row = std::size_t(w) * 4;
    readback.resize(row * h);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    GLuint source = fbo;
    if (resolveFbo) {
      glBlitNamedFramebuffer(fbo, resolveFbo, 0, 0, GLint(w), GLint(h), 0, 0, GLint(w), GLint(h),
                             GL_COLOR_BUFFER_BIT, GL_NEAREST);
      source = resolveFbo;
    }
    glNamedFramebufferReadBuffer(source, GL_COLOR_ATTACHMENT0);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, source);
    glReadPixels(0, 0, GLsizei(w), GLsizei(h), GL_RGBA, GL_UNSIGNED_BYTE, readback.data());
    // GL's first row is the bottom one; images store the top row first.
    out.width = w;
    out.height = h;
    out.rgba.resize(row * h);
    for (std::uint32_t y = 0; y < h; ++y) {
      std::memcpy(out.rgba.data() + row * y, readback.data() + row * (h - 1 - y), row);
    }
  }
};

Renderer::Renderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Renderer::~Renderer() = default;

Result<std::unique_ptr<Renderer>> Renderer::create(const RenderSettings& s) {
  if (s.width == 0 || s.height == 0 || s.width > 16384 || s.height > 16384) {
    return Problem{"renderer", 0, "frame size must be 1..16384 pixels each way"};
  }
  if (s.samples > 16) return Problem{"renderer", 0, "multisampling must be 0..16 samples"};
  auto egl = EglContext::create();
  if (!egl) return egl.problems();
  auto impl = std::make_unique<Impl>();
  impl->egl = std::move(egl.value());
  impl->settings = s;
  if (s.colour == ColourMode::height) {
    // Pixels hold data: nothing may blend into them.
    impl->settings.sky = false;
    impl->settings.fog = false;
    impl->settings.samples = 0;
    impl->settings.clearColour = Rgb{0, 0, 0};
  }
  if (epoxy_gl_version() < 45) {
    return Problem{kGlContextProblem, 0,
                   "the EGL context offers OpenGL " + std::to_string(epoxy_gl_version()) +
                       ", sandtable needs 4.5 core"};
  }
  impl->rendererName = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  impl->version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  std::string err = impl->createTargets();
  if (err.empty()) err = impl->createPrograms();
  if (!err.empty()) return Problem{"renderer", 0, "renderer: " + err};
  impl->createGeometry();
  impl->warmUp();
  return std::unique_ptr<Renderer>(new Renderer(std::move(impl)));
}

std::string Renderer::draw(const DisplayBuffer& buf, Image& out) {
  Impl& m = *impl_;
  m.renderInto(buf);
  m.readFrame(out);
  const GLenum e = glGetError();
  if (e != GL_NO_ERROR) return "renderer: GL error " + std::to_string(e) + " in frame " + std::to_string(buf.frame);
  return {};
}

const RenderStats& Renderer::stats() const { return impl_->stats; }

const std::string& Renderer::glRenderer() const { return impl_->rendererName; }

std::string Renderer::description() const {
  return impl_->rendererName + ", OpenGL " + impl_->version + ", EGL " + impl_->egl->platform();
}

std::optional<double> heightAt(const Image& img, std::uint32_t x, std::uint32_t y) {
  const Rgb c = img.at(x, y);
  const std::uint32_t code = (std::uint32_t(c.r) << 16) | (std::uint32_t(c.g) << 8) | c.b;
  if (code == 0) return std::nullopt;
  return code / kHeightCodeScale - kHeightCodeOffset;
}

bool headlessGlAvailable(std::string& why) {
  RenderSettings s;
  s.width = s.height = 16;
  auto r = Renderer::create(s);
  if (!r) why = r.error();
  return r.ok();
}

}  // namespace sandtable::runtime
