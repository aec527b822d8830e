// Octahedral unit normals (module.h octEncode, octDecode; docs/FORMAT.md
// §9.7): two snorm16 components, the lower hemisphere folded onto the
// corners.
#include <algorithm>
#include <cmath>

#include "sandtable/formats/module.h"

namespace sandtable::module {

namespace {

float signNotZero(float v) { return v < 0.0f ? -1.0f : 1.0f; }

std::uint32_t snorm16(float c) {
  const long q = std::lround(std::clamp(c, -1.0f, 1.0f) * 32767.0f);
  return std::uint32_t(std::uint16_t(std::int16_t(q)));
}

float unsnorm16(std::uint32_t bits) {
  return std::max(float(std::int16_t(std::uint16_t(bits))) / 32767.0f, -1.0f);
}

}  // namespace

std::uint32_t octEncode(float x, float y, float z) {
  const float n = std::fabs(x) + std::fabs(y) + std::fabs(z);
  if (!(n > 0.0f) || !std::isfinite(n)) return 0;  // no direction: up
  float u = x / n, v = z / n;
  if (y < 0.0f) {  // fold the lower hemisphere onto the corners
    const float fu = (1.0f - std::fabs(v)) * signNotZero(u);
    const float fv = (1.0f - std::fabs(u)) * signNotZero(v);
    u = fu, v = fv;
  }
  return snorm16(u) | snorm16(v) << 16;
}

std::array<float, 3> octDecode(std::uint32_t packed) {
  float u = unsnorm16(packed & 0xffffu), v = unsnorm16(packed >> 16);
  const float y = 1.0f - std::fabs(u) - std::fabs(v);
  if (y < 0.0f) {
    const float fu = (1.0f - std::fabs(v)) * signNotZero(u);
    const float fv = (1.0f - std::fabs(u)) * signNotZero(v);
    u = fu, v = fv;
  }
  const float len = std::sqrt(u * u + y * y + v * v);
  return {u / len, y / len, v / len};
}

}  // namespace sandtable::module
