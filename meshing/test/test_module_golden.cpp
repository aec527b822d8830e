// Modules assembled by the terrain rules (lattice, square split, skirts) and
// coded in every module version must not change, byte for byte, nor what
// they decode to. The fingerprints below were recorded by this same code
// built against main at 4837c13, before the rules moved into
// formats/terrain_rule.h; they cover a grid whose east and south modules
// are narrower (short last squares at the coarse levels), culture vertices
// off the lattice (plane heights and offsets in versions 3 and 4) and
// implicit skirts.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <string>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/module.h"
#include "sandtable/meshing/assemble.h"
#include "sandtable/meshing/lattice.h"
#include "sandtable/testing/fixtures.h"

namespace sandtable::meshing {
namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kPostsX = 70, kPostsZ = 45, kSquares = 16;
constexpr int kLevels = 3;

/// Rough, integer-made terrain (no libm, so every machine agrees).
float rough(std::uint32_t i, std::uint32_t j) {
  return float(50.0 + 0.75 * double((i * 37 + j * 91) % 23) + 0.125 * i - 0.0625 * j);
}

std::shared_ptr<const grid::GridFile> roughGrid() {
  const fs::path dir = fs::temp_directory_path() / ("sandtable-module-golden." + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / "grid.stg").string();
  const Status written = fixtures::writeGrid(path, kPostsX, kPostsZ, 10.0, rough);
  EXPECT_TRUE(written.ok()) << written.error();
  auto g = grid::GridFile::open(path);
  EXPECT_TRUE(g.ok()) << g.error();
  fs::remove_all(dir);  // the mapping stays valid
  return g.value();
}

/// The plain grid triangles with the skin texture rule (module.h), and a
/// decal triangle (priority 2) inside the upper half of every third
/// square: off-lattice vertices whose heights the later versions code from
/// the lattice plane. The last decal of a level keeps raw texture
/// coordinates (version 4's raw-texture suffix).
bool skin(const LevelLattice& lat, module::Level& out) {
  plainSkin(lat, 3, out);
  const double s0 = module::skinTextureOffset(lat.moduleX), t0 = module::skinTextureOffset(lat.moduleZ);
  const auto skinS = [&](float x) { return float((s0 + double(x)) / module::kSkinTextureRepeat); };
  const auto skinT = [&](float z) { return float((t0 + double(z)) / module::kSkinTextureRepeat); };
  for (module::Vertex& v : out.vertices) v.s = skinS(v.x), v.t = skinT(v.z);
  const std::size_t sx = lat.xs.size() - 1, sz = lat.zs.size() - 1;
  for (std::size_t square = 0; square < sx * sz; square += 3) {
    const std::size_t a = square % sx, b = square / sx;
    const double x0 = lat.xs[a], x1 = lat.xs[a + 1], z0 = lat.zs[b], z1 = lat.zs[b + 1];
    const float h = lat.heights[b * (sx + 1) + a];
    const bool raw = square + 3 >= sx * sz;
    const auto first = std::uint32_t(out.vertices.size());
    const double f[3][2] = {{0.25, 0.25}, {0.5, 0.25}, {0.25, 0.5}};
    for (int k = 0; k < 3; ++k) {
      const auto x = float(x0 + f[k][0] * (x1 - x0)), z = float(z0 + f[k][1] * (z1 - z0));
      const float y = h + 0.37f * float(k + 1);
      out.vertices.push_back({x, y, z, raw ? 0.125f * float(k) : skinS(x), raw ? 0.5f : skinT(z)});
    }
    module::Group g;
    g.square = std::uint32_t(square);
    g.half = module::Half::upper;
    g.priority = 2;
    g.material = 7;
    g.firstIndex = std::uint32_t(out.indices.size());
    g.indexCount = 3;
    out.indices.insert(out.indices.end(), {first, first + 2, first + 1});
    out.groups.push_back(g);
  }
  return true;
}

void append(std::vector<std::byte>& all, const std::vector<std::byte>& bytes) {
  all.insert(all.end(), bytes.begin(), bytes.end());
}

TEST(ModuleGolden, assembledModulesKeepTheirBytesAndDecodingInEveryVersion) {
  const auto g = roughGrid();
  const std::uint32_t mx = (kPostsX - 2) / kSquares + 1, mz = (kPostsZ - 2) / kSquares + 1;
  ASSERT_EQ(mx, 5u);  // the east module is 5 squares wide
  ASSERT_EQ(mz, 3u);  // the south module 12 squares high
  struct Coding {
    std::uint32_t version;
    double heightStep;
    std::uint32_t bytesCrc, decodedCrc;
  };
  // Recorded at 4837c13 (see above). bytes: CRC-32 of every module's
  // encoding, concatenated in row-major module order; decoded: CRC-32 of
  // every decoded module re-encoded as version 1 (a plain image of each
  // level's vertices, indices, groups and maxHeight).
  const Coding codings[] = {
      {1, 0.01, 0x745e617fu, 0x745e617fu}, {2, 0.01, 0xcf9bb5deu, 0xa65dae8bu},
      {3, 0.01, 0x1b5074a2u, 0x0c2b5554u}, {4, 0.01, 0xfc2b49c2u, 0xd51125bdu},
      {5, 0.01, 0xbec551aau, 0xd51125bdu}, {4, 0.0, 0x7168c467u, 0x745e617fu},
  };
  std::vector<module::Module> modules;
  const grid::GridHeightField field(*g);
  for (std::uint32_t kz = 0; kz < mz; ++kz) {
    for (std::uint32_t kx = 0; kx < mx; ++kx) {
      modules.push_back(assembleModule(field, kSquares, kLevels, kx, kz, 9,
                                       [](int, const LevelLattice& lat, module::Level& out) { return skin(lat, out); }));
      ASSERT_TRUE(module::checkEncodable(modules.back()).ok()) << module::checkEncodable(modules.back()).error();
    }
  }
  for (const Coding& c : codings) {
    std::vector<std::byte> bytes, decoded;
    for (const module::Module& m : modules) {
      const std::vector<std::byte> b = module::encode(m, {.version = c.version, .heightStep = c.heightStep});
      ASSERT_EQ(module::encodedVersion(b), c.version);
      if (c.version >= 3) {  // the rules are in use: lattice, implicit skirts, plane heights
        const auto flags = loadLE<std::uint32_t>(b.data() + module::kHeaderBytes + module::levelField2::flags);
        const std::uint32_t want = module::kLevel2Lattice | module::kLevel3ImplicitSkirts |
                                   module::kLevel3PlaneHeights |
                                   (c.version >= 4 && c.heightStep > 0 ? module::kLevel4PlaneOffsets : 0u);
        EXPECT_EQ(flags & want, want) << "version " << c.version;
      }
      append(bytes, b);
      const Result<module::Module> d = module::decode(b, "golden");
      ASSERT_TRUE(d.ok()) << d.error();
      append(decoded, module::encode(d.value(), {.version = 1}));
    }
    char got[64];
    std::snprintf(got, sizeof got, "{%u, %.2f, 0x%08xu, 0x%08xu}", c.version, c.heightStep, crc32(bytes),
                  crc32(decoded));
    EXPECT_EQ(crc32(bytes), c.bytesCrc) << "version " << c.version << ": now " << got;
    EXPECT_EQ(crc32(decoded), c.decodedCrc) << "version " << c.version << ": now " << got;
  }
}

}  // namespace
}  // namespace sandtable::meshing
