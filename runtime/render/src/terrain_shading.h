#pragma once
// The colour rules both terrain programs share (grid mesh and load
// modules), as GLSL for each stage, so the two modes draw the same ground
// the same way (docs/VIEWER.md, "Colours"). Private to the renderer.
//
// A surface point gets, in this order:
//   - its material class colour where culture covers it (modules only);
//   - water colour where the grid's per-post material is water (the water
//     weight, interpolated between posts, is at least one half);
//   - else the elevation tint: a fixed ramp in metres above the datum.
// Then it is lit by the fixed sun (ambient 0.40 + 0.60 diffuse) and fogged.
// The tint, the light and the fog weight are the vertex stage's,
// interpolated; the choice among them (culture, water, tint) and the road
// texture are per fragment, so coastlines and road markings stay sharp.
//
// `--colour height` replaces all of it: the fragment writes its world
// height as a 24-bit code in RGB (renderer.h, kHeightCode*).
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

#include "sandtable/render/gl_program.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/camera_math.h"

namespace sandtable::render::detail {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kDegToRad = kPi / 180.0;

/// What a module vertex's colour means: its alpha byte (GpuVertex::rgba).
/// Every vertex of a triangle has the same kind.
enum class SurfaceKind : std::uint8_t {
  tint = 0,      ///< no culture: red byte = water weight (0 or 255), else elevation tint
  road = 85,     ///< class colour times the road texture, no markings
  marked = 170,  ///< class colour times the road texture, with its white markings
  colour = 255,  ///< the class colour as it is
};

/// The elevation tint's stops: metres above the datum and 0xRRGGBB.
struct TintStop {
  float metres;
  std::uint32_t rgb;
};
inline constexpr std::array<TintStop, 7> kTintRamp = {{
    {0, 0x5A8C3A},     // lowland green (the default table's grass)
    {500, 0x66933F},   // green
    {1000, 0x8C9A50},  // yellow-green
    {1600, 0xA08A5E},  // tan
    {2200, 0x8A7864},  // brown
    {2700, 0x8A8782},  // grey rock
    {3300, 0xF0F0F2},  // snow, from here up
}};
inline constexpr std::uint32_t kWaterRgb = 0x3A6EA5;  ///< the default table's water class

/// The GLSL both stages share, after the ramp's constants.
inline constexpr const char* kShadingCommonGlsl = R"(
uniform vec3 uSun;
uniform vec3 uFogColor;
uniform float uFogDensity;
uniform float uFogStart;
uniform bool uFog;
uniform bool uHeightMode;

// Ambient 0.40 plus 0.60 diffuse from the fixed sun.
float sunLight(vec3 normal) {
  return 0.40 + 0.60 * max(dot(normalize(normal), uSun), 0.0);
}
)";

/// The vertex stage's part: the tint, the light and the fog, which vary
/// slowly across a triangle, are computed once per vertex and
/// interpolated (Gouraud), so the fragment stage does one select, one
/// multiply and one mix (docs/VIEWER.md, "Colours": on llvmpipe the
/// per-fragment ramp, normalize and exp were a third of a frame).
inline constexpr const char* kShadingVertexGlsl = R"(
vec3 elevationTint(float h) {
  vec3 c = kTint[0];
  for (int k = 1; k < kStops; ++k) {
    c = mix(c, kTint[k], clamp((h - kAt[k - 1]) / (kAt[k] - kAt[k - 1]), 0.0, 1.0));
  }
  return c;
}

// Fog weight of the surface colour at `dist` metres from the eye: 1 clear.
float fogWeight(float dist) {
  if (!uFog) return 1.0;
  float k = uFogDensity * max(dist - uFogStart, 0.0);
  return exp(-k * k);
}
)";

/// The fragment stage's part.
inline constexpr const char* kShadingFragmentGlsl = R"(
uniform sampler2D uRoad;

const vec3 kMarking = vec3(0.92, 0.92, 0.90);

// 24-bit fixed point: code = round((h + 1000) * 256), RGB = code's bytes,
// high first; code 0 (the clear colour) is no terrain.
vec4 heightCode(float h) {
  float code = clamp(floor((h + 1000.0) * 256.0 + 0.5), 1.0, 16777215.0);
  float hi = floor(code / 65536.0);
  float mid = floor((code - hi * 65536.0) / 256.0);
  float lo = code - hi * 65536.0 - mid * 256.0;
  return vec4(hi, mid, lo, 255.0) / 255.0;
}

// kind: 0 tint (rgb.r = water weight), 1 road, 2 marked road, 3 colour.
// tint, light and fog: the vertex stage's, interpolated.
vec4 shadeSurface(int kind, vec3 rgb, vec2 st, float h, vec3 tint, float light, float fog) {
  if (uHeightMode) return heightCode(h);
  vec3 base;
  if (kind == 0) {
    base = rgb.r >= 0.5 ? kWater : tint;
  } else if (kind == 3) {
    base = rgb;
  } else {
#ifdef SANDTABLE_ROAD_TEXTURE
    vec4 t = texture(uRoad, vec2(st.y, st.x));
    base = rgb * t.rgb;
    if (kind == 2) base = mix(base, kMarking, t.a);
#else
    base = rgb;  // not drawn: a list with road triangles takes the program with the texture
#endif
  }
  return vec4(mix(uFogColor, base * light, fog), 1.0);
}
)";

/// "#version 450 core", the ramp as GLSL constants (from kTintRamp, so the
/// table above is the one definition) and kShadingCommonGlsl.
inline std::string shadingHeaderGlsl() {
  std::string at, tint;
  char buf[96];
  for (const TintStop& s : kTintRamp) {
    std::snprintf(buf, sizeof buf, "%s%.1f", at.empty() ? "" : ", ", double(s.metres));
    at += buf;
    std::snprintf(buf, sizeof buf, "%svec3(%u, %u, %u) / 255.0", tint.empty() ? "" : ", ",
                  (s.rgb >> 16) & 0xFFu, (s.rgb >> 8) & 0xFFu, s.rgb & 0xFFu);
    tint += buf;
  }
  std::snprintf(buf, sizeof buf, "const vec3 kWater = vec3(%u, %u, %u) / 255.0;\n", (kWaterRgb >> 16) & 0xFFu,
                (kWaterRgb >> 8) & 0xFFu, kWaterRgb & 0xFFu);
  const std::string water = buf;
  const std::string n = std::to_string(kTintRamp.size());
  return "#version 450 core\nconst int kStops = " + n + ";\nconst float kAt[kStops] = float[](" + at +
         ");\nconst vec3 kTint[kStops] = vec3[](" + tint + ");\n" + water + kShadingCommonGlsl;
}

/// The vertex stage's shared GLSL: the programs add their inputs and a
/// main() that passes elevationTint(), sunLight() and fogWeight() on.
inline std::string shadingVertexGlsl() { return shadingHeaderGlsl() + kShadingVertexGlsl; }

/// The fragment stage's shared GLSL: the programs add a main() that calls
/// shadeSurface(). Uniforms of both: uSun, uFogColor, uFogDensity,
/// uFogStart, uFog, uHeightMode, uRoad (unit 0). Without `roadTexture`
/// road kinds get their class colour untextured: llvmpipe runs both sides
/// of a branch, so a program that samples the road texture pays for it
/// at every fragment, roads or not.
inline std::string shadingFragmentGlsl(bool roadTexture) {
  return shadingHeaderGlsl() + (roadTexture ? "#define SANDTABLE_ROAD_TEXTURE\n" : "") + kShadingFragmentGlsl;
}

/// Direction towards the fixed sun: azimuth 200 degrees (south-south-west,
/// so a northbound eye sees the slopes facing it lit), 40 degrees up.
inline std::array<float, 3> sunDirection() {
  const double az = 200.0 * kDegToRad, el = 40.0 * kDegToRad;
  return {float(std::cos(el) * std::sin(az)), float(std::sin(el)), float(-std::cos(el) * std::cos(az))};
}

/// The block's uniforms that never change over a flight: sun, fog colour
/// and switch, height mode, road texture unit.
inline void setShadingUniforms(const GlProgram& p, const RenderSettings& s) {
  const auto sun = sunDirection();
  p.set("uSun", sun[0], sun[1], sun[2]);
  p.set("uFogColor", s.background.r / 255.0f, s.background.g / 255.0f, s.background.b / 255.0f);
  p.set("uFog", int(s.fog));
  p.set("uHeightMode", int(s.colour == ColourMode::height));
  p.set("uRoad", 0);
}

/// The uniforms of one frame: the eye (relative to the buffer's origin)
/// and the fog that the view distance sets.
inline void setFrameShading(const GlProgram& p, const scene::DisplayBuffer& buf) {
  const scene::Camera& cam = buf.camera;
  p.set("uEye", float(cam.x - buf.originX), float(cam.y), float(cam.z - buf.originZ));
  p.set("uFogDensity", float(scene::fogDensityFor(cam.viewDistance)));
  p.set("uFogStart", float(scene::kFogClearFraction * cam.viewDistance));
}

}  // namespace sandtable::render::detail
