// Version 5's static objects section (docs/FORMAT.md §9.10): fixed-width
// planes, byte-shuffled so zstd sees each field's bytes together.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "module_internal.h"
#include "sandtable/formats/bytes.h"

namespace sandtable::module {

std::vector<std::uint32_t> tallestObjects(const Module& m, std::size_t level) {
  if (level >= m.levels.size() || m.levels.empty()) return {};
  const Level& l0 = m.levels.front();
  const Level& l = m.levels[level];
  std::vector<std::uint32_t> out(std::size_t(l0.squaresX) * l0.squaresZ, kNoObject);
  if (l.objectY.size() != m.objects.size() || l0.spacing <= 0) return out;
  std::vector<float> top(out.size(), 0.0f);
  for (std::size_t k = 0; k < m.objects.size(); ++k) {
    const Object& o = m.objects[k];
    const auto column = [&](float c, std::uint32_t n) {
      const double cell = std::floor(double(c) / l0.spacing);
      return std::size_t(std::clamp(cell, 0.0, double(n - 1)));
    };
    const std::size_t sq = column(o.z, l0.squaresZ) * l0.squaresX + column(o.x, l0.squaresX);
    const float t = l.objectY[k] + o.height;
    if (out[sq] == kNoObject || t > top[sq]) out[sq] = std::uint32_t(k), top[sq] = t;
  }
  return out;
}

namespace detail {

namespace {
std::string str(std::uint64_t v) { return std::to_string(v); }
std::uint32_t bits(float f) { return std::bit_cast<std::uint32_t>(f); }
float real(std::uint32_t u) { return std::bit_cast<float>(u); }
}  // namespace

std::uint64_t objectsBytes(const Module& m) {
  const std::uint64_t n = m.objects.size();
  return 4 + n * (kObjectBytes + 4 * m.levels.size());
}

void encodeObjects(const Module& m, std::vector<std::byte>& out) {
  const std::size_t n = m.objects.size(), at = out.size();
  out.resize(at + std::size_t(objectsBytes(m)));
  std::byte* p = out.data() + at;
  storeLE<std::uint32_t>(p, std::uint32_t(n));
  p += 4;
  const auto& o = m.objects;
  p = putPlane<2>(p, n, [&](std::size_t i) { return o[i].icon; });
  p = putPlane<2>(p, n, [&](std::size_t i) { return o[i].cls; });
  p = putPlane<4>(p, n, [&](std::size_t i) { return bits(o[i].x); });
  p = putPlane<4>(p, n, [&](std::size_t i) { return bits(o[i].z); });
  p = putPlane<2>(p, n, [&](std::size_t i) { return o[i].heading; });
  p = putPlane<4>(p, n, [&](std::size_t i) { return bits(o[i].scale); });
  p = putPlane<4>(p, n, [&](std::size_t i) { return bits(o[i].radius); });
  p = putPlane<4>(p, n, [&](std::size_t i) { return bits(o[i].height); });
  for (const Level& l : m.levels) {
    // checkEncodable holds objectY to the objects' count; a short one pads with 0.
    p = putPlane<4>(p, n, [&](std::size_t i) { return i < l.objectY.size() ? bits(l.objectY[i]) : 0u; });
  }
}

Status decodeObjects(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base,
                     std::size_t& pos, Module& m) {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Status(Problem{file, base + off, "module: objects: " + msg});
  };
  if (bytes.size() - pos < 4) {
    return fail(bytes.size(), "truncated: the object count needs 4 bytes, the input ends at byte " +
                                  str(bytes.size()));
  }
  const auto n = loadLE<std::uint32_t>(bytes.data() + pos);
  const std::uint64_t each = kObjectBytes + 4 * std::uint64_t(m.levels.size());
  const std::uint64_t left = bytes.size() - pos - 4;
  if (n > kMaxObjects) {
    return fail(pos, "count " + str(n) + " is over the limit of " + str(kMaxObjects) + " objects per module");
  }
  if (std::uint64_t(n) * each > left) {
    return fail(bytes.size(), "truncated: " + str(n) + " objects need " + str(std::uint64_t(n) * each) +
                                  " bytes, " + str(left) + " remain");
  }
  const std::byte* p = bytes.data() + pos + 4;
  m.objects.resize(n);
  auto& o = m.objects;
  getPlane<2>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].icon = std::uint16_t(u), o[i].id = i; });
  p += 2 * std::size_t(n);
  getPlane<2>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].cls = std::uint16_t(u); });
  p += 2 * std::size_t(n);
  getPlane<4>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].x = real(u); });
  p += 4 * std::size_t(n);
  getPlane<4>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].z = real(u); });
  p += 4 * std::size_t(n);
  getPlane<2>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].heading = std::uint16_t(u); });
  p += 2 * std::size_t(n);
  const std::byte* const scalePlane = p;
  getPlane<4>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].scale = real(u); });
  p += 4 * std::size_t(n);
  getPlane<4>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].radius = real(u); });
  p += 4 * std::size_t(n);
  getPlane<4>(p, n, [&](std::size_t i, std::uint32_t u) { o[i].height = real(u); });
  p += 4 * std::size_t(n);
  for (Level& l : m.levels) {
    l.objectY.resize(n);
    getPlane<4>(p, n, [&](std::size_t i, std::uint32_t u) { l.objectY[i] = real(u); });
    p += 4 * std::size_t(n);
  }
  // Values the renderer and the simulator would turn into NaN positions.
  const std::size_t scaleAt = std::size_t(scalePlane - bytes.data());
  for (std::size_t i = 0; i < n; ++i) {
    const Object& b = o[i];
    if (!std::isfinite(b.x) || !std::isfinite(b.z)) {
      return fail(pos + 4 + 4 * n, "object " + str(i) + " position is not finite");
    }
    if (!(std::isfinite(b.scale) && b.scale > 0) || !(std::isfinite(b.radius) && b.radius >= 0) ||
        !(std::isfinite(b.height) && b.height >= 0)) {
      return fail(scaleAt, "object " + str(i) + " scale, radius or height is not finite and positive");
    }
    for (std::size_t li = 0; li < m.levels.size(); ++li) {
      if (!std::isfinite(m.levels[li].objectY[i])) {
        return fail(std::size_t(p - bytes.data()), "object " + str(i) + " elevation on level " + str(li) +
                                                       " is not finite");
      }
    }
  }
  pos = std::size_t(p - bytes.data());
  return {};
}

}  // namespace detail
}  // namespace sandtable::module
