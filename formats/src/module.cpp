#include "sandtable/formats/module.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>

#include "sandtable/formats/bytes.h"
#include "module_internal.h"

namespace sandtable::module {
namespace {

using namespace detail;

std::uint64_t squareCount(const Level& l) { return std::uint64_t(l.squaresX) * l.squaresZ; }

bool needsU32Indices(const Level& l) {
  if (l.vertices.size() > kMaxU16Vertices) return true;
  for (const std::uint32_t i : l.indices) {
    if (i > 0xffffu) return true;  // out of range anyway; keep it visible to decode
  }
  return false;
}

std::uint64_t levelBytes(const Level& l, bool u32Indices) {
  return kLevelHeaderBytes + std::uint64_t(kVertexBytes) * l.vertices.size() + 4 * squareCount(l) +
         (u32Indices ? 4u : 2u) * std::uint64_t(l.indices.size()) +
         std::uint64_t(kGroupBytes) * l.groups.size();
}

std::uint32_t floatBits(float f) { return std::bit_cast<std::uint32_t>(f); }

std::string str(std::uint64_t v) { return std::to_string(v); }

}  // namespace

Status checkEncodable(const Module& m) {
  auto fail = [](const std::string& msg) { return Status(Problem{"", 0, msg}); };
  if (m.levels.empty() || m.levels.size() > kMaxLevels) {
    return fail("module: " + str(m.levels.size()) + " levels; a module holds 1 to " + str(kMaxLevels));
  }
  for (std::size_t li = 0; li < m.levels.size(); ++li) {
    const Level& l = m.levels[li];
    const std::string where = "module: level " + str(li);
    if (l.squaresX < 1 || l.squaresZ < 1 || l.squaresX > kMaxSquaresPerAxis ||
        l.squaresZ > kMaxSquaresPerAxis) {
      return fail(where + " squares " + str(l.squaresX) + " x " + str(l.squaresZ) +
             " are out of range (1 to 65536 each)");
    }
    if (l.maxHeight.size() != squareCount(l)) {
      return fail(where + " has " + str(l.maxHeight.size()) + " maxHeight values for " +
             str(squareCount(l)) + " squares");
    }
    if (l.vertices.size() > 0xffffffffu || l.indices.size() > 0xffffffffu ||
        l.groups.size() > 0xffffffffu) {
      return fail(where + " has more than 2^32 - 1 vertices, indices or groups");
    }
    std::uint64_t next = 0;
    for (std::size_t g = 0; g < l.groups.size(); ++g) {
      if (l.groups[g].firstIndex != next) {
        return fail(where + " group " + str(g) + " firstIndex " + str(l.groups[g].firstIndex) +
               " is not " + str(next) +
               ", the sum of the index counts before it (groups must cover the indices "
               "contiguously, in order)");
      }
      next += l.groups[g].indexCount;
    }
    if (next != l.indices.size()) {
      return fail(where + " groups cover " + str(next) + " of its " + str(l.indices.size()) + " indices");
    }
    if (!l.normals.empty() && l.normals.size() != l.vertices.size()) {
      return fail(where + " has " + str(l.normals.size()) + " normals for " + str(l.vertices.size()) +
                  " vertices (one per vertex, or none)");
    }
    if (l.objectY.size() != m.objects.size()) {
      return fail(where + " has " + str(l.objectY.size()) + " object elevations for " + str(m.objects.size()) +
                  " objects (one per object on every level)");
    }
  }
  if (m.objects.size() > kMaxObjects) {
    return fail("module: " + str(m.objects.size()) + " objects; a module holds at most " + str(kMaxObjects));
  }
  return {};
}

std::uint64_t encodedBytes(const Module& m) {
  std::uint64_t n = kHeaderBytes;
  for (const Level& l : m.levels) n += levelBytes(l, needsU32Indices(l));
  return m.objects.empty() ? n : n + std::max(detail::objectsBytes(m), detail::objectsBytesV6Bound(m));
}

namespace {

std::vector<std::byte> encodeV1(const Module& m) {
  std::vector<bool> wide(m.levels.size());
  std::uint64_t total = kHeaderBytes;
  for (std::size_t li = 0; li < m.levels.size(); ++li) {
    wide[li] = needsU32Indices(m.levels[li]);
    total += levelBytes(m.levels[li], wide[li]);
  }
  std::vector<std::byte> out(static_cast<std::size_t>(total), std::byte{0});
  std::byte* const h = out.data();
  std::memcpy(h + field::magic, kMagic.data(), kMagic.size());
  storeLE<std::uint32_t>(h + field::version, kVersion);
  storeLE<std::uint32_t>(h + field::headerBytes, kHeaderBytes);
  storeLE<std::uint32_t>(h + field::kx, m.kx);
  storeLE<std::uint32_t>(h + field::kz, m.kz);
  storeLE<std::uint32_t>(h + field::levelCount, static_cast<std::uint32_t>(m.levels.size()));
  storeLE<std::uint32_t>(h + field::flags, 0);
  storeLE<std::uint64_t>(h + field::totalBytes, total);

  std::byte* p = h + kHeaderBytes;
  for (std::size_t li = 0; li < m.levels.size(); ++li) {
    const Level& l = m.levels[li];
    const auto& v = l.vertices;
    const auto& g = l.groups;
    storeLE<double>(p + levelField::spacing, l.spacing);
    storeLE<std::uint32_t>(p + levelField::squaresX, l.squaresX);
    storeLE<std::uint32_t>(p + levelField::squaresZ, l.squaresZ);
    storeLE<float>(p + levelField::skirtDepth, l.skirtDepth);
    storeLE<std::uint32_t>(p + levelField::flags, wide[li] ? kLevelFlagU32Indices : 0u);
    storeLE<std::uint32_t>(p + levelField::vertexCount, static_cast<std::uint32_t>(v.size()));
    storeLE<std::uint32_t>(p + levelField::indexCount,
                           static_cast<std::uint32_t>(l.indices.size()));
    storeLE<std::uint32_t>(p + levelField::groupCount, static_cast<std::uint32_t>(g.size()));
    p += kLevelHeaderBytes;
    p = putPlane<4>(p, v.size(), [&](std::size_t i) { return floatBits(v[i].x); });
    p = putPlane<4>(p, v.size(), [&](std::size_t i) { return floatBits(v[i].y); });
    p = putPlane<4>(p, v.size(), [&](std::size_t i) { return floatBits(v[i].z); });
    p = putPlane<4>(p, v.size(), [&](std::size_t i) { return floatBits(v[i].s); });
    p = putPlane<4>(p, v.size(), [&](std::size_t i) { return floatBits(v[i].t); });
    const auto squares = static_cast<std::size_t>(squareCount(l));
    p = putPlane<4>(p, squares, [&](std::size_t i) {
      return floatBits(i < l.maxHeight.size() ? l.maxHeight[i] : 0.0f);
    });
    const auto index = [&](std::size_t i) { return l.indices[i]; };
    p = wide[li] ? putDeltaPlane<4>(p, l.indices.size(), index)
                 : putDeltaPlane<2>(p, l.indices.size(), index);
    p = putDeltaPlane<4>(p, g.size(), [&](std::size_t i) { return g[i].square; });
    p = putPlane<1>(p, g.size(), [&](std::size_t i) { return std::uint32_t(g[i].half); });
    p = putPlane<1>(p, g.size(), [&](std::size_t i) { return std::uint32_t(g[i].priority); });
    p = putPlane<2>(p, g.size(), [&](std::size_t i) { return std::uint32_t(g[i].material); });
    p = putPlane<4>(p, g.size(), [&](std::size_t i) { return g[i].indexCount; });
  }
  assert(p == out.data() + out.size());
  storeLE<std::uint32_t>(h + field::payloadCrc, crc32(std::span(out).subspan(kHeaderBytes)));
  storeLE<std::uint32_t>(h + field::headerCrc, crc32(std::span(out).first(field::headerCrc)));
  return out;
}

}  // namespace

std::vector<std::byte> encode(const Module& m, const EncodeOptions& options) {
  assert(checkEncodable(m).ok());
  return options.version == kVersion ? encodeV1(m) : detail::encodeV2(m, options);
}

std::uint32_t encodedVersion(std::span<const std::byte> bytes) {
  if (bytes.size() < field::version + 4) return 0;
  const auto version = loadLE<std::uint32_t>(bytes.data() + field::version);
  if (version == kVersion && std::memcmp(bytes.data(), kMagic.data(), kMagic.size()) == 0) return version;
  if (version == kVersion2 && std::memcmp(bytes.data(), kMagic2.data(), kMagic2.size()) == 0) return version;
  if (version == kVersion3 && std::memcmp(bytes.data(), kMagic3.data(), kMagic3.size()) == 0) return version;
  if (version == kVersion4 && std::memcmp(bytes.data(), kMagic4.data(), kMagic4.size()) == 0) return version;
  if (version == kVersion5 && std::memcmp(bytes.data(), kMagic5.data(), kMagic5.size()) == 0) return version;
  if (version == kVersion6 && std::memcmp(bytes.data(), kMagic6.data(), kMagic6.size()) == 0) return version;
  return 0;
}

// ---------------------------------------------------------------- decode

namespace {

/// Decodes one level starting at `pos` (checked: at least the level header
/// fits or a problem is returned). Advances `pos` past the level.
class LevelDecoder {
 public:
  LevelDecoder(std::span<const std::byte> bytes, const std::string& file, std::uint64_t base)
      : bytes_(bytes), file_(file), base_(base) {}

  /// The first problem of the level, if any.
  Status decode(std::size_t li, std::size_t& pos, Level& l) const {
    const std::string lv = "level " + str(li);
    auto fail = [&](std::size_t off, const std::string& msg) {
      return Status(Problem{file_, base_ + off, "module: " + lv + msg});
    };
    const std::size_t left = bytes_.size() - pos;
    if (left < kLevelHeaderBytes) {
      return fail(pos, ": truncated: the level header needs " + str(kLevelHeaderBytes) +
                           " bytes, only " + str(left) + " remain");
    }
    const std::byte* h = bytes_.data() + pos;
    l.spacing = loadLE<double>(h + levelField::spacing);
    l.squaresX = loadLE<std::uint32_t>(h + levelField::squaresX);
    l.squaresZ = loadLE<std::uint32_t>(h + levelField::squaresZ);
    l.skirtDepth = loadLE<float>(h + levelField::skirtDepth);
    const auto flags = loadLE<std::uint32_t>(h + levelField::flags);
    const auto nv = loadLE<std::uint32_t>(h + levelField::vertexCount);
    const auto ni = loadLE<std::uint32_t>(h + levelField::indexCount);
    const auto ng = loadLE<std::uint32_t>(h + levelField::groupCount);
    if (!(std::isfinite(l.spacing) && l.spacing > 0)) {
      return fail(pos + levelField::spacing,
                  " spacing " + std::to_string(l.spacing) + " is not a finite positive number");
    }
    for (const std::size_t f : {levelField::squaresX, levelField::squaresZ}) {
      const std::uint32_t n = loadLE<std::uint32_t>(h + f);
      if (n < 1 || n > kMaxSquaresPerAxis) {
        return fail(pos + f, " squares " + str(l.squaresX) + " x " + str(l.squaresZ) +
                                 " are out of range (1 to 65536 each)");
      }
    }
    if (!(std::isfinite(l.skirtDepth) && l.skirtDepth >= 0)) {
      return fail(pos + levelField::skirtDepth,
                  " skirt depth " + std::to_string(l.skirtDepth) + " is not a finite number >= 0");
    }
    if ((flags & ~kLevelFlagU32Indices) != 0) {
      return fail(pos + levelField::flags,
                  " flags " + str(flags) + " has bits other than bit 0 (u32 indices) set");
    }
    const std::uint64_t squares = std::uint64_t(l.squaresX) * l.squaresZ;
    const std::uint64_t indexWidth = (flags & kLevelFlagU32Indices) ? 4 : 2;
    const std::uint64_t need = std::uint64_t(kVertexBytes) * nv + 4 * squares + indexWidth * ni +
                               std::uint64_t(kGroupBytes) * ng;
    if (need > left - kLevelHeaderBytes) {
      return fail(pos + levelField::vertexCount, ": " + str(nv) + " vertices, " + str(ni) +
                                                     " indices, " + str(ng) + " groups and " +
                                                     str(squares) + " squares need " + str(need) +
                                                     " bytes after the level header, only " +
                                                     str(left - kLevelHeaderBytes) + " remain");
    }
    // Every count now fits in the bytes: sizing the vectors is bounded by
    // the input's length.
    std::size_t p = pos + kLevelHeaderBytes;
    const std::byte* b = bytes_.data();
    l.vertices.resize(nv);
    Vertex* v = l.vertices.data();
    getPlane<4>(b + p, nv,
                [v](std::size_t i, std::uint32_t u) { v[i].x = std::bit_cast<float>(u); });
    p += 4 * std::size_t(nv);
    getPlane<4>(b + p, nv,
                [v](std::size_t i, std::uint32_t u) { v[i].y = std::bit_cast<float>(u); });
    p += 4 * std::size_t(nv);
    getPlane<4>(b + p, nv,
                [v](std::size_t i, std::uint32_t u) { v[i].z = std::bit_cast<float>(u); });
    p += 4 * std::size_t(nv);
    getPlane<4>(b + p, nv,
                [v](std::size_t i, std::uint32_t u) { v[i].s = std::bit_cast<float>(u); });
    p += 4 * std::size_t(nv);
    getPlane<4>(b + p, nv,
                [v](std::size_t i, std::uint32_t u) { v[i].t = std::bit_cast<float>(u); });
    p += 4 * std::size_t(nv);
    const auto ns = static_cast<std::size_t>(squares);
    l.maxHeight.resize(ns);
    float* mh = l.maxHeight.data();
    getPlane<4>(b + p, ns,
                [mh](std::size_t i, std::uint32_t u) { mh[i] = std::bit_cast<float>(u); });
    p += 4 * ns;

    // Indices, each below the vertex count.
    l.indices.resize(ni);
    std::uint32_t* idx = l.indices.data();
    if (indexWidth == 4) {
      getDeltaPlane<4>(b + p, ni, idx);
    } else {
      getDeltaPlane<2>(b + p, ni, idx);
    }
    std::uint32_t maxIndex = 0;
    for (std::uint32_t k = 0; k < ni; ++k) maxIndex = std::max(maxIndex, idx[k]);
    if (ni > 0 && maxIndex >= nv) {
      std::uint32_t k = 0;
      while (idx[k] < nv) ++k;
      return fail(p + k, " index " + str(k) + " is " + str(idx[k]) +
                             ", not below the vertex count " + str(nv));
    }
    p += static_cast<std::size_t>(indexWidth * ni);

    // Groups: five planes; firstIndex is the running sum of indexCount.
    const std::size_t squarePlane = p, halfPlane = p + 4 * std::size_t(ng),
                      priorityPlane = halfPlane + ng, materialPlane = priorityPlane + ng,
                      countPlane = materialPlane + 2 * std::size_t(ng);
    l.groups.resize(ng);
    Group* gr = l.groups.data();
    {
      std::uint32_t prev = 0;
      getPlane<4>(b + squarePlane, ng, [&](std::size_t i, std::uint32_t z) {
        gr[i].square = prev = unzigzagDelta<4>(z, prev);
      });
    }
    getPlane<1>(b + halfPlane, ng,
                [&](std::size_t i, std::uint32_t u) { gr[i].half = static_cast<Half>(u); });
    getPlane<1>(b + priorityPlane, ng, [&](std::size_t i, std::uint32_t u) {
      gr[i].priority = static_cast<std::uint8_t>(u);
    });
    getPlane<2>(b + materialPlane, ng, [&](std::size_t i, std::uint32_t u) {
      gr[i].material = static_cast<std::uint16_t>(u);
    });
    getPlane<4>(b + countPlane, ng, [&](std::size_t i, std::uint32_t u) { gr[i].indexCount = u; });
    std::uint64_t first = 0, prevKey = 0;
    for (std::uint32_t g = 0; g < ng; ++g) {
      const auto gs = [g] { return " group " + str(g); };
      const auto half = static_cast<std::uint8_t>(gr[g].half);
      if (half > 2) {
        return fail(halfPlane + g,
                    gs() + " half " + str(half) + " is not 0 (upper), 1 (lower) or 2 (skirt)");
      }
      if (gr[g].square >= squares) {
        return fail(squarePlane + g, gs() + " square " + str(gr[g].square) +
                                         " is not below the level's " + str(squares) + " squares");
      }
      const std::uint32_t count = gr[g].indexCount;
      if (count == 0 || count % 3 != 0) {
        return fail(countPlane + g,
                    gs() + " index count " + str(count) + " is not a positive multiple of 3");
      }
      if (first + count > ni) {
        return fail(countPlane + g, gs() + " indices " + str(first) + ".." +
                                        str(first + count - 1) + " run past the level's " +
                                        str(ni) + " indices");
      }
      const std::uint64_t key = groupKey(gr[g].priority, gr[g].square, half, gr[g].material);
      if (g > 0 && key < prevKey) {  // equal keys may follow each other
        return fail(squarePlane + g, gs() + " (priority " + str(gr[g].priority) + ", square " +
                                         str(gr[g].square) + ", half " + str(half) + ", material " +
                                         str(gr[g].material) + ") does not follow group " +
                                         str(g - 1) +
                                         " in (priority, square, half, material) order");
      }
      prevKey = key;
      gr[g].firstIndex = static_cast<std::uint32_t>(first);
      first += count;
    }
    if (first != ni) {
      return fail(countPlane,
                  " groups cover " + str(first) + " of the level's " + str(ni) + " indices");
    }
    pos = countPlane + 4 * std::size_t(ng);
    return {};
  }

 private:
  std::span<const std::byte> bytes_;
  const std::string& file_;
  std::uint64_t base_;
};

}  // namespace

Status decodeInto(std::span<const std::byte> bytes, const std::string& file, std::uint64_t baseOffset,
                  Module& m) {
  auto fail = [&](std::uint64_t off, const std::string& msg) {
    return Status(Problem{file, baseOffset + off, "module: " + msg});
  };
  if (bytes.size() < kHeaderBytes) {
    return fail(bytes.size(), "truncated: the header needs " + str(kHeaderBytes) +
                                  " bytes, the input ends at byte " + str(bytes.size()));
  }
  const std::byte* h = bytes.data();
  // "SANDMOD" then the version's digit; the version field must agree.
  if (std::memcmp(h + field::magic, kMagic.data(), kMagic.size() - 1) != 0 ||
      h[7] < std::byte{'1'} || h[7] > std::byte{'6'}) {
    return fail(field::magic, "bad magic: not a sandtable load module (expected \"SANDMOD1\" to \"SANDMOD6\")");
  }
  const auto version = loadLE<std::uint32_t>(h + field::version);
  if (version < kVersion || version > kVersion6) {
    return fail(field::version, "version " + str(version) +
                                    " is not supported (this reader knows versions 1 to 6)");
  }
  if (std::uint32_t(h[7]) - '0' != version) {
    return fail(field::version, "version " + str(version) + " does not match the magic's \"SANDMOD" +
                                    char(h[7]) + "\"");
  }
  const auto storedHeaderCrc = loadLE<std::uint32_t>(h + field::headerCrc);
  const auto headerCrc = crc32(bytes.first(field::headerCrc));
  if (storedHeaderCrc != headerCrc) {
    return fail(field::headerCrc, "header checksum mismatch (stored " + crcHex(storedHeaderCrc) +
                                      ", computed " + crcHex(headerCrc) + ")");
  }
  if (loadLE<std::uint32_t>(h + field::headerBytes) != kHeaderBytes) {
    return fail(field::headerBytes, "header size must be " + str(kHeaderBytes));
  }
  if (loadLE<std::uint32_t>(h + field::flags) != 0) {
    return fail(field::flags, "flags must be 0 in version " + str(version));
  }
  const auto levelCount = loadLE<std::uint32_t>(h + field::levelCount);
  if (levelCount < 1 || levelCount > kMaxLevels) {
    return fail(field::levelCount, "level count " + str(levelCount) + " is out of range (1 to " +
                                       str(kMaxLevels) + ")");
  }
  const auto total = loadLE<std::uint64_t>(h + field::totalBytes);
  if (total != bytes.size()) {
    return fail(std::min<std::uint64_t>(total, bytes.size()),
                "input is " + str(bytes.size()) + " bytes but the header says " + str(total) +
                    (bytes.size() < total ? ": truncated" : ": trailing bytes"));
  }
  const auto storedPayloadCrc = loadLE<std::uint32_t>(h + field::payloadCrc);
  const auto payloadCrc = crc32(bytes.subspan(kHeaderBytes));
  if (storedPayloadCrc != payloadCrc) {
    return fail(field::payloadCrc, "payload checksum mismatch (stored " + crcHex(storedPayloadCrc) +
                                       ", computed " + crcHex(payloadCrc) +
                                       "): the module is corrupt");
  }

  m.kx = loadLE<std::uint32_t>(h + field::kx);
  m.kz = loadLE<std::uint32_t>(h + field::kz);
  m.levels.resize(levelCount);
  const LevelDecoder levels(bytes, file, baseOffset);
  std::size_t pos = kHeaderBytes;
  for (std::uint32_t li = 0; li < levelCount; ++li) {
    Level& l = m.levels[li];
    if (version == kVersion) {
      if (Status level = levels.decode(li, pos, l); !level) return level;
      l.normals.clear();  // version 1 has none
      l.heightStep = 0;
    } else if (Status level = detail::decodeLevelV2(bytes, file, baseOffset, li, pos, l, std::min(version, kVersion4));
               !level) {
      return level;
    }
  }
  m.scattering = {};
  if (version >= kVersion6) {
    if (Status objects = detail::decodeObjectsV6(bytes, file, baseOffset, pos, m); !objects) return objects;
  } else if (version == kVersion5) {
    if (Status objects = detail::decodeObjects(bytes, file, baseOffset, pos, m); !objects) return objects;
  } else {
    m.objects.clear();
    for (Level& l : m.levels) l.objectY.clear();
  }
  if (pos != bytes.size()) {
    return fail(pos, str(bytes.size() - pos) + " bytes follow the " +
                         (version >= kVersion5 ? "objects section" : "last level"));
  }
  return {};
}

Result<Module> decode(std::span<const std::byte> bytes, const std::string& file,
                      std::uint64_t baseOffset) {
  Module m;
  if (Status st = decodeInto(bytes, file, baseOffset, m); !st) return st.problems();
  return m;
}

}  // namespace sandtable::module
