// icons.pack v2 (docs/FORMAT.md §12), and v1 still read: golden bytes of
// both, round trips, every
// truncated prefix, hostile fields (with re-sealed CRCs, and hostile counts
// decoded under a memory limit), random mutations, and encode refusing
// what decode refuses with the same message and offset.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/icon_pack.h"

namespace sandtable::iconpack {
namespace {

namespace fs = std::filesystem;

std::string hex(std::span<const std::byte> b) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (std::byte x : b) {
    s += d[std::to_integer<int>(x) >> 4];
    s += d[std::to_integer<int>(x) & 15];
  }
  return s;
}

/// Bytes of a hex string (two digits a byte).
std::vector<std::byte> fromHex(const std::string& h) {
  std::vector<std::byte> b;
  for (std::size_t k = 0; k + 1 < h.size(); k += 2) {
    b.push_back(static_cast<std::byte>(std::stoi(h.substr(k, 2), nullptr, 16)));
  }
  return b;
}

/// zlib's crc32 called directly: expected CRCs that do not come from the
/// code under test.
std::uint32_t zlibCrc(std::span<const std::byte> b) {
  return static_cast<std::uint32_t>(
      ::crc32(0L, reinterpret_cast<const Bytef*>(b.data()), static_cast<uInt>(b.size())));
}

/// A u32 as 8 hex digits, little-endian, written out by shifts.
std::string leHex(std::uint32_t v) {
  std::string s;
  for (int k = 0; k < 4; ++k, v >>= 8) {
    static const char* d = "0123456789abcdef";
    s += d[(v >> 4) & 15];
    s += d[v & 15];
  }
  return s;
}

/// Sets body_bytes to the size and recomputes both CRCs, so that a
/// hand-made change reaches the checks behind them.
void reseal(std::vector<std::byte>& b) {
  storeLE<std::uint64_t>(b.data() + 24, b.size() - kHeaderBytes);
  storeLE<std::uint32_t>(b.data() + 32, crc32(std::span(b).subspan(kHeaderBytes)));
  storeLE<std::uint32_t>(b.data() + 36, crc32(std::span(b).first(36)));
}

void setU32(std::vector<std::byte>& b, std::size_t at, std::uint32_t v) { storeLE<std::uint32_t>(b.data() + at, v); }
void setF32(std::vector<std::byte>& b, std::size_t at, float v) { storeLE<float>(b.data() + at, v); }
void setU16(std::vector<std::byte>& b, std::size_t at, std::uint16_t v) { storeLE<std::uint16_t>(b.data() + at, v); }

/// The golden pack's one DIS pattern, 1.1.225.*.2: category, specific and
/// extra are wildcards (bits 3, 5, 6 of the mask: 0x68).
DisPattern goldenDis() { return DisPattern{{1, 1, 225, 0, 2, 0, 0}, 0x68}; }

/// One texture of 3 bytes; one icon "box" (armed, DIS pattern goldenDis())
/// with one material, two levels and one part (the alive hull) holding one
/// mesh of 3 vertices with texcoords: one triangle at level 0, none at level 1.
/// Version 1 stored no pattern: `v1` leaves it out.
Pack goldenPack(bool v1 = false) {
  Pack p;
  p.textures.push_back({"a", {std::byte{0x89}, std::byte{0x50}, std::byte{0x4e}}});
  Icon icon;
  icon.name = "box";
  icon.armed = true;
  if (!v1) {
    icon.dis = {goldenDis()};
  }
  icon.bounds = {0, 0, 0, 1, 1, 0};
  icon.cylinderRadius = 1;
  icon.cylinderHeight = 1;
  icon.materials = {Material{{255, 0, 0, 255}, 0}};
  icon.ranges = {100, 500};
  Mesh m;
  m.material = 0;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  m.normals = {0, 0, 1, 0, 0, 1, 0, 0, 1};
  m.texcoords = {0, 0, 1, 0, 0, 1};
  m.levels = {{0, 1, 2}, {}};
  Part hull;
  hull.meshes.push_back(m);
  icon.parts.push_back(hull);
  p.icons.push_back(icon);
  return p;
}

// Field offsets in the version 2 golden pack's 284 bytes (FORMAT.md §12.9).
namespace at {
constexpr std::size_t textureBytes = 43;  // texture 0 byte_count
constexpr std::size_t iconName = 50;      // icon 0 name length
constexpr std::size_t iconFlags = 55;
constexpr std::size_t disCount = 59;
constexpr std::size_t disPattern = 61;    // its wildcard mask; the type's 8 bytes follow
constexpr std::size_t bounds = 70;
constexpr std::size_t radius = 94;
constexpr std::size_t materialCount = 102;
constexpr std::size_t materialTexture = 110;
constexpr std::size_t levelCount = 114;
constexpr std::size_t ranges = 118;
constexpr std::size_t partCount = 126;
constexpr std::size_t state = 132;
constexpr std::size_t parent = 136;
constexpr std::size_t meshCount = 152;
constexpr std::size_t meshMaterial = 156;
constexpr std::size_t vertexCount = 160;
constexpr std::size_t meshFlags = 164;
constexpr std::size_t positions = 168;
constexpr std::size_t normals = 204;
constexpr std::size_t level0Count = 264;
constexpr std::size_t level0Indices = 268;
constexpr std::size_t end = 284;
}  // namespace at

// The version 1 golden pack's 281 bytes: the icon's 8 DIS bytes where
// version 2 has its pattern count and patterns.
namespace at1 {
constexpr std::size_t iconFlags = 55;
constexpr std::size_t dis = 59;
constexpr std::size_t bounds = 67;
constexpr std::size_t end = 281;
}  // namespace at1

/// A mesh of `n` vertices on a fan: level l keeps every (l+1)th triangle.
Mesh fan(std::uint32_t material, std::uint32_t n, bool texcoords, std::size_t levels, float shift) {
  Mesh m;
  m.material = material;
  for (std::uint32_t k = 0; k < n; ++k) {
    const float a = static_cast<float>(k) * 0.7f;
    m.positions.insert(m.positions.end(), {std::cos(a) + shift, 0.25f * static_cast<float>(k), std::sin(a)});
    m.normals.insert(m.normals.end(), {std::cos(a), 0, std::sin(a)});
    if (texcoords) {
      m.texcoords.insert(m.texcoords.end(), {static_cast<float>(k) / static_cast<float>(n), 0.5f});
    }
  }
  m.levels.resize(levels);
  for (std::size_t l = 0; l < levels; ++l) {
    for (std::uint32_t k = 1; k + 1 < n; k += static_cast<std::uint32_t>(l + 1)) {
      m.levels[l].insert(m.levels[l].end(), {0, k, k + 1});
    }
  }
  return m;
}

/// Two textures (one empty), a tank with a DIS type, an alive hull, a
/// turret on it and a gun on the turret, a dead hull, a material without
/// texture; a tree with one level and a part without meshes.
Pack richPack() {
  Pack p;
  p.textures.push_back({"camo.png", {std::byte{1}, std::byte{2}, std::byte{3}, std::byte{4}, std::byte{5}}});
  p.textures.push_back({"empty.jpg", {}});
  Icon tank;
  tank.name = "M1A1 tank";
  tank.armed = true;
  tank.dis = {DisPattern{{1, 1, 225, 1, 1, 3, 0}, 0}, DisPattern{{1, 1, 0, 1, 0, 0, 0}, 0x74},
              DisPattern{{}, kDisAllWild}};
  tank.bounds = {-2, 0, -4.5f, 2, 2.5f, 4.5f};
  tank.cylinderRadius = 4.9f;
  tank.cylinderHeight = 2.5f;
  tank.materials = {Material{{90, 100, 60, 255}, 0}, Material{{20, 20, 20, 255}, kNoTexture},
                    Material{{200, 200, 200, 128}, 1}};
  tank.ranges = {50, 200, 1000};
  Part hull;
  hull.meshes = {fan(0, 8, true, 3, 0), fan(1, 5, false, 3, 1)};
  Part turret;
  turret.name = "turret";
  turret.parent = 0;
  turret.offset = {0, 1.5f, -0.25f};
  turret.meshes = {fan(0, 6, true, 3, 0)};
  Part gun;
  gun.name = "gun";
  gun.parent = 1;
  gun.offset = {-0.0f, 0.25f, 1.75f};  // -0.0 must come back bit for bit
  gun.meshes = {fan(2, 4, false, 3, 0)};
  Part dead;
  dead.state = State::dead;
  dead.meshes = {fan(1, 7, false, 3, 2)};
  tank.parts = {hull, turret, gun, dead};
  Icon tree;
  tree.name = "tree";
  tree.resupply = true;
  tree.bounds = {-1, 0, -1, 1, 6, 1};
  tree.cylinderRadius = 1.4f;
  tree.cylinderHeight = 6;
  tree.materials = {Material{}};
  tree.ranges = {300};
  Part trunk;
  trunk.meshes = {fan(0, 5, false, 1, 0)};
  Part marker;
  marker.name = "marker";
  tree.parts = {trunk, marker};
  p.icons = {tank, tree};
  return p;
}

std::vector<std::byte> encoded(const Pack& p) {
  auto b = encode(p);
  EXPECT_TRUE(b.ok()) << b.error();
  return b.ok() ? b.value() : std::vector<std::byte>{};
}

bool startsWith(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }

/// The version 1 golden pack (FORMAT.md §12.10), as version 1 wrote it.
std::vector<std::byte> version1Bytes() {
  const std::string body =
      // texture 0: name "a", byte_count 3, the bytes
      "0100"
      "61"
      "03000000"
      "89504e"
      // icon 0: name "box", flags 1 (armed), DIS type all zero
      "0300"
      "626f78"
      "01000000"
      "0000000000000000"
      // bounds: min 0 0 0, max 1 1 0 (1.0f = 0x3f800000); cylinder radius 1, height 1
      "00000000"
      "00000000"
      "00000000"
      "0000803f"
      "0000803f"
      "00000000"
      "0000803f"
      "0000803f"
      // 1 material: rgba ff 00 00 ff, texture 0
      "01000000"
      "ff0000ff"
      "00000000"
      // 2 levels: ranges 100 (0x42c80000), 500 (0x43fa0000)
      "02000000"
      "0000c842"
      "0000fa43"
      // 1 part: name "", state 0 (alive), reserved u8 0 and u16 0, parent -1,
      // offset 0 0 0, 1 mesh
      "01000000"
      "0000"
      "00"
      "00"
      "0000"
      "ffffffff"
      "000000000000000000000000"
      "01000000"
      // mesh 0: material 0, 3 vertices, flags 1 (has texcoords)
      "00000000"
      "03000000"
      "01000000"
      // positions (0,0,0) (1,0,0) (0,1,0)
      "000000000000000000000000"
      "0000803f0000000000000000"
      "000000000000803f00000000"
      // normals (0,0,1) three times
      "00000000000000000000803f"
      "00000000000000000000803f"
      "00000000000000000000803f"
      // texcoords (0,0) (1,0) (0,1)
      "0000000000000000"
      "0000803f00000000"
      "000000000000803f"
      // level 0: 3 indices 0 1 2; level 1: no index
      "03000000"
      "00000000"
      "01000000"
      "02000000"
      "00000000";
  const std::string fields = "535449434f4e5300"
                             "01000000"
                             "28000000"
                             "01000000"
                             "01000000"
                             "f100000000000000" +
                             leHex(zlibCrc(fromHex(body)));
  return fromHex(fields + leHex(zlibCrc(fromHex(fields))) + body);
}

// Golden bytes of version 2. If this fails, the format changed: bump
// kVersion, keep a reader for versions 1 and 2, and add a new golden test.
// The fields are written out by hand; both CRCs are computed here with zlib
// over the bytes FORMAT.md §12 says they cover.
TEST(IconPack, version2GoldenBytes) {
  const std::string body =
      // texture 0: name "a", byte_count 3, the bytes
      "0100"
      "61"
      "03000000"
      "89504e"
      // icon 0: name "box", flags 1 (armed)
      "0300"
      "626f78"
      "01000000"
      // 1 DIS pattern: mask 0x68 (category, specific, extra are wildcards),
      // kind 1, domain 1, country 225 (0x00e1), category 0, subcategory 2,
      // specific 0, extra 0: "1.1.225.*.2"
      "0100"
      "68"
      "01"
      "01"
      "e100"
      "00"
      "02"
      "00"
      "00"
      // bounds: min 0 0 0, max 1 1 0 (1.0f = 0x3f800000); cylinder radius 1, height 1
      "00000000"
      "00000000"
      "00000000"
      "0000803f"
      "0000803f"
      "00000000"
      "0000803f"
      "0000803f"
      // 1 material: rgba ff 00 00 ff, texture 0
      "01000000"
      "ff0000ff"
      "00000000"
      // 2 levels: ranges 100 (0x42c80000), 500 (0x43fa0000)
      "02000000"
      "0000c842"
      "0000fa43"
      // 1 part: name "", state 0 (alive), reserved u8 0 and u16 0, parent -1,
      // offset 0 0 0, 1 mesh
      "01000000"
      "0000"
      "00"
      "00"
      "0000"
      "ffffffff"
      "000000000000000000000000"
      "01000000"
      // mesh 0: material 0, 3 vertices, flags 1 (has texcoords)
      "00000000"
      "03000000"
      "01000000"
      // positions (0,0,0) (1,0,0) (0,1,0)
      "000000000000000000000000"
      "0000803f0000000000000000"
      "000000000000803f00000000"
      // normals (0,0,1) three times
      "00000000000000000000803f"
      "00000000000000000000803f"
      "00000000000000000000803f"
      // texcoords (0,0) (1,0) (0,1)
      "0000000000000000"
      "0000803f00000000"
      "000000000000803f"
      // level 0: 3 indices 0 1 2; level 1: no index
      "03000000"
      "00000000"
      "01000000"
      "02000000"
      "00000000";
  const std::vector<std::byte> bodyBytes = fromHex(body);
  ASSERT_EQ(bodyBytes.size(), 244u);
  const std::uint32_t bodyCrc = zlibCrc(bodyBytes);
  EXPECT_EQ(bodyCrc, 0x80f191ddu);  // the value FORMAT.md §12.9 quotes
  // Header: magic "STICONS\0", version 2, header_bytes 40, 1 icon, 1
  // texture, body_bytes 244 (0xf4), body_crc, then the CRC of bytes 0..35.
  const std::string fields = "535449434f4e5300"
                             "02000000"
                             "28000000"
                             "01000000"
                             "01000000"
                             "f400000000000000" +
                             leHex(bodyCrc);
  ASSERT_EQ(fromHex(fields).size(), 36u);
  const std::uint32_t headerCrc = zlibCrc(fromHex(fields));
  EXPECT_EQ(headerCrc, 0x0f33fc92u);  // the value FORMAT.md §12.9 quotes
  const std::vector<std::byte> expected = fromHex(fields + leHex(headerCrc) + body);
  ASSERT_EQ(expected.size(), 284u);

  EXPECT_EQ(hex(encoded(goldenPack())), hex(expected));
  auto back = decode(expected, "golden.pack");
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back.value(), goldenPack());
  EXPECT_EQ(triangleCount(back->icons[0], 0), 1u);
  EXPECT_EQ(triangleCount(back->icons[0], 1), 0u);
  EXPECT_EQ(triangleCount(back->icons[0], 2), 0u);  // no such level
  EXPECT_EQ(triangleCount(back->icons[0], 0, State::dead), 0u);
}

// Version 1 packs (written before DIS patterns) still read: the golden
// bytes of version 1, worked out by hand when it was current, give the same
// pack less its pattern; a version 1 DIS type (flag bit 2) reads as one
// pattern without wildcards. encode writes version 2.
TEST(IconPack, version1PacksStillRead) {
  const std::vector<std::byte> v1 = version1Bytes();
  ASSERT_EQ(v1.size(), at1::end);
  EXPECT_EQ(zlibCrc(std::span(v1).subspan(40)), 0xd147c6c1u);  // as FORMAT.md quoted for version 1
  EXPECT_EQ(zlibCrc(std::span(v1).first(36)), 0x488134ebu);
  auto back = decode(v1, "v1.pack");
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back.value(), goldenPack(true));
  const auto upgraded = encoded(back.value());
  EXPECT_EQ(loadLE<std::uint32_t>(upgraded.data() + 8), kVersion);
  EXPECT_EQ(upgraded.size(), at1::end - 6);  // 8 DIS bytes become a pattern count of 0
  // With a DIS type: flags armed | has DIS type, the type 1.1.225.1.1.3.0.
  std::vector<std::byte> withDis = v1;
  setU32(withDis, at1::iconFlags, 0x5);
  const std::vector<std::byte> type = fromHex("0101e10001010300");
  std::copy(type.begin(), type.end(), withDis.begin() + at1::dis);
  reseal(withDis);
  auto dis = decode(withDis, "v1.pack");
  ASSERT_TRUE(dis.ok()) << dis.error();
  ASSERT_EQ(dis->icons[0].dis.size(), 1u);
  EXPECT_EQ(dis->icons[0].dis[0], (DisPattern{{1, 1, 225, 1, 1, 3, 0}, 0}));
  // Version 1's own rules still hold.
  struct V1Case {
    const char* name;
    std::function<void(std::vector<std::byte>&)> change;
    std::string message;
    std::uint64_t offset;
  };
  const std::vector<V1Case> cases = {
      {"DIS bytes without the flag", [](auto& b) { b[at1::dis + 1] = std::byte{1}; },
       "icon 0 'box' has DIS type bytes that are not zero but flag bit 2 (has DIS type) is clear", at1::dis},
      {"unknown flag bits", [](auto& b) { setU32(b, at1::iconFlags, 0x9); },
       "icon 0 'box' flags 0x00000009 have bits set other than bit 0 (armed), 1 (resupply) and 2 (has DIS type)",
       at1::iconFlags},
      {"icon count past the body", [](auto& b) { setU32(b, 16, 65535); },
       "truncated in icons: icon count 65535 needs at least 6356895 bytes, the body has 231 left", 16},
  };
  for (const V1Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<std::byte> b = v1;
    c.change(b);
    reseal(b);
    auto p = decode(b, "v1.pack");
    ASSERT_FALSE(p.ok());
    EXPECT_NE(p.message().find(c.message), std::string::npos) << p.message();
    EXPECT_EQ(p.problems().front().offset, c.offset) << p.message();
  }
  // Every prefix of a version 1 pack fails, as of version 2.
  for (std::size_t n = 0; n < v1.size(); ++n) {
    auto p = decode(std::span(v1).first(n), "cut.pack");
    ASSERT_FALSE(p.ok()) << "prefix " << n;
    EXPECT_LE(p.problems().front().offset, n);
    EXPECT_NE(p.message().find("truncated"), std::string::npos) << "prefix " << n << ": " << p.message();
  }
  for (std::size_t n = kHeaderBytes; n < v1.size(); ++n) {
    std::vector<std::byte> cut(v1.begin(), v1.begin() + static_cast<std::ptrdiff_t>(n));
    reseal(cut);
    auto p = decode(cut, "cut.pack");
    ASSERT_FALSE(p.ok()) << "prefix " << n;
    EXPECT_TRUE(startsWith(p.message(), "icons.pack: truncated in ")) << "prefix " << n << ": " << p.message();
  }
}

TEST(IconPack, roundTripsARichPack) {
  const Pack p = richPack();
  const auto bytes = encoded(p);
  auto back = decode(bytes, "rich.pack");
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back.value(), p);
  EXPECT_EQ(encoded(back.value()), bytes);  // bit for bit (-0.0 included)
  const Icon& tank = back->icons[0];
  ASSERT_EQ(tank.dis.size(), 3u);
  EXPECT_EQ(tank.dis[0].type.country, 225);
  EXPECT_EQ(tank.dis[1].wild, 0x74);
  EXPECT_EQ(tank.materials[1].texture, kNoTexture);
  EXPECT_EQ(tank.parts[2].parent, 1);
  EXPECT_TRUE(std::signbit(tank.parts[2].offset[0]));
  EXPECT_EQ(tank.parts[3].state, State::dead);
  EXPECT_TRUE(tank.parts[1].meshes[0].texcoords.size() == 12);
  EXPECT_TRUE(back->icons[1].resupply);
  EXPECT_TRUE(back->icons[1].dis.empty());
  EXPECT_TRUE(back->icons[1].parts[1].meshes.empty());
  EXPECT_TRUE(back->textures[1].bytes.empty());
  // Fans of 8, 5, 6 and 4 vertices alive; 7 dead. Level 1 keeps every other triangle.
  EXPECT_EQ(triangleCount(tank, 0), 6u + 3u + 4u + 2u);
  EXPECT_EQ(triangleCount(tank, 1), 3u + 2u + 2u + 1u);
  EXPECT_EQ(triangleCount(tank, 0, State::dead), 5u);
  // An empty pack is a pack too.
  auto none = decode(encoded(Pack{}), "empty.pack");
  ASSERT_TRUE(none.ok()) << none.error();
  EXPECT_EQ(none.value(), Pack{});
  EXPECT_EQ(encoded(Pack{}).size(), kHeaderBytes);
}

TEST(IconPack, readsWhatItWrites) {
  const fs::path dir = fs::temp_directory_path() / ("sandtable-iconpack." + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / kFileName).string();
  ASSERT_TRUE(writeFile(path, richPack()).ok());
  auto back = readFile(path);
  ASSERT_TRUE(back.ok()) << back.error();
  EXPECT_EQ(back.value(), richPack());
  // A pack encode refuses is not written, and the problem names the path.
  Pack bad = richPack();
  bad.icons[1].name = "M1A1 tank";
  const std::string badPath = (dir / "bad.pack").string();
  const Status st = writeFile(badPath, bad);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.problems().front().file, badPath);
  EXPECT_NE(st.message().find("already used by icon 0"), std::string::npos) << st.message();
  EXPECT_FALSE(fs::exists(badPath));
  // Unreadable files.
  auto missing = readFile((dir / "missing.pack").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.problems().front().file, (dir / "missing.pack").string());
  EXPECT_TRUE(startsWith(missing.message(), "icons.pack: cannot open")) << missing.message();
  fs::remove_all(dir);
}

TEST(IconPack, everyTruncatedPrefixFails) {
  const auto bytes = encoded(richPack());
  ASSERT_GT(bytes.size(), 1000u);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    auto p = decode(std::span(bytes).first(n), "cut.pack");
    ASSERT_FALSE(p.ok()) << "prefix " << n;
    const Problem& q = p.problems().front();
    EXPECT_EQ(q.file, "cut.pack");
    EXPECT_LE(q.offset, n);
    EXPECT_TRUE(startsWith(q.message, "icons.pack: ")) << q.message;
    EXPECT_NE(q.message.find("truncated"), std::string::npos) << "prefix " << n << ": " << q.message;
  }
}

// A body cut short whose header is re-sealed to match (a writer bug, or
// hostile bytes) gets past the size and CRC checks: every such prefix then
// fails where the parse runs out, naming what it was reading.
TEST(IconPack, everyResealedTruncatedBodyFailsWhereItRunsOut) {
  const auto bytes = encoded(richPack());
  for (std::size_t n = kHeaderBytes; n < bytes.size(); ++n) {
    std::vector<std::byte> cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    reseal(cut);
    auto p = decode(cut, "cut.pack");
    ASSERT_FALSE(p.ok()) << "prefix " << n;
    const Problem& q = p.problems().front();
    EXPECT_EQ(q.file, "cut.pack");
    EXPECT_LE(q.offset, n);
    EXPECT_TRUE(startsWith(q.message, "icons.pack: truncated in ")) << "prefix " << n << ": " << q.message;
  }
  // The message says where: the golden pack cut inside its positions.
  auto golden = encoded(goldenPack());
  golden.resize(at::positions + 40);
  reseal(golden);
  auto p = decode(golden, "cut.pack");
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.problems().front().offset, at::vertexCount);
  EXPECT_EQ(p.message(),
            "icons.pack: truncated in icon 0 'box', part 0, mesh 0 positions: vertex count 3 needs 96 bytes of "
            "positions, normals and texcoords, the body has 40 left");
}

#if defined(__SANITIZE_ADDRESS__)
#define SANDTABLE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SANDTABLE_ASAN 1
#endif
#endif

/// Decodes `bytes` in a child process whose address space may grow by at
/// most 32 MiB beyond what it has: a decoder that sized a vector by a
/// hostile count before checking it against the bytes left would die of
/// bad_alloc there. True when the child's decode failed cleanly. (Under
/// AddressSanitizer, whose shadow memory defeats an address-space limit,
/// it only decodes.)
bool failsWithinMemory(const std::vector<std::byte>& bytes) {
#ifdef SANDTABLE_ASAN
  return !decode(bytes, "hostile").ok();
#else
  const pid_t pid = ::fork();
  if (pid < 0) {
    return false;
  }
  if (pid == 0) {
    long pages = 0;
    std::ifstream statm("/proc/self/statm");
    statm >> pages;
    const auto limit = static_cast<rlim_t>(pages) * static_cast<rlim_t>(::sysconf(_SC_PAGESIZE)) + (32u << 20);
    const rlimit r{limit, limit};
    int code = 4;
    if (pages > 0 && ::setrlimit(RLIMIT_AS, &r) == 0) {
      try {
        code = decode(bytes, "hostile").ok() ? 2 : 0;
      } catch (...) {
        code = 3;  // bad_alloc: a hostile count was trusted
      }
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
#endif
}

// Each malformed input with its message and offset. Byte-level changes to
// the golden pack; `seal` re-seals the size and CRCs afterwards so that the
// check behind them is the one exercised.
struct Hostile {
  const char* name;
  std::function<void(std::vector<std::byte>&)> change;
  bool seal;
  std::string message;  // a substring of the first problem's message
  std::uint64_t offset;
  bool count = false;  // a hostile count: decoded under a memory limit first
};

std::vector<Hostile> hostileCases() {
  const std::uint32_t huge = 0xFFFFFFFFu;
  auto u32 = [](std::size_t where, std::uint32_t v) {
    return [=](std::vector<std::byte>& b) { setU32(b, where, v); };
  };
  auto f32 = [](std::size_t where, float v) { return [=](std::vector<std::byte>& b) { setF32(b, where, v); }; };
  auto u8 = [](std::size_t where, std::uint8_t v) {
    return [=](std::vector<std::byte>& b) { b[where] = static_cast<std::byte>(v); };
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  return {
      // Header, in check order.
      {"short header", [](auto& b) { b.resize(39); }, false, "truncated header: the header needs 40 bytes", 39},
      {"bad magic", u8(0, 'X'), true, "bad magic: not a sandtable icon database", 0},
      {"version too new", u32(8, 3), true, "version 3 is not supported (this reader knows versions 1 and 2)", 8},
      {"version 0", u32(8, 0), true, "version 0 is not supported (this reader knows versions 1 and 2)", 8},
      {"header size", u32(12, 48), true, "header size 48 must be 40", 12},
      {"header CRC", u8(36, 0x5a), false, "header checksum mismatch (stored 0x", 36},
      {"body size: truncated", [](auto& b) { b.pop_back(); }, false,
       "file is 283 bytes but the header says 40 + 244: truncated", 283},
      {"body size: trailing bytes", [](auto& b) { b.push_back(std::byte{0}); }, false,
       "file is 285 bytes but the header says 40 + 244: trailing bytes", 284},
      {"body CRC", [](auto& b) { b[200] ^= std::byte{1}; }, false, "body checksum mismatch (stored 0x", 32},
      // Counts, checked against the bytes left before anything is sized.
      {"icon count out of range", u32(16, huge), true, "icon count 4294967295 is out of range (0 to 65535)", 16,
       true},
      {"icon count past the body", u32(16, 65535), true,
       "truncated in icons: icon count 65535 needs at least 5963685 bytes, the body has 234 left", 16, true},
      {"texture count past the body", u32(20, huge), true,
       "truncated in textures: texture count 4294967295 needs at least 25769803770 bytes, the body has 244 "
       "left", 20,
       true},
      {"texture byte count", u32(at::textureBytes, huge), true,
       "truncated in texture 0 'a' bytes: needs 4294967295 bytes, the body has 237 left", at::textureBytes, true},
      {"material count out of range", u32(at::materialCount, huge), true,
       "icon 0 'box' material count 4294967295 is out of range (1 to 65535)", at::materialCount, true},
      {"material count past the body", u32(at::materialCount, 65535), true,
       "truncated in icon 0 'box' materials: material count 65535 needs 524280 bytes", at::materialCount, true},
      {"part count past the body", u32(at::partCount, 256), true,
       "truncated in icon 0 'box' parts: part count 256 needs at least 6656 bytes", at::partCount, true},
      {"mesh count past the body", u32(at::meshCount, 65535), true,
       "truncated in icon 0 'box', part 0 meshes: mesh count 65535 needs at least 2883540 bytes", at::meshCount, true},
      {"vertex count out of range", u32(at::vertexCount, huge), true,
       "icon 0 'box', part 0, mesh 0 vertex count 4294967295 is out of range (1 to 16777216)", at::vertexCount,
       true},
      {"vertex count past the body", u32(at::vertexCount, 1u << 24), true,
       "truncated in icon 0 'box', part 0, mesh 0 positions: vertex count 16777216 needs 536870912 bytes of "
       "positions, normals and texcoords, the body has 116 left",
       at::vertexCount, true},
      {"index count past the body", u32(at::level0Count, huge), true,
       "truncated in icon 0 'box', part 0, mesh 0 indices: index count 4294967295 needs 17179869180 bytes, the "
       "body has 16 left",
       at::level0Count, true},
      // References.
      {"index out of range", u32(at::level0Indices + 4, 3), true,
       "icon 0 'box', part 0, mesh 0 level 0 index 1 is 3, not below the vertex count 3", at::level0Indices + 4},
      {"index count not a multiple of 3", u32(at::level0Count, 2), true,
       "icon 0 'box', part 0, mesh 0 level 0 index count 2 is not a multiple of 3", at::level0Count},
      {"mesh material out of range", u32(at::meshMaterial, 1), true,
       "icon 0 'box', part 0, mesh 0 material 1 is not below the icon's 1 materials", at::meshMaterial},
      {"texture out of range", u32(at::materialTexture, 1), true,
       "icon 0 'box' material 0 texture 1 is not below the pack's 1 textures", at::materialTexture},
      {"parent not earlier", u32(at::parent, 0), true,
       "icon 0 'box', part 0 parent 0 is neither -1 (the icon's body) nor an earlier part", at::parent},
      {"parent below -1", u32(at::parent, 0xFFFFFFFEu), true, "part 0 parent -2 is neither", at::parent},
      // Values.
      {"NaN position", f32(at::positions + 16, nan), true,
       "icon 0 'box', part 0, mesh 0 positions[4] (vertex 1) is nan; every value must be finite",
       at::positions + 16},
      {"infinite normal", f32(at::normals + 8, std::numeric_limits<float>::infinity()), true,
       "mesh 0 normals[2] (vertex 0) is inf", at::normals + 8},
      {"NaN bounds", f32(at::bounds + 20, nan), true, "icon 0 'box' bounds[5] is nan", at::bounds + 20},
      {"bounds min above max", f32(at::bounds, 2), true, "icon 0 'box' bounds min x (2) is greater than max x (1)",
       at::bounds},
      {"negative cylinder radius", f32(at::radius, -1), true,
       "icon 0 'box' cylinder radius -1 is not a finite number >= 0", at::radius},
      {"level count out of range", u32(at::levelCount, 9), true, "icon 0 'box' level count 9 is out of range (1 to 8)",
       at::levelCount},
      {"non-increasing ranges", f32(at::ranges + 4, 100), true,
       "icon 0 'box' range 1 (100) is not greater than range 0 (100); ranges must increase strictly", at::ranges + 4},
      {"range not positive", f32(at::ranges, 0), true, "icon 0 'box' range 0 (0) is not a finite number > 0",
       at::ranges},
      // Flags and reserved bits.
      {"unknown icon flag bits", u32(at::iconFlags, 0x11), true,
       "icon 0 'box' flags 0x00000011 have bits set other than bit 0 (armed) and 1 (resupply)", at::iconFlags},
      {"version 1's DIS flag in version 2", u32(at::iconFlags, 0x5), true,
       "icon 0 'box' flags 0x00000005 have bits set other than bit 0 (armed) and 1 (resupply)", at::iconFlags},
      {"unknown mesh flag bits", u32(at::meshFlags, 3), true,
       "icon 0 'box', part 0, mesh 0 flags 0x00000003 have bits set other than bit 0 (has texcoords)",
       at::meshFlags},
      // DIS patterns.
      {"DIS pattern count out of range", [](auto& b) { setU16(b, at::disCount, 65); }, true,
       "icon 0 'box' DIS pattern count 65 is out of range (0 to 64)", at::disCount},
      {"DIS pattern count past the body", [](auto& b) { setU16(b, at::disCount, 64); }, true,
       "truncated in icon 0 'box' DIS patterns: DIS pattern count 64 needs 576 bytes, the body has 223 left",
       at::disCount},
      {"DIS wildcard mask bit 7", u8(at::disPattern, 0xe8), true,
       "icon 0 'box' DIS pattern 0 wildcard mask 0xe8 has bit 7 set; bits 0 to 6 are kind to extra", at::disPattern},
      {"DIS wildcard field not zero", u8(at::disPattern + 5, 3), true,
       "icon 0 'box' DIS pattern 0 category is a wildcard but stores 3; a wildcard field stores 0",
       at::disPattern + 5},
      {"DIS wildcard extra not zero", u8(at::disPattern + 8, 1), true,
       "DIS pattern 0 extra is a wildcard but stores 1", at::disPattern + 8},
      {"state not alive or dead", u8(at::state, 2), true, "icon 0 'box', part 0 state 2 is not 0 (alive) or 1 (dead)",
       at::state},
      {"reserved byte", u8(at::state + 2, 1), true, "icon 0 'box', part 0 reserved bytes after the state are not zero",
       at::state + 2},
      // Names.
      {"empty icon name", [](auto& b) { b[at::iconName] = std::byte{0}; }, true,
       "icon 0 name is empty; every icon needs a name", at::iconName},
      {"name too long", [](auto& b) { b[at::iconName] = std::byte{0x2c}; b[at::iconName + 1] = std::byte{1}; },
       true, "icon 0 name is 300 bytes, more than 255", at::iconName},
      {"control byte in a name", u8(at::iconName + 3, 0x0a), true,
       "icon 0 name has control byte 0x0A at byte 1; names are printable text", at::iconName + 3},
      {"DEL in a name", u8(at::iconName + 2, 0x7f), true, "name has control byte 0x7F at byte 0", at::iconName + 2},
      {"duplicate icon names",
       [](auto& b) {
         const std::vector<std::byte> icon(b.begin() + at::iconName, b.end());
         b.insert(b.end(), icon.begin(), icon.end());
         setU32(b, 16, 2);
       },
       true, "icon 1 'box' name 'box' is already used by icon 0; give every icon its own name", at::end},
      {"no alive hull", u8(at::state, 1), true,
       "icon 0 'box' has no alive hull: one part must have state alive (0), parent -1 and an empty name",
       at::partCount},
      {"trailing bytes after the last icon", [](auto& b) { b.push_back(std::byte{0}); }, true,
       "trailing bytes: the last icon ends at byte 284, the body at byte 285", at::end},
  };
}

TEST(IconPack, hostileBytesGiveTheirMessages) {
  const auto golden = encoded(goldenPack());
  ASSERT_EQ(golden.size(), at::end);
  for (const Hostile& h : hostileCases()) {
    SCOPED_TRACE(h.name);
    std::vector<std::byte> b = golden;
    h.change(b);
    if (h.seal) {
      reseal(b);
    }
    if (h.count) {
      ASSERT_TRUE(failsWithinMemory(b)) << "a hostile count was trusted before it was checked";
    }
    auto p = decode(b, "hostile.pack");
    ASSERT_FALSE(p.ok());
    const Problem& q = p.problems().front();
    EXPECT_EQ(q.file, "hostile.pack");
    EXPECT_TRUE(startsWith(q.message, "icons.pack: ")) << q.message;
    EXPECT_NE(q.message.find(h.message), std::string::npos) << q.message;
    EXPECT_EQ(q.offset, h.offset) << q.message;
  }
}

// Random byte changes, insertions and deletions, re-sealed: decode never
// crashes, and either fails with problems in the file or accepts a pack
// that encodes back to the very same bytes (one encoding per pack).
TEST(IconPack, randomMutationsNeverCrash) {
  const std::vector<std::vector<std::byte>> bases = {encoded(goldenPack()), encoded(richPack()), version1Bytes()};
  std::mt19937 rng(20260501);
  int accepted = 0;
  for (int iter = 0; iter < 4000; ++iter) {
    std::vector<std::byte> b = bases[static_cast<std::size_t>(iter) % bases.size()];
    const int changes = 1 + static_cast<int>(rng() % 4);
    for (int c = 0; c < changes; ++c) {
      const std::size_t where = rng() % b.size();
      switch (rng() % 8) {
        case 0:
          b.insert(b.begin() + static_cast<std::ptrdiff_t>(where), static_cast<std::byte>(rng()));
          break;
        case 1:
          if (b.size() > kHeaderBytes + 1) {
            b.erase(b.begin() + static_cast<std::ptrdiff_t>(where));
          }
          break;
        case 2:
          b[where] ^= static_cast<std::byte>(1u << (rng() % 8));
          break;
        default:
          b[where] = static_cast<std::byte>(rng());
          break;
      }
    }
    if (rng() % 8 != 0) {
      reseal(b);
    }
    auto p = decode(b, "mutant.pack");
    if (p.ok()) {
      ++accepted;
      auto again = encode(p.value());
      ASSERT_TRUE(again.ok()) << "iteration " << iter << ": decode accepts what encode refuses: " << again.error();
      if (loadLE<std::uint32_t>(b.data() + 8) == kVersion) {
        ASSERT_EQ(hex(again.value()), hex(b)) << "iteration " << iter;
      } else {  // a mutated version field: an older version is rewritten in the newest, same pack
        auto twice = decode(again.value(), "again.pack");
        ASSERT_TRUE(twice.ok()) << twice.error();
        ASSERT_EQ(twice.value(), p.value()) << "iteration " << iter;
      }
    } else {
      ASSERT_FALSE(p.problems().empty());
      const Problem& q = p.problems().front();
      EXPECT_EQ(q.file, "mutant.pack");
      EXPECT_LE(q.offset, b.size());
      EXPECT_TRUE(startsWith(q.message, "icons.pack: ")) << q.message;
    }
  }
  EXPECT_GT(accepted, 0);  // some mutations (a float, a colour) still make a pack
}

// Encode mirrors decode: a pack that breaks a rule the bytes can express
// is refused with the very problem (message and offset) decode gives for
// the same change made to the bytes.
TEST(IconPack, encodeRefusesWhatDecodeRefuses) {
  struct Pair {
    const char* name;
    std::function<void(Pack&)> model;
    std::function<void(std::vector<std::byte>&)> bytes;
  };
  auto mesh0 = [](Pack& p) -> Mesh& { return p.icons[0].parts[0].meshes[0]; };
  const std::vector<Pair> pairs = {
      {"index out of range", [&](Pack& p) { mesh0(p).levels[0][1] = 3; },
       [](auto& b) { setU32(b, at::level0Indices + 4, 3); }},
      {"material out of range", [&](Pack& p) { mesh0(p).material = 1; },
       [](auto& b) { setU32(b, at::meshMaterial, 1); }},
      {"texture out of range", [](Pack& p) { p.icons[0].materials[0].texture = 1; },
       [](auto& b) { setU32(b, at::materialTexture, 1); }},
      {"parent not earlier", [](Pack& p) { p.icons[0].parts[0].parent = 0; }, [](auto& b) { setU32(b, at::parent, 0); }},
      {"NaN position", [&](Pack& p) { mesh0(p).positions[4] = std::nanf(""); },
       [](auto& b) { setF32(b, at::positions + 16, std::nanf("")); }},
      {"non-increasing ranges", [](Pack& p) { p.icons[0].ranges[1] = 100; },
       [](auto& b) { setF32(b, at::ranges + 4, 100); }},
      {"bounds", [](Pack& p) { p.icons[0].bounds[0] = 2; }, [](auto& b) { setF32(b, at::bounds, 2); }},
      {"DIS wildcard field not zero", [](Pack& p) { p.icons[0].dis[0].type.category = 3; },
       [](auto& b) { b[at::disPattern + 5] = std::byte{3}; }},
      {"DIS wildcard mask bit 7", [](Pack& p) { p.icons[0].dis[0].wild |= 0x80; },
       [](auto& b) { b[at::disPattern] = std::byte{0xe8}; }},
      {"state", [](Pack& p) { p.icons[0].parts[0].state = static_cast<State>(2); },
       [](auto& b) { b[at::state] = std::byte{2}; }},
      {"no alive hull", [](Pack& p) { p.icons[0].parts[0].state = State::dead; },
       [](auto& b) { b[at::state] = std::byte{1}; }},
      {"index count", [&](Pack& p) { mesh0(p).levels[0].pop_back(); },
       [](auto& b) {
         setU32(b, at::level0Count, 2);
         b.erase(b.begin() + at::level0Indices + 8, b.begin() + at::level0Indices + 12);
       }},
      {"empty name", [](Pack& p) { p.icons[0].name.clear(); },
       [](auto& b) {
         b[at::iconName] = std::byte{0};
         b.erase(b.begin() + at::iconName + 2, b.begin() + at::iconName + 5);
         setU32(b, 16, 1);
       }},
      {"duplicate name", [](Pack& p) { p.icons.push_back(p.icons[0]); },
       [](auto& b) {
         const std::vector<std::byte> icon(b.begin() + at::iconName, b.end());
         b.insert(b.end(), icon.begin(), icon.end());
         setU32(b, 16, 2);
       }},
  };
  for (const Pair& c : pairs) {
    SCOPED_TRACE(c.name);
    Pack p = goldenPack();
    c.model(p);
    auto e = encode(p);
    ASSERT_FALSE(e.ok());
    std::vector<std::byte> b = encoded(goldenPack());
    c.bytes(b);
    reseal(b);
    auto d = decode(b, "x");
    ASSERT_FALSE(d.ok());
    EXPECT_EQ(e.message(), d.message());
    EXPECT_EQ(e.problems().front().offset, d.problems().front().offset);
    EXPECT_NE(e.message().find("icon "), std::string::npos) << e.message();
  }
}

// What bytes cannot express, encode checks on its own, naming the icon.
TEST(IconPack, encodeRefusesMisshapenPacks) {
  struct Case {
    const char* name;
    std::function<void(Pack&)> change;
    std::string message;
  };
  auto mesh0 = [](Pack& p) -> Mesh& { return p.icons[0].parts[0].meshes[0]; };
  const std::vector<Case> cases = {
      {"positions not 3 per vertex", [&](Pack& p) { mesh0(p).positions.push_back(0); },
       "icons.pack: icon 0 'box', part 0, mesh 0 has 10 position values, not 3 per vertex"},
      {"no vertices",
       [&](Pack& p) {
         mesh0(p).positions.clear();
         mesh0(p).normals.clear();
       },
       "icons.pack: icon 0 'box', part 0, mesh 0 vertex count 0 is out of range (1 to 16777216)"},
      {"normals", [&](Pack& p) { mesh0(p).normals.pop_back(); },
       "icons.pack: icon 0 'box', part 0, mesh 0 has 8 normal values for 3 vertices (needs 9)"},
      {"texcoords", [&](Pack& p) { mesh0(p).texcoords.pop_back(); },
       "icons.pack: icon 0 'box', part 0, mesh 0 has 5 texcoord values for 3 vertices (needs 0 or 6)"},
      {"levels", [&](Pack& p) { mesh0(p).levels.pop_back(); },
       "icons.pack: icon 0 'box', part 0, mesh 0 has 1 index lists for the icon's 2 levels"},
      {"no material", [](Pack& p) { p.icons[0].materials.clear(); },
       "icons.pack: icon 0 'box' material count 0 is out of range (1 to 65535)"},
      {"no level", [](Pack& p) { p.icons[0].ranges.clear(); },
       "icons.pack: icon 0 'box' level count 0 is out of range (1 to 8)"},
      {"no part", [](Pack& p) { p.icons[0].parts.clear(); },
       "icons.pack: icon 0 'box' part count 0 is out of range (1 to 256)"},
      {"long name", [](Pack& p) { p.icons[0].name.assign(256, 'x'); },
       "icons.pack: icon 0 name is 256 bytes, more than 255"},
      {"long part name", [](Pack& p) { p.icons[0].parts[0].name.assign(70000, 'x'); },
       "icons.pack: icon 0 'box', part 0 name is 70000 bytes, more than 255"},
      {"texture name", [](Pack& p) { p.textures[0].name = "a\tb"; },
       "icons.pack: texture 0 name has control byte 0x09 at byte 1; names are printable text"},
      {"too many DIS patterns", [](Pack& p) { p.icons[0].dis.resize(65); },
       "icons.pack: icon 0 'box' DIS pattern count 65 is out of range (0 to 64)"},
      {"too many icons", [](Pack& p) { p.icons.resize(65536); },
       "icons.pack: icon count 65536 is out of range (0 to 65535)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    Pack p = goldenPack();
    c.change(p);
    auto e = encode(p);
    ASSERT_FALSE(e.ok());
    EXPECT_EQ(e.message(), c.message);
    EXPECT_EQ(e.problems().front().file, "");
  }
}

}  // namespace
}  // namespace sandtable::iconpack
