// Version 6's objects section (docs/FORMAT.md §9.11): the scatter rules
// that regenerate the module's trees (scatter.h), each with the candidates
// it must drop or, where the record cannot regenerate them, a bitmap of
// the ones it keeps; and the explicit objects, quantised. No elevations:
// decode computes every base on the record's own levels.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <optional>
#include <tuple>

#include "module_internal.h"
#include "sandtable/formats/bytes.h"
#include "sandtable/formats/scatter.h"

namespace sandtable::module::detail {

namespace {

std::string str(std::uint64_t v) { return std::to_string(v); }
std::uint32_t bits(float f) { return std::bit_cast<std::uint32_t>(f); }

bool sameBits(const Object& a, const Object& b) {
  return a.icon == b.icon && a.cls == b.cls && bits(a.x) == bits(b.x) && bits(a.z) == bits(b.z) &&
         a.heading == b.heading && bits(a.scale) == bits(b.scale) && bits(a.radius) == bits(b.radius) &&
         bits(a.height) == bits(b.height) && a.id == b.id;
}

/// The extent explicit positions are quantised over: the scattering's, or
/// the record's first level when the module has no scattering frame.
Scattering frameOf(const Module& m) {
  Scattering s;
  s.x0 = m.scattering.x0;
  s.z0 = m.scattering.z0;
  s.width = m.scattering.width;
  s.depth = m.scattering.depth;
  const bool usable = std::isfinite(s.x0) && std::isfinite(s.z0) && std::isfinite(s.width) && s.width > 0 &&
                      std::isfinite(s.depth) && s.depth > 0;
  if (!usable) {
    const Level* l = m.levels.empty() ? nullptr : &m.levels.front();
    s = {};
    s.width = l && l->spacing > 0 ? l->spacing * std::max(l->squaresX, 1u) : 1.0;
    s.depth = l && l->spacing > 0 ? l->spacing * std::max(l->squaresZ, 1u) : 1.0;
  }
  return s;
}

/// What the encoder stores for one rule.
struct RulePlan {
  ScatterRule rule;
  std::uint8_t mode = kRuleRegenerate;
  std::vector<std::uint32_t> removed;  ///< regenerate: candidate numbers to drop
  std::vector<std::uint8_t> kept;      ///< bitmap: one bit per candidate
};

/// The section's explicit scale code range and codes (§9.11).
struct ScaleCode {
  float lo = 1, hi = 1;
  std::uint8_t code(float s) const {
    if (!(hi > lo)) return 0;
    const double c = 255.0 * std::log(double(s) / lo) / std::log(double(hi) / lo);
    return std::uint8_t(std::clamp(std::llround(c), 0ll, 255ll));
  }
  float value(std::uint8_t c) const {
    if (!(hi > lo)) return lo;
    return float(double(lo) * std::exp(std::log(double(hi) / lo) * (double(c) / 255.0)));
  }
};

std::uint16_t positionCode(float v, double extent) {
  const double c = std::round(double(v) / extent * 65536.0);
  return std::uint16_t(std::clamp(std::isfinite(c) ? c : 0.0, 0.0, 65535.0));
}
float positionValue(std::uint16_t c, double extent) { return float(double(c) * (extent / 65536.0)); }

}  // namespace

std::uint64_t objectsBytesV6Bound(const Module& m) {
  std::uint64_t n = kObjectsHeaderBytes6 + m.objects.size() * (kPaletteBytes6 + kExplicitBytes6 + 1);
  for (const ScatterRule& r : m.scattering.rules) n += kRuleBytes6 + (cellRange(r, m.scattering).count() + 7) / 8;
  return n;
}

void encodeObjectsV6(const Module& m, bool regenerateRules, std::vector<std::byte>& out) {
  const Scattering frame = frameOf(m);
  // Scattered objects: those a rule of the module reproduces bit for bit.
  std::map<std::uint16_t, std::size_t> ruleOf;  // rule index -> position in m.scattering.rules
  for (std::size_t r = 0; r < m.scattering.rules.size(); ++r) {
    const ScatterRule& rule = m.scattering.rules[r];
    if (rule.index <= 0x7fff) ruleOf.emplace(rule.index, r);  // the first of a duplicated index
  }
  std::vector<std::vector<std::uint64_t>> members(m.scattering.rules.size());  // candidate numbers
  std::vector<const Object*> explicitObjects;
  std::uint64_t budget = kMaxObjects;
  std::vector<CellRange> ranges;
  std::vector<bool> usable;
  const Scattering& sc = m.scattering;
  const bool frameOk = std::isfinite(sc.x0) && std::isfinite(sc.z0) && sc.width > 0 && sc.width <= kMaxExtent6 &&
                       sc.depth > 0 && sc.depth <= kMaxExtent6;
  for (std::size_t r = 0; r < sc.rules.size(); ++r) {
    const ScatterRule& rule = sc.rules[r];
    ranges.push_back(cellRange(rule, sc));
    const std::uint64_t c = ranges.back().count();
    // A rule the decoder would refuse stores its trees explicitly.
    const auto it = ruleOf.find(rule.index);
    const bool ok = frameOk && it != ruleOf.end() && it->second == r && c > 0 && c <= budget &&
                    std::isfinite(rule.scaleMin) && std::isfinite(rule.scaleMax) && rule.scaleMin > 0 &&
                    rule.scaleMin <= rule.scaleMax && std::isfinite(rule.radius) && rule.radius >= 0 &&
                    std::isfinite(rule.height) && rule.height >= 0;
    usable.push_back(ok);
    if (ok) budget -= c;
  }
  for (const Object& o : m.objects) {
    bool scattered = false;
    if (isScattered(o.id)) {
      const auto it = ruleOf.find(idRule(o.id));
      if (it != ruleOf.end() && usable[it->second]) {
        const ScatterRule& rule = m.scattering.rules[it->second];
        const CellRange& range = ranges[it->second];
        const std::int64_t i = idCellI(o.id), j = idCellJ(o.id);
        if (i >= range.i0 && i <= range.i1 && j >= range.j0 && j <= range.j1) {
          const Candidate c = candidate(rule, m.scattering, i, j);
          if (c.inside && sameBits(c.object, o)) {
            members[it->second].push_back(std::uint64_t(j - range.j0) * range.columns() + std::uint64_t(i - range.i0));
            scattered = true;
          }
        }
      }
    }
    if (!scattered) explicitObjects.push_back(&o);
  }
  // Each rule with trees: regenerate on the record's first level, dropping
  // the few it must, or a bitmap of the candidates kept.
  std::optional<Surface> surface;
  std::vector<RulePlan> plans;
  for (std::size_t r = 0; r < members.size(); ++r) {
    auto& s = members[r];
    if (s.empty()) continue;
    std::sort(s.begin(), s.end());
    if (std::adjacent_find(s.begin(), s.end()) != s.end()) {
      s.erase(std::unique(s.begin(), s.end()), s.end());  // a duplicated id: unreachable from build
    }
    RulePlan p{m.scattering.rules[r], kRuleRegenerate, {}, {}};
    const CellRange& range = ranges[r];
    bool regenerate = regenerateRules && !m.levels.empty();
    if (regenerate) {
      if (!surface) surface.emplace(m.levels.front(), true);
      Scattering one = m.scattering;
      one.rules = {p.rule};
      std::size_t at = 0;
      for (const Object& o : scatter(one, 0, *surface)) {
        const std::uint64_t k =
            std::uint64_t(idCellJ(o.id) - range.j0) * range.columns() + std::uint64_t(idCellI(o.id) - range.i0);
        while (at < s.size() && s[at] < k) {
          regenerate = false;  // a tree the rule does not make here
          ++at;
        }
        if (!regenerate) break;
        if (at < s.size() && s[at] == k) ++at;
        else p.removed.push_back(std::uint32_t(k));
      }
      if (at < s.size()) regenerate = false;
      if (regenerate && 4 * p.removed.size() > (range.count() + 7) / 8) regenerate = false;  // the bitmap is smaller
    }
    if (!regenerate) {
      p.mode = kRuleBitmap;
      p.removed.clear();
      p.kept.assign(std::size_t((range.count() + 7) / 8), 0);
      for (const std::uint64_t k : s) p.kept[k / 8] |= std::uint8_t(1u << (k % 8));
    }
    plans.push_back(std::move(p));
  }
  // The explicit objects, in id order, against a palette of (icon, class,
  // cylinder at scale 1).
  std::stable_sort(explicitObjects.begin(), explicitObjects.end(),
                   [](const Object* a, const Object* b) { return a->id < b->id; });
  std::map<std::pair<std::uint16_t, std::uint16_t>, std::pair<float, float>> palette;
  ScaleCode scale;
  for (std::size_t k = 0; k < explicitObjects.size(); ++k) {
    const Object& o = *explicitObjects[k];
    const bool ok = std::isfinite(o.scale) && o.scale > 0;
    palette.try_emplace({o.icon, o.cls}, ok ? o.radius / o.scale : 0.0f, ok ? o.height / o.scale : 0.0f);
    const float s = ok ? o.scale : 1.0f;
    scale.lo = k == 0 ? s : std::min(scale.lo, s);
    scale.hi = k == 0 ? s : std::max(scale.hi, s);
  }
  std::map<std::pair<std::uint16_t, std::uint16_t>, std::uint32_t> paletteIndex;
  for (const auto& [key, cyl] : palette) paletteIndex.emplace(key, std::uint32_t(paletteIndex.size()));

  const std::size_t n = explicitObjects.size(), p = palette.size();
  std::size_t bytes = kObjectsHeaderBytes6 + kPaletteBytes6 * p + kExplicitBytes6 * n + (p > 256 ? n : 0);
  for (const RulePlan& r : plans) bytes += kRuleBytes6 + 4 * r.removed.size() + r.kept.size();
  const std::size_t at = out.size();
  out.resize(at + bytes);
  std::byte* q = out.data() + at;
  storeLE<std::uint32_t>(q + 0, std::uint32_t(n));
  storeLE<std::uint16_t>(q + 4, std::uint16_t(plans.size()));
  storeLE<std::uint16_t>(q + 6, std::uint16_t(p));
  storeLE<double>(q + 8, frame.x0);
  storeLE<double>(q + 16, frame.z0);
  storeLE<double>(q + 24, frame.width);
  storeLE<double>(q + 32, frame.depth);
  storeLE<float>(q + 40, scale.lo);
  storeLE<float>(q + 44, scale.hi);
  q += kObjectsHeaderBytes6;
  for (const auto& [key, cyl] : palette) {
    storeLE<std::uint16_t>(q + 0, key.first);
    storeLE<std::uint16_t>(q + 2, key.second);
    storeLE<float>(q + 4, cyl.first);
    storeLE<float>(q + 8, cyl.second);
    q += kPaletteBytes6;
  }
  for (const RulePlan& r : plans) {
    storeLE<std::uint16_t>(q + 0, r.rule.icon);
    storeLE<std::uint16_t>(q + 2, r.rule.classId);
    storeLE<std::uint16_t>(q + 4, r.rule.index);
    q[6] = std::byte{r.mode};
    q[7] = std::byte{0};
    storeLE<double>(q + 8, r.rule.cell);
    storeLE<std::uint64_t>(q + 16, r.rule.seed);
    storeLE<double>(q + 24, r.rule.scaleMin);
    storeLE<double>(q + 32, r.rule.scaleMax);
    storeLE<float>(q + 40, r.rule.radius);
    storeLE<float>(q + 44, r.rule.height);
    storeLE<std::uint32_t>(q + 48, std::uint32_t(r.mode == kRuleRegenerate ? r.removed.size() : r.kept.size()));
    storeLE<std::uint32_t>(q + 52, 0);
    q += kRuleBytes6;
    q = putPlane<4>(q, r.removed.size(), [&](std::size_t k) { return r.removed[k]; });
    if (!r.kept.empty()) std::memcpy(q, r.kept.data(), r.kept.size());
    q += r.kept.size();
  }
  const auto& e = explicitObjects;
  q = putPlane<2>(q, n, [&](std::size_t k) { return positionCode(e[k]->x, frame.width); });
  q = putPlane<2>(q, n, [&](std::size_t k) { return positionCode(e[k]->z, frame.depth); });
  q = putPlane<1>(q, n, [&](std::size_t k) { return std::uint32_t((e[k]->heading + 128u) >> 8 & 0xff); });
  q = putPlane<1>(q, n, [&](std::size_t k) { return std::uint32_t(scale.code(e[k]->scale)); });
  const auto index = [&](std::size_t k) { return paletteIndex.at({e[k]->icon, e[k]->cls}); };
  if (p > 256) q = putPlane<2>(q, n, index);
  else q = putPlane<1>(q, n, index);
}

Status decodeObjectsV6(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base,
                       std::size_t& pos, Module& m) {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Status(Problem{file, base + off, "module: objects: " + msg});
  };
  const std::byte* const data = bytes.data();
  // `what` names the part only on failure: a sound decode builds no string
  // (the pager's loaders decode without allocating once warm).
  auto need = [&](std::size_t at, std::uint64_t n, auto what) -> Status {
    if (bytes.size() - at < n) {
      return fail(bytes.size(), "truncated: " + what() + " needs " + str(n) + " bytes, " + str(bytes.size() - at) +
                                    " remain");
    }
    return {};
  };
  if (Status st = need(pos, kObjectsHeaderBytes6, [] { return std::string("the objects header"); }); !st) return st;
  const std::byte* h = data + pos;
  const auto n = loadLE<std::uint32_t>(h + 0);
  const auto ruleCount = loadLE<std::uint16_t>(h + 4);
  const auto paletteCount = loadLE<std::uint16_t>(h + 6);
  Scattering s;
  s.x0 = loadLE<double>(h + 8);
  s.z0 = loadLE<double>(h + 16);
  s.width = loadLE<double>(h + 24);
  s.depth = loadLE<double>(h + 32);
  ScaleCode scale{loadLE<float>(h + 40), loadLE<float>(h + 44)};
  if (n > kMaxObjects) {
    return fail(pos, "explicit count " + str(n) + " is over the limit of " + str(kMaxObjects) + " objects per module");
  }
  if (!std::isfinite(s.x0) || !std::isfinite(s.z0) || !(std::isfinite(s.width) && s.width > 0 && s.width <= kMaxExtent6) ||
      !(std::isfinite(s.depth) && s.depth > 0 && s.depth <= kMaxExtent6)) {
    return fail(pos + 8, "the module's corner and extent must be finite, the extent in (0, " +
                             str(std::uint64_t(kMaxExtent6)) + "] metres");
  }
  if (!(std::isfinite(scale.lo) && scale.lo > 0 && std::isfinite(scale.hi) && scale.hi >= scale.lo)) {
    return fail(pos + 40, "the explicit scale range must be finite, positive and in order");
  }
  if (n > 0 && paletteCount == 0) return fail(pos + 6, "explicit objects need a palette");
  std::size_t at = pos + kObjectsHeaderBytes6;
  if (Status st = need(at, std::uint64_t(kPaletteBytes6) * paletteCount, [&] { return str(paletteCount) + " palette entries"; }); !st) {
    return st;
  }
  struct Entry {
    std::uint16_t icon, cls;
    float radius, height;
  };
  std::vector<Entry> palette(paletteCount);  // at most 65535 entries, held by the bytes (checked above)
  for (Entry& e : palette) {
    e = {loadLE<std::uint16_t>(data + at), loadLE<std::uint16_t>(data + at + 2), loadLE<float>(data + at + 4),
         loadLE<float>(data + at + 8)};
    if (!(std::isfinite(e.radius) && e.radius >= 0 && std::isfinite(e.height) && e.height >= 0)) {
      return fail(at + 4, "palette cylinder is not finite and >= 0");
    }
    at += kPaletteBytes6;
  }
  // Rules: every count is checked against the bytes and the object limit
  // before anything is generated.
  struct Stored {
    ScatterRule rule;
    std::uint8_t mode;
    CellRange range;
    std::size_t list;  ///< offset of its list
    std::uint32_t listCount;
  };
  if (Status st = need(at, std::uint64_t(kRuleBytes6) * ruleCount, [&] { return str(ruleCount) + " rules"; }); !st) return st;
  std::vector<Stored> rules;
  rules.reserve(ruleCount);
  std::uint64_t total = n;
  for (std::uint32_t r = 0; r < ruleCount; ++r) {
    if (Status st = need(at, kRuleBytes6, [&] { return "rule " + str(r); }); !st) return st;
    const std::byte* q = data + at;
    Stored x{};
    x.rule.icon = loadLE<std::uint16_t>(q);
    x.rule.classId = loadLE<std::uint16_t>(q + 2);
    x.rule.index = loadLE<std::uint16_t>(q + 4);
    x.mode = std::uint8_t(q[6]);
    x.rule.cell = loadLE<double>(q + 8);
    x.rule.seed = loadLE<std::uint64_t>(q + 16);
    x.rule.scaleMin = loadLE<double>(q + 24);
    x.rule.scaleMax = loadLE<double>(q + 32);
    x.rule.radius = loadLE<float>(q + 40);
    x.rule.height = loadLE<float>(q + 44);
    x.listCount = loadLE<std::uint32_t>(q + 48);
    const auto name = [&] { return "rule " + str(r) + " "; };
    if (x.mode > kRuleBitmap || q[7] != std::byte{0} || loadLE<std::uint32_t>(q + 52) != 0) {
      return fail(at + 6, name() + "mode must be 0 or 1 and its reserved bytes 0");
    }
    if (x.rule.index > 0x7fff) return fail(at + 4, name() + "index " + str(x.rule.index) + " is over 32767");
    for (const Stored& y : rules) {
      if (y.rule.index == x.rule.index) return fail(at + 4, name() + "index " + str(x.rule.index) + " is repeated");
    }
    if (!(std::isfinite(x.rule.cell) && x.rule.cell > 0)) return fail(at + 8, name() + "cell is not finite and positive");
    if (!(std::isfinite(x.rule.scaleMin) && x.rule.scaleMin > 0 && std::isfinite(x.rule.scaleMax) &&
          x.rule.scaleMax >= x.rule.scaleMin)) {
      return fail(at + 24, name() + "scale range is not finite, positive and in order");
    }
    if (!(std::isfinite(x.rule.radius) && x.rule.radius >= 0 && std::isfinite(x.rule.height) && x.rule.height >= 0)) {
      return fail(at + 40, name() + "cylinder is not finite and >= 0");
    }
    // The candidate count, in doubles before any integer is formed.
    const double columns = std::floor((s.x0 + s.width) / x.rule.cell) - std::floor(s.x0 / x.rule.cell) + 1;
    const double rows = std::floor((s.z0 + s.depth) / x.rule.cell) - std::floor(s.z0 / x.rule.cell) + 1;
    if (!(columns * rows <= double(kMaxObjects - total))) {
      return fail(at + 8, name() + "cell " + std::to_string(x.rule.cell) + " m makes " +
                              (std::isfinite(columns * rows) ? str(std::uint64_t(columns * rows)) : std::string("too many")) +
                              " candidates; with the module's other objects over the limit of " + str(kMaxObjects));
    }
    x.range = cellRange(x.rule, s);
    if (x.range.count() == 0) return fail(at + 8, name() + "cells fall outside the ids' range (|i|, |j| < 2^23)");
    total += x.range.count();
    const std::uint64_t listBytes = x.mode == kRuleRegenerate ? 4ull * x.listCount : x.listCount;
    if (x.mode == kRuleBitmap && x.listCount != (x.range.count() + 7) / 8) {
      return fail(at + 48, name() + "bitmap is " + str(x.listCount) + " bytes; its " + str(x.range.count()) +
                               " candidates need " + str((x.range.count() + 7) / 8));
    }
    if (x.mode == kRuleRegenerate && x.listCount > x.range.count()) {
      return fail(at + 48, name() + "drops " + str(x.listCount) + " of its " + str(x.range.count()) + " candidates");
    }
    at += kRuleBytes6;
    if (Status st = need(at, listBytes, [&] { return name() + "list"; }); !st) return st;
    x.list = at;
    at += std::size_t(listBytes);
    rules.push_back(x);
  }
  const std::uint64_t explicitBytes = std::uint64_t(n) * (kExplicitBytes6 + (paletteCount > 256 ? 1 : 0));
  if (Status st = need(at, explicitBytes, [&] { return str(n) + " explicit objects"; }); !st) return st;

  // Everything is within the bytes and the limit: build the objects.
  m.objects.clear();
  m.objects.reserve(std::size_t(n));
  const std::byte* e = data + at;
  std::vector<std::uint16_t> xs(n), zs(n);
  getPlane<2>(e, n, [&](std::size_t k, std::uint32_t u) { xs[k] = std::uint16_t(u); });
  getPlane<2>(e + 2 * std::size_t(n), n, [&](std::size_t k, std::uint32_t u) { zs[k] = std::uint16_t(u); });
  const auto* headings = reinterpret_cast<const std::uint8_t*>(e + 4 * std::size_t(n));
  const auto* scales = headings + n;
  const std::byte* indexPlane = e + 6 * std::size_t(n);
  for (std::size_t k = 0; k < n; ++k) {
    std::uint32_t pi = std::uint8_t(indexPlane[k]);
    if (paletteCount > 256) pi |= std::uint32_t(std::uint8_t(indexPlane[n + k])) << 8;
    if (pi >= paletteCount) {
      return fail(at + 6 * n + k, "explicit object " + str(k) + " names palette entry " + str(pi) + " of " +
                                      str(paletteCount));
    }
    Object o;
    o.icon = palette[pi].icon;
    o.cls = palette[pi].cls;
    o.x = positionValue(xs[k], s.width);
    o.z = positionValue(zs[k], s.depth);
    o.heading = std::uint16_t(headings[k] << 8);
    o.scale = scale.value(scales[k]);
    o.radius = palette[pi].radius * o.scale;
    o.height = palette[pi].height * o.scale;
    o.id = k;
    m.objects.push_back(o);
  }
  const std::size_t end = at + std::size_t(explicitBytes);
  // The rules' trees.
  s.rules.clear();
  for (const Stored& x : rules) s.rules.push_back(x.rule);
  std::optional<Surface> surface;
  for (std::size_t r = 0; r < rules.size(); ++r) {
    const Stored& x = rules[r];
    const std::uint64_t columns = x.range.columns();
    if (x.mode == kRuleRegenerate) {
      if (!surface) surface.emplace(m.levels.front(), true);
      std::uint32_t prev = 0;
      std::vector<std::uint32_t> removed(x.listCount);
      getPlane<4>(data + x.list, x.listCount, [&](std::size_t k, std::uint32_t u) { removed[k] = u; });
      for (std::size_t k = 0; k < removed.size(); ++k) {
        if (removed[k] >= x.range.count() || (k > 0 && removed[k] <= prev)) {
          return fail(x.list + k, "rule " + str(r) + " drops candidate " + str(removed[k]) +
                                      ": not ascending or past its candidates");
        }
        prev = removed[k];
      }
      std::size_t next = 0;
      for (const Object& o : scatter(s, r, *surface)) {
        const std::uint64_t k = std::uint64_t(idCellJ(o.id) - x.range.j0) * columns + std::uint64_t(idCellI(o.id) - x.range.i0);
        while (next < removed.size() && removed[next] < k) ++next;
        if (next < removed.size() && removed[next] == k) continue;
        m.objects.push_back(o);
      }
    } else {
      const auto* bitmap = reinterpret_cast<const std::uint8_t*>(data + x.list);
      const std::uint64_t count = x.range.count();
      if (count % 8 != 0 && (bitmap[count / 8] >> (count % 8)) != 0) {
        return fail(x.list + count / 8, "rule " + str(r) + " bitmap has bits past its candidates");
      }
      for (std::uint64_t k = 0; k < count; ++k) {
        if (!(bitmap[k / 8] >> (k % 8) & 1)) continue;
        const Candidate c = candidate(x.rule, s, x.range.i0 + std::int64_t(k % columns), x.range.j0 + std::int64_t(k / columns));
        if (!c.inside) {
          return fail(x.list + k / 8, "rule " + str(r) + " keeps candidate " + str(k) + ", which is another module's");
        }
        m.objects.push_back(c.object);
      }
    }
  }
  sortObjects(m.objects);
  m.scattering = std::move(s);
  placeBases(m);
  pos = end;
  return {};
}

}  // namespace sandtable::module::detail
