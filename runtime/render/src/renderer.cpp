#include "sandtable/render/renderer.h"

#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>

#include "sandtable/scene/camera_math.h"
#include "entity_draw.h"
#include "module_draw.h"
#include "object_draw.h"
#include "sandtable/render/egl_context.h"
#include "sandtable/render/gl_program.h"
#include "terrain_shading.h"

namespace sandtable::render {
namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

// Appended to detail::shadingVertexGlsl().
const char* kTerrainVertexMain = R"(
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in float aWater;
uniform mat4 uViewProjection;
uniform vec3 uEye;
out vec3 vPosition;
out float vWater;
out vec3 vTint;
out float vLight;
out float vFog;
void main() {
  gl_Position = uViewProjection * vec4(aPosition, 1.0);
  vPosition = aPosition;
  vWater = aWater;
  vTint = elevationTint(aPosition.y);
  vLight = sunLight(aNormal);
  vFog = fogWeight(distance(aPosition, uEye));
}
)";

// Appended to detail::shadingFragmentGlsl(): the grid has no culture, so
// every point is water or tinted. Flat shading lights each triangle with
// its own normal, from the screen-space derivatives of the position.
const char* kTerrainFragmentMain = R"(
in vec3 vPosition;
in float vWater;
in vec3 vTint;
in float vLight;
in float vFog;
uniform bool uFlat;
out vec4 fragColor;
void main() {
  float light = vLight;
  if (uFlat) {
    vec3 n = cross(dFdx(vPosition), dFdy(vPosition));
    light = sunLight(n.y < 0.0 ? -n : n);
  }
  fragColor = shadeSurface(0, vec3(vWater, 0.0, 0.0), vec2(0.0), vPosition.y, vTint, light, vFog);
}
)";

// The sky over kFullScreenVertexGlsl: the colour follows the angle of each
// pixel's view ray above the horizon, so the horizon tracks the pitch.
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

// The HUD pass's layer over kFullScreenVertexGlsl: one texel per pixel,
// the layer's row 0 (uploaded first, so texture row 0) at the top.
const char* kOverlayFragmentShader = R"(#version 450 core
layout(binding = 0) uniform sampler2D uLayer;
out vec4 fragColor;
void main() {
  ivec2 size = textureSize(uLayer, 0);
  ivec2 p = ivec2(gl_FragCoord.xy);
  fragColor = texelFetch(uLayer, ivec2(p.x, size.y - 1 - p.y), 0);
}
)";

// A darkened box from a copy of the frame behind it, with the arithmetic
// of the CPU panel (hud.cpp: dst + (0 - dst) * alpha + 0.5, truncated, in
// float): fixed-function blending rounds its factors to 8 bits and would
// leave some pixels one step off the panel's PNGs.
const char* kDarkenFragmentShader = R"(#version 450 core
layout(binding = 1) uniform sampler2D uBehind;
uniform float uAlpha;
out vec4 fragColor;
void main() {
  vec3 dst = round(texelFetch(uBehind, ivec2(gl_FragCoord.xy), 0).rgb * 255.0);
  precise vec3 toward = (vec3(0.0) - dst) * uAlpha;
  precise vec3 mixed = (dst + toward) + 0.5;
  fragColor = vec4(floor(mixed) / 255.0, 1.0);
}
)";

Eigen::Vector3f toVec(Rgb c) { return {c.r / 255.0f, c.g / 255.0f, c.b / 255.0f}; }

/// A box with row 0 at the top as GL's scissor rectangle (row 0 at the bottom).
void scissorTo(const PixelBox& b, std::uint32_t frameHeight) {
  glScissor(b.x, GLint(frameHeight) - b.y - b.height, b.width, b.height);
}

Problem glProblem(GLenum e, const char* where, std::uint64_t frame) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "renderer: GL error 0x%04X %s in frame %llu", unsigned(e), where,
                static_cast<unsigned long long>(frame));
  return Problem{"renderer", 0, buf};
}

}  // namespace

const char* renderPassName(RenderPass p) {
  switch (p) {
    case RenderPass::sky: return "sky";
    case RenderPass::terrain: return "terrain";
    case RenderPass::decals: return "decals";
    case RenderPass::models: return "models";
    case RenderPass::resolve: return "resolve";
    case RenderPass::hud: return "hud";
  }
  return "?";
}

struct Renderer::Impl {
  std::unique_ptr<EglContext> egl;
  RenderSettings settings;
  std::string rendererName, version;
  GLuint fbo = 0, colorRb = 0, depthRb = 0;
  GLuint resolveFbo = 0, resolveRb = 0;  ///< single-sample copy of a multisampled frame
  GlProgram terrainProgram, skyProgram, overlayProgram, darkenProgram;
  GLuint terrainVao = 0, emptyVao = 0, vbo = 0;
  GLuint layerTexture = 0;  ///< the HUD pass's overlay layer, frame-sized
  GLuint behindTexture = 0; ///< the frame under the darkened boxes, copied there
  std::vector<std::uint8_t> readback;
  std::unique_ptr<detail::ModuleRenderer> modules;
  std::unique_ptr<detail::ObjectRenderer> objects;  ///< when RenderSettings::icons and staticObjects are set
  std::unique_ptr<detail::EntityRenderer> entities;  ///< when RenderSettings::icons is set
  std::unique_ptr<ModelsPass> models;
  RenderStats stats;
  std::uint64_t frame = 0, readBackCount = 0;
  std::uint64_t layerOverlay = 0;  ///< Overlay::id() the layer texture holds

  ~Impl() {
    if (!egl) return;
    models.reset();
    entities.reset();
    objects.reset();
    modules.reset();
    terrainProgram.reset();
    skyProgram.reset();
    overlayProgram.reset();
    darkenProgram.reset();
    glDeleteVertexArrays(1, &terrainVao);
    glDeleteVertexArrays(1, &emptyVao);
    glDeleteBuffers(1, &vbo);
    glDeleteTextures(1, &layerTexture);
    glDeleteTextures(1, &behindTexture);
    glDeleteFramebuffers(1, &fbo);
    glDeleteRenderbuffers(1, &colorRb);
    glDeleteRenderbuffers(1, &depthRb);
    glDeleteFramebuffers(1, &resolveFbo);
    glDeleteRenderbuffers(1, &resolveRb);
  }

  /// The single-sampled target: what the HUD pass draws into, read-back
  /// reads and present() blits.
  GLuint frameTarget() const { return resolveFbo ? resolveFbo : fbo; }
  GLuint frameColour() const { return resolveFbo ? resolveRb : colorRb; }

  Status createTargets() {
    const auto w = GLsizei(settings.width), h = GLsizei(settings.height);
    const auto samples = GLsizei(settings.samples);
    glCreateRenderbuffers(1, &colorRb);
    glNamedRenderbufferStorageMultisample(colorRb, samples, GL_RGBA8, w, h);
    glCreateRenderbuffers(1, &depthRb);
    glNamedRenderbufferStorageMultisample(depthRb, samples, GL_DEPTH_COMPONENT32F, w, h);
    if (samples > 0) {
      // The HUD, read-back and present need single samples: resolve into a
      // plain colour buffer.
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
      return Problem{"renderer", 0,
                     "renderer: framebuffer " + std::to_string(w) + "x" + std::to_string(h) +
                         " is incomplete (status " + std::to_string(status) +
                         "); try a smaller RenderSettings::width / height"};
    }
    glCreateTextures(GL_TEXTURE_2D, 1, &layerTexture);
    glTextureStorage2D(layerTexture, 1, GL_RGBA8, w, h);
    const std::vector<std::uint8_t> clear(std::size_t(w) * std::size_t(h) * 4, 0);
    glTextureSubImage2D(layerTexture, 0, 0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, clear.data());
    glCreateTextures(GL_TEXTURE_2D, 1, &behindTexture);
    glTextureStorage2D(behindTexture, 1, GL_RGBA8, w, h);
    return {};
  }

  void createGeometry() {
    glCreateBuffers(1, &vbo);
    glCreateVertexArrays(1, &terrainVao);
    glVertexArrayVertexBuffer(terrainVao, 0, vbo, 0, sizeof(scene::TerrainVertex));
    glEnableVertexArrayAttrib(terrainVao, 0);
    glVertexArrayAttribFormat(terrainVao, 0, 3, GL_FLOAT, GL_FALSE, offsetof(scene::TerrainVertex, x));
    glVertexArrayAttribBinding(terrainVao, 0, 0);
    glEnableVertexArrayAttrib(terrainVao, 1);
    glVertexArrayAttribFormat(terrainVao, 1, 3, GL_FLOAT, GL_FALSE, offsetof(scene::TerrainVertex, nx));
    glVertexArrayAttribBinding(terrainVao, 1, 0);
    glEnableVertexArrayAttrib(terrainVao, 2);
    glVertexArrayAttribFormat(terrainVao, 2, 1, GL_FLOAT, GL_FALSE, offsetof(scene::TerrainVertex, water));
    glVertexArrayAttribBinding(terrainVao, 2, 0);
    // Full-screen triangles need no attributes, but core GL needs a VAO.
    glCreateVertexArrays(1, &emptyVao);
  }

  Status createPrograms() {
    auto terrain = GlProgram::build("terrain", detail::shadingVertexGlsl() + kTerrainVertexMain,
                                    detail::shadingFragmentGlsl(false) + kTerrainFragmentMain);
    if (!terrain) return terrain.problems();
    terrainProgram = std::move(terrain.value());
    auto sky = GlProgram::build("sky", kFullScreenVertexGlsl, kSkyFragmentShader);
    if (!sky) return sky.problems();
    skyProgram = std::move(sky.value());
    auto overlay = GlProgram::build("overlay", kFullScreenVertexGlsl, kOverlayFragmentShader);
    if (!overlay) return overlay.problems();
    overlayProgram = std::move(overlay.value());
    auto darken = GlProgram::build("darken", kFullScreenVertexGlsl, kDarkenFragmentShader);
    if (!darken) return darken.problems();
    darkenProgram = std::move(darken.value());
    modules = std::make_unique<detail::ModuleRenderer>();
    if (Status st = modules->create(settings); !st) return st;
    if (settings.icons && !settings.icons->icons.empty()) {
      if (settings.staticObjects) {
        objects = std::make_unique<detail::ObjectRenderer>();
        if (Status st = objects->create(settings); !st) return st;
      }
      entities = std::make_unique<detail::EntityRenderer>();
      if (Status st = entities->create(settings, objects ? objects->textures() : 0); !st) return st;
    }
    // Settings that never change over a flight.
    detail::setShadingUniforms(terrainProgram, settings);
    terrainProgram.set("uFlat", int(settings.shading == Shading::flat));
    // The zenith is a deeper, bluer shade of the background colour.
    const Eigen::Vector3f horizon = toVec(settings.background);
    const Eigen::Vector3f zenith = horizon.cwiseProduct(Eigen::Vector3f(0.55f, 0.72f, 0.95f));
    skyProgram.set("uHorizon", horizon.x(), horizon.y(), horizon.z());
    skyProgram.set("uZenith", zenith.x(), zenith.y(), zenith.z());
    return {};
  }

  void drawSky(const scene::Camera& cam) {
    const float tanH = float(std::tan(cam.hfovDeg * kDegToRad / 2.0));
    const float tanV = float(std::tan(cam.vfovDeg() * kDegToRad / 2.0));
    skyProgram.set("uTanHalfFov", tanH, tanV);
    skyProgram.set("uPitch", float(cam.pitchDeg * kDegToRad));
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
    skyProgram.use();
    glBindVertexArray(emptyVao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDepthMask(GL_TRUE);
  }

  void drawMesh(const scene::DisplayBuffer& buf) {
    if (buf.vertices.empty()) return;
    const Eigen::Matrix4f viewProjection =
        scene::viewProjection(buf.camera, buf.originX, buf.originZ).cast<float>();
    terrainProgram.setMatrix4("uViewProjection", viewProjection.data());
    detail::setFrameShading(terrainProgram, buf);
    // Re-specifying the store each frame orphans last frame's copy, so the
    // driver never waits for the GPU to finish with it.
    glNamedBufferData(vbo, GLsizeiptr(buf.vertices.size() * sizeof(scene::TerrainVertex)),
                      buf.vertices.data(), GL_STREAM_DRAW);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);  // reversed Z
    // From above a height field only front faces can be the nearest surface.
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    terrainProgram.use();
    glBindVertexArray(terrainVao);
    glMultiDrawArrays(GL_TRIANGLE_STRIP, buf.firsts.data(), buf.counts.data(),
                      GLsizei(buf.firsts.size()));
    glDisable(GL_CULL_FACE);
  }

  void beginFrame() {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, GLsizei(settings.width), GLsizei(settings.height));
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
    glClearDepth(0.0);  // reversed Z: 0 is the far plane
    const Rgb c = settings.clearColour;
    glClearColor(c.r / 255.0f, c.g / 255.0f, c.b / 255.0f, 1.0f);
    glClear(GL_DEPTH_BUFFER_BIT | (settings.sky ? 0 : GL_COLOR_BUFFER_BIT));
  }

  void resolve() {
    if (!resolveFbo) return;
    const auto w = GLint(settings.width), h = GLint(settings.height);
    glBlitNamedFramebuffer(fbo, resolveFbo, 0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
  }

  Status runPass(RenderPass pass, const scene::DisplayBuffer& buf, const Eigen::Matrix4f& vp) {
    switch (pass) {
      case RenderPass::sky:
        if (settings.sky) drawSky(buf.camera);
        break;
      case RenderPass::terrain:
        if (buf.moduleMode) {
          modules->prepare(buf, stats);
          modules->drawTerrain(buf, vp, stats);
        } else {
          drawMesh(buf);
        }
        break;
      case RenderPass::decals:
        if (buf.moduleMode) modules->drawDecals(buf, stats);
        break;
      case RenderPass::models:
        if (objects && buf.moduleMode) objects->draw(buf, vp, *modules, stats);
        if (entities) {
          static const std::vector<scene::DynamicInstance> none;
          entities->draw(buf, vp, buf.moduleMode ? modules.get() : nullptr,
                         objects && buf.moduleMode ? objects->diverted() : none, stats);
        }
        if (models) {
          PassContext ctx{buf, {}};
          std::copy(vp.data(), vp.data() + 16, ctx.viewProjection.begin());
          if (Status st = models->draw(ctx); !st) return st;
          glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        }
        break;
      case RenderPass::resolve:
        resolve();
        break;
      case RenderPass::hud:
        break;  // drawOverlay(): the caller fills the overlay after draw()
    }
    return {};
  }

  Status drawPasses(const scene::DisplayBuffer& buf) {
    stats = RenderStats{};
    frame = buf.frame;
    beginFrame();
    const Eigen::Matrix4f vp = scene::viewProjection(buf.camera, buf.originX, buf.originZ).cast<float>();
    Status st;
    for (const RenderPass pass : kRenderPasses) {
      st = runPass(pass, buf, vp);
      if (!st) break;
    }
    if (buf.moduleMode) modules->finishFrame(buf, stats);
    return st;
  }

  void uploadLayer(const Overlay& overlay) {
    const Image& layer = overlay.layer();
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, GLint(layer.width));
    std::vector<PixelBox> boxes = overlay.changedBoxes();
    if (overlay.id() != layerOverlay) boxes = {PixelBox{0, 0, int(layer.width), int(layer.height)}};
    layerOverlay = overlay.id();
    for (const PixelBox& b : boxes) {
      const std::uint8_t* first = layer.rgba.data() + (std::size_t(b.y) * layer.width + std::size_t(b.x)) * 4;
      glTextureSubImage2D(layerTexture, 0, b.x, b.y, b.width, b.height, GL_RGBA, GL_UNSIGNED_BYTE, first);
    }
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  }

  void drawHud(const Overlay& overlay) {
    uploadLayer(overlay);
    glBindFramebuffer(GL_FRAMEBUFFER, frameTarget());
    glViewport(0, 0, GLsizei(settings.width), GLsizei(settings.height));
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
    glEnable(GL_SCISSOR_TEST);
    glDisable(GL_BLEND);
    glBindVertexArray(emptyVao);
    darkenProgram.use();
    glBindTextureUnit(1, behindTexture);
    for (const Darken& d : overlay.darkened()) {
      const GLint y = GLint(settings.height) - d.box.y - d.box.height;  // GL rows from the bottom
      glCopyImageSubData(frameColour(), GL_RENDERBUFFER, 0, d.box.x, y, 0, behindTexture, GL_TEXTURE_2D, 0,
                         d.box.x, y, 0, d.box.width, d.box.height, 1);
      darkenProgram.set("uAlpha", d.alpha);
      scissorTo(d.box, settings.height);
      glDrawArrays(GL_TRIANGLES, 0, 3);
    }
    const PixelBox bounds = overlay.drawnBounds();
    if (!bounds.empty()) {
      glEnable(GL_BLEND);
      glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
      overlayProgram.use();
      glBindTextureUnit(0, layerTexture);
      scissorTo(bounds, settings.height);
      glDrawArrays(GL_TRIANGLES, 0, 3);
    }
    glDisable(GL_BLEND);
    glDisable(GL_SCISSOR_TEST);
    glDepthMask(GL_TRUE);
  }

  /// llvmpipe compiles shaders for the actual state on the first draw;
  /// doing one tiny frame (with a panel) here keeps that out of frame 0's timing.
  void warmUp() {
    scene::DisplayBuffer b;
    b.camera.y = 10;
    b.camera.aspect = double(settings.width) / double(settings.height);
    b.vertices = {{-1, 0, -20, 0, 1, 0, 0}, {-1, 0, -19, 0, 1, 0, 0}, {1, 0, -20, 0, 1, 0, 0},
                  {1, 0, -19, 0, 1, 0, 0}};
    b.firsts = {0};
    b.counts = {4};
    (void)drawPasses(b);
    if (objects || entities) {
      glBindFramebuffer(GL_FRAMEBUFFER, fbo);
      const Eigen::Matrix4f vp = scene::viewProjection(b.camera, b.originX, b.originZ).cast<float>();
      if (objects) objects->warmUp(b, vp);
      if (entities) entities->warmUp(b, vp);
      resolve();
    }
    if (settings.colour != ColourMode::height) {
      Overlay o;
      o.begin(settings.width, settings.height);
      o.layer().rgba[3] = 255;
      o.darken({0, 0, 1, 1}, 0.5f);
      o.drawn({0, 0, 1, 1});
      drawHud(o);
    }
    Image scratch;
    readInto(scratch);
  }

  void readInto(Image& out) {
    const std::uint32_t w = settings.width, h = settings.height;
    const std::size_t row = std::size_t(w) * 4;
    readback.resize(row * h);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    const GLuint source = frameTarget();
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

  Status glStatus(const char* where) const {
    const GLenum e = glGetError();
    if (e != GL_NO_ERROR) return glProblem(e, where, frame);
    return {};
  }

  /// Blits the frame into the window's back buffer, fitted and centred
  /// (nearest pixels at 1:1 and when enlarging, linear when shrinking),
  /// black around it, and swaps. Inside the window's lock.
  Status presentLocked(std::uint32_t winW, std::uint32_t winH) {
    const double s = std::min(double(winW) / settings.width, double(winH) / settings.height);
    const auto vw = GLint(std::lround(settings.width * s)), vh = GLint(std::lround(settings.height * s));
    const GLint x0 = (GLint(winW) - vw) / 2, y0 = (GLint(winH) - vh) / 2;
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glViewport(0, 0, GLsizei(winW), GLsizei(winH));
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    glBlitNamedFramebuffer(frameTarget(), 0, 0, 0, GLint(settings.width), GLint(settings.height), x0, y0,
                           x0 + vw, y0 + vh, GL_COLOR_BUFFER_BIT, s < 1.0 ? GL_LINEAR : GL_NEAREST);
    if (Status st = glStatus("presenting the frame"); !st) return st;
    return egl->swapBuffers();
  }
};

Renderer::Renderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Renderer::~Renderer() = default;

Result<std::unique_ptr<Renderer>> Renderer::create(const RenderSettings& s, PresentTarget* window) {
  if (s.width == 0 || s.height == 0 || s.width > 16384 || s.height > 16384) {
    return Problem{"renderer", 0, "RenderSettings::width and height must be 1..16384 pixels"};
  }
  if (s.samples > 16) return Problem{"renderer", 0, "RenderSettings::samples must be 0..16"};
  auto egl = window ? EglContext::createOn(*window) : EglContext::create();
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
  if (Status st = impl->createTargets(); !st) return st.problems();
  if (Status st = impl->createPrograms(); !st) return st.problems();
  impl->createGeometry();
  impl->warmUp();
  return std::unique_ptr<Renderer>(new Renderer(std::move(impl)));
}

Status Renderer::draw(const scene::DisplayBuffer& buf) {
  Impl& m = *impl_;
  if (Status st = m.drawPasses(buf); !st) return st;
  return m.glStatus("drawing");
}

Status Renderer::drawOverlay(const Overlay& overlay) {
  Impl& m = *impl_;
  if (m.settings.colour == ColourMode::height) return {};  // data pixels: nothing over them
  const Image& layer = overlay.layer();
  if (layer.width != m.settings.width || layer.height != m.settings.height) {
    return Problem{"renderer", 0,
                   "renderer: the overlay is " + std::to_string(layer.width) + "x" + std::to_string(layer.height) +
                       ", the frame " + std::to_string(m.settings.width) + "x" + std::to_string(m.settings.height)};
  }
  m.drawHud(overlay);
  return m.glStatus("in the HUD pass");
}

void Renderer::finish() {
  const GLsync fence = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  // Flush first, then wait in steps: a second per step, for ever.
  GLbitfield flags = GL_SYNC_FLUSH_COMMANDS_BIT;
  while (glClientWaitSync(fence, flags, 1'000'000'000) == GL_TIMEOUT_EXPIRED) flags = 0;
  glDeleteSync(fence);
}

Status Renderer::readFrame(Image& out) {
  impl_->readInto(out);
  ++impl_->readBackCount;
  return impl_->glStatus("reading the frame back");
}

Status Renderer::present() {
  Impl& m = *impl_;
  PresentTarget* window = m.egl->window();
  if (!window) return Problem{"renderer", 0, "renderer: present() needs a renderer created on a window"};
  Status st;
  window->withSurface([&](std::uint32_t w, std::uint32_t h) { st = m.presentLocked(w, h); });
  return st;
}

IndexedGridRate Renderer::measureIndexedGrid(const scene::Camera& camera, std::uint32_t squares, double spacing,
                                             std::uint32_t nodeSquares, std::uint32_t frames) {
  Impl& m = *impl_;
  const detail::PlainGridRun run =
      m.modules->drawPlainGrid(camera, squares, spacing, nodeSquares, frames, [&] { m.beginFrame(); });
  IndexedGridRate r;
  r.triangles = run.triangles;
  r.draws = run.draws;
  r.frames = std::uint32_t(run.frameMs.size());
  if (run.frameMs.empty()) return r;
  std::vector<double> ms = run.frameMs;
  std::sort(ms.begin(), ms.end());
  const auto at = [&](double q) { return ms[std::min(ms.size() - 1, std::size_t(q * double(ms.size() - 1) + 0.5))]; };
  r.p50Ms = at(0.5);
  r.p99Ms = at(0.99);
  double sum = 0;
  for (const double v : ms) sum += v;
  r.meanMs = sum / double(ms.size());
  r.trianglesPerSecond = r.p50Ms > 0 ? double(r.triangles) / (r.p50Ms / 1000.0) : 0;
  return r;
}

void Renderer::setModelsPass(std::unique_ptr<ModelsPass> pass) { impl_->models = std::move(pass); }

const RenderStats& Renderer::stats() const { return impl_->stats; }

std::uint64_t Renderer::framesReadBack() const { return impl_->readBackCount; }

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

}  // namespace sandtable::render
