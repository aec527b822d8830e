#pragma once
// A load module, version 1 (docs/FORMAT.md, "module"): one square of the
// database (seed chapter V.H: 1 km by default) holding, for each level of
// detail, everything the renderer and simulator need with no further
// computation: vertices, triangle indices grouped by grid square and
// priority (seed Figure 29's count and index arrays), material ids, texture
// coordinates, the highest vertex of each grid square, and skirts that hide
// cracks between modules and between levels.
//
// Frames. Vertex positions are module-local: x east and z south of the
// module's north-west corner, y up (metres above the vertical datum). The
// module's north-west corner lies at world X = kx * edge, Z = kz * edge,
// where edge = squares * spacing (manifest `module_size_m`).
//
// Grid triangles (seed Figures 14, 15). Every grid square is split along
// its SW-NE diagonal into the upper triangle (NW, NE, SW corners; the half
// that holds the NW corner) and the lower triangle (NE, SE, SW corners).
// This is the same diagonal the runtime sampler interpolates on.
//
// Levels. Level 0 is the finest and uses the grid spacing; level l uses
// posts every 2^l grid posts. A level's lattice is indexed by post columns
// and rows of the grid, clamped at the database's east and south edges, so
// a module at the edge may have narrower last squares at coarse levels.
#include <array>
#include <cstddef>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::module {

inline constexpr std::array<char, 8> kMagic = {'S', 'A', 'N', 'D', 'M', 'O', 'D', '1'};
inline constexpr std::uint32_t kVersion = 1;
/// Version 2 (docs/FORMAT.md §9.7): the same 48-byte module header with
/// this magic and version 2; levels in the layout of "version 2" below.
inline constexpr std::array<char, 8> kMagic2 = {'S', 'A', 'N', 'D', 'M', 'O', 'D', '2'};
inline constexpr std::uint32_t kVersion2 = 2;
/// Version 3 (docs/FORMAT.md §9.8): version 2 with a 112-byte level header
/// whose skirts and heights follow from the lattice (flags below).
inline constexpr std::array<char, 8> kMagic3 = {'S', 'A', 'N', 'D', 'M', 'O', 'D', '3'};
inline constexpr std::uint32_t kVersion3 = 3;
/// Version 4 (docs/FORMAT.md §9.9): version 3 with a 124-byte level header;
/// quantised culture heights are offsets from the lattice plane, and decal
/// texture coordinates are stored as integers (flags below).
inline constexpr std::array<char, 8> kMagic4 = {'S', 'A', 'N', 'D', 'M', 'O', 'D', '4'};
inline constexpr std::uint32_t kVersion4 = 4;
/// Version 5 (docs/FORMAT.md §9.10): version 4's levels followed by the
/// static objects section (below): icon instances with an elevation on
/// every level of detail (seed chapter V.F, obslocstruct yloc[], Figure 87).
inline constexpr std::array<char, 8> kMagic5 = {'S', 'A', 'N', 'D', 'M', 'O', 'D', '5'};
inline constexpr std::uint32_t kVersion5 = 5;
/// Version 6 (docs/FORMAT.md §9.11): version 5 with objects as rules: the
/// scatter rules that regenerate the module's trees, their exceptions, and
/// the explicit objects in a compact encoding; no stored elevations.
inline constexpr std::array<char, 8> kMagic6 = {'S', 'A', 'N', 'D', 'M', 'O', 'D', '6'};
inline constexpr std::uint32_t kVersion6 = 6;
/// The version writers produce by default.
inline constexpr std::uint32_t kNewestVersion = kVersion6;
/// Default height quantisation step of version 2, metres (1 cm).
inline constexpr double kDefaultHeightStep = 0.01;

// ------------------------------------------------------------------ layout
// Shared by encode, decode, the tests and docs (docs/FORMAT.md, "module").
// A module is a 48-byte header followed by its levels, finest first. Each
// level is a 36-byte level header followed by its arrays, as planes:
//
//   x, y, z, s, t       f32[vertexCount] each
//   maxHeight           f32[squaresX * squaresZ]
//   indices             u16[indexCount] (u32 with kLevelFlagU32Indices), delta-coded
//   group square        u32[groupCount], delta-coded
//   group half          u8[groupCount]
//   group priority      u8[groupCount]
//   group material      u16[groupCount]
//   group indexCount    u32[groupCount]
//
// Every plane of n values of w > 1 bytes is byte-shuffled: stored as w
// byte planes of n bytes, byte 0 (least significant) of every value, then
// byte 1, and so on. A delta-coded plane stores zigzag(v[k] - v[k-1]) with
// v[-1] = 0, the difference taken modulo 2^(8w) as a signed w-byte value and
// zigzag(d) = (d << 1) ^ (d >> (8w - 1)). Group firstIndex is not stored:
// it is the running sum of indexCount. This layout makes zstd level 9
// output about 40% smaller than plain arrays (docs/FORMAT.md, "module").

inline constexpr std::uint32_t kHeaderBytes = 48;
inline constexpr std::uint32_t kLevelHeaderBytes = 36;
inline constexpr std::uint32_t kMaxLevels = 16;
inline constexpr std::uint32_t kMaxSquaresPerAxis = 65536;
/// Writers use u16 indices when a level has at most this many vertices.
inline constexpr std::uint32_t kMaxU16Vertices = 65536;
/// Level flag bit 0: indices are stored as u32 (else u16).
inline constexpr std::uint32_t kLevelFlagU32Indices = 1;
inline constexpr std::uint32_t kVertexBytes = 5 * 4;  ///< x, y, z, s, t
inline constexpr std::uint32_t kGroupBytes = 4 + 1 + 1 + 2 + 4;

/// Byte offsets of the module header fields.
namespace field {
inline constexpr std::size_t magic = 0, version = 8, headerBytes = 12, kx = 16, kz = 20,
                             levelCount = 24, flags = 28, totalBytes = 32, payloadCrc = 40,
                             headerCrc = 44;
}
static_assert(field::headerCrc + 4 == kHeaderBytes, "module header layout");

/// Byte offsets of the level header fields, from the start of the level.
namespace levelField {
inline constexpr std::size_t spacing = 0, squaresX = 8, squaresZ = 12, skirtDepth = 16, flags = 20,
                             vertexCount = 24, indexCount = 28, groupCount = 32;
}
static_assert(levelField::groupCount + 4 == kLevelHeaderBytes, "level header layout");
static_assert(kVertexBytes == 20 && kGroupBytes == 12, "plane widths");

// ------------------------------------------------------- layout, version 2
// Version 2 stores what the grid implies, not what it repeats (issue 11;
// docs/FORMAT.md §9.7 byte by byte). A level is a 104-byte level header and
//
//   lattice heights   u32[P] shuffled: zigzag residual of the parallelogram
//                     predictor over the (X+1) x (Z+1) posts (flag lattice)
//   lattice normals   u16[P] u, then u16[P] v, shuffled, same predictor,
//                     values >> normalShift (flags lattice and normals)
//   maxHeight         f32[S] shuffled (absent with flag derivedMaxHeight)
//   vertex stream     meshopt_encodeVertexBuffer of the E = V - P other
//                     vertices: u32 x bits, y code, z bits, s bits, t bits
//                     [, normal] (24 bytes with normals, else 20)
//   index stream      meshopt_encodeIndexSequence of the I indices
//   group runs        LEB128 runs (below)
//
// Lattice vertices are vertices 0 .. P-1, the posts row-major, as the
// builder writes them: their x, z, s, t follow from spacing, lastX/lastZ
// and skinS0/skinT0 in the level header; only y (and the normal) is stored.
// The encoder uses the lattice only when every one of those values comes
// back bit for bit, so x, z, s and t are lossless in every case.
// Heights: y code q - heightBase with q = round(y / heightStep) (signed,
// on the whole database's 1 cm lattice, so neighbours decode the same
// edge heights); decoded y = float(double(heightBase + code) * step), at
// most step / 2 + half a float ulp of |y| from the original. A level with
// a non-finite y (or too wide a range) stores float bits (flag exact).
// maxHeight is recomputed from the decoded vertices where it was the
// highest skin and decal vertex of each square (flag derivedMaxHeight).
// Group runs: consecutive groups with one priority, material and index
// count whose squares step (sq, upper) -> (sq, lower) -> (sq+1, upper), or
// (sq, skirt) -> (sq+1, skirt), are one run.

inline constexpr std::uint32_t kLevelHeaderBytes2 = 104;
inline constexpr std::uint32_t kLevel2Lattice = 1;           ///< vertices 0..P-1 are the lattice posts
inline constexpr std::uint32_t kLevel2DerivedMaxHeight = 2;  ///< maxHeight is not stored
inline constexpr std::uint32_t kLevel2Normals = 4;           ///< Level::normals are stored
inline constexpr std::uint32_t kLevel2ExactHeights = 8;      ///< y codes are float bits
inline constexpr std::uint32_t kLevel2KnownFlags = 15;

// ------------------------------------------------------- layout, version 3
// Version 3 is version 2 with twelve more level header bytes (skirt node,
// material, stream index count) and three more rules, all lossless and checked bit for bit by the
// encoder, which leaves a flag clear wherever its rule does not reproduce
// the level exactly:
//  - implicit skirts: the skirt groups, their indices and their bottom
//    vertices are what meshing::addSkirts makes from the lattice (one group
//    per node of skirtNode squares, sides north, south, west, east, bottom
//    vertices y - skirtDepth with s = t = 0, appended after the others);
//    none of them is stored;
//  - plane heights: the y code of every other vertex is stored as the
//    difference from the code of the lattice triangle's plane at its x, z;
//  - lattice runs (no flag: bit 0 of a run's length field): a run of
//    groups that are each one grid triangle of the lattice, (NW, SW, NE)
//    upper or (NE, SW, SE) lower, stores no indices.
// streamIndices counts the indices the index stream holds.
inline constexpr std::uint32_t kLevelHeaderBytes3 = 116;
inline constexpr std::uint32_t kLevel3ImplicitSkirts = 16;
inline constexpr std::uint32_t kLevel3PlaneHeights = 32;
inline constexpr std::uint32_t kLevel3KnownFlags = 63;
namespace levelField3 {
inline constexpr std::size_t skirtNode = 104, skirtMaterial = 108, reserved = 110, streamIndices = 112;
}
static_assert(levelField3::streamIndices + 4 == kLevelHeaderBytes3, "version 3 level header layout");

// ------------------------------------------------------- layout, version 4
// Version 4 is version 3 with eight more level header bytes and two rules:
//  - plane offsets (flag): with quantised heights, the y of every stream
//    vertex is the lattice plane's height at its x, z plus a whole number
//    of steps, so a culture vertex on a grid edge stays on the edge the
//    lattice triangle beside it draws (version 3 re-quantised it);
//  - raw texture: the last rawTextureVertices stream vertices (the
//    builder's decals) store s and t as integers n, s = n * 2^stExponent
//    (32767: their float bits), not XOR the skin texture.
inline constexpr std::uint32_t kLevelHeaderBytes4 = 124;
inline constexpr std::uint32_t kLevel4PlaneOffsets = 64;
inline constexpr std::uint32_t kLevel4KnownFlags = 127;
namespace levelField4 {
inline constexpr std::size_t rawTextureVertices = 116, stExponent = 120, reserved = 122;
}
static_assert(levelField4::reserved + 2 == kLevelHeaderBytes4, "version 4 level header layout");

/// Byte offsets of the version 2 level header fields, from the level's start.
namespace levelField2 {
inline constexpr std::size_t spacing = 0, squaresX = 8, squaresZ = 12, skirtDepth = 16, flags = 20,
                             vertexCount = 24, indexCount = 28, groupCount = 32, runCount = 36,
                             heightStep = 40, heightBase = 48, lastX = 56, lastZ = 64, skinS0 = 72,
                             skinT0 = 80, normalShift = 88, vertexStreamBytes = 92,
                             indexStreamBytes = 96, runBytes = 100;
}
static_assert(levelField2::runBytes + 4 == kLevelHeaderBytes2, "version 2 level header layout");
/// A meshopt vertex stream never expands more than this (v0 codec: 2 header
/// bits per 16 bytes of one byte lane); decode refuses larger claims.
inline constexpr std::uint64_t kMaxVertexStreamExpansion = 64;

// ------------------------------------------------------- layout, version 5
// After the last level, the objects section:
//
//   objectCount  u32 n
//   icon         u16[n]   index into icons.pack
//   class        u16[n]   material class that placed it (kObjectClassExplicit: a points file)
//   x, z         f32[n]   module-local metres, as vertices
//   heading      u16[n]   clockwise from north (-z), code * 2 pi / 65536
//   scale        f32[n]   > 0, times the icon's size
//   radius       f32[n]   bounding cylinder, scaled, metres, >= 0
//   height       f32[n]
//   y            f32[n] per level, finest first: the base on that level's
//                triangles at (x, z)
//
// every plane of width > 1 byte-shuffled like the others. A record of the
// pack's split layout is a module of its own levels: each record carries
// the whole objects list with the elevations of its levels.
inline constexpr std::uint32_t kObjectBytes = 2 + 2 + 4 + 4 + 2 + 4 + 4 + 4;  ///< before the y planes
/// Object::cls of a points file's objects; 0xff00 + k: the material table's
/// k-th `place` line; below 0xff00: the area class a `scatter` line filled.
inline constexpr std::uint16_t kObjectClassExplicit = 0xffff;
inline constexpr std::uint16_t kObjectClassPlace = 0xff00;
inline constexpr std::uint32_t kMaxPlaceLines = 0xff;
/// A module holds at most this many objects (decode refuses more).
inline constexpr std::uint32_t kMaxObjects = 1u << 20;
static_assert(kObjectBytes == 26, "object plane widths");

// ------------------------------------------------------- layout, version 6
// After the last level, the objects section of docs/FORMAT.md §9.11: a
// 48-byte header, the explicit objects' palette, the scatter rules (each a
// 56-byte record and its list), and the explicit objects' planes. A rule
// either regenerates its trees on the record's first level (mode 0, its
// list the candidates to drop) or lists the candidates it keeps (mode 1, a
// bitmap: a coarse record has no level 0 to regenerate on).
inline constexpr std::uint8_t kRuleRegenerate = 0;
inline constexpr std::uint8_t kRuleBitmap = 1;

/// Which part of a grid square a group of triangles belongs to.
enum class Half : std::uint8_t {
  upper = 0,  ///< NW, NE, SW corners
  lower = 1,  ///< NE, SE, SW corners
  skirt = 2,  ///< vertical seam skirt along a module edge (not in a grid triangle)
};

/// Draw priorities (seed Figure 18).
inline constexpr std::uint8_t kPrioritySkin = 1;
inline constexpr std::uint8_t kPriorityRoad = 10;
inline constexpr std::uint8_t kPriorityObject = 99;

struct Vertex {
  float x = 0, y = 0, z = 0;  ///< module-local metres (x east, y up, z south)
  float s = 0, t = 0;         ///< texture coordinates (roads: S along, T across, seed Figure 17); rules below
};

// Texture coordinates (docs/FORMAT.md §9.6; checked by validate):
//  - skin (priority 1): the texture repeats every kSkinTextureRepeat metres
//    of the database, s = (S0 + x) / repeat and t = (T0 + z) / repeat, where
//    S0, T0 are skinTextureOffset() of the module's north-west corner (grid
//    post i0 = kx * moduleSquares, j0 likewise) in metres from the grid's
//    origin: the same world point has the same s, t in every module and
//    level, and the float32 values stay small;
//  - decals (priority 2..98, line classes): s = metres along the nearest
//    centreline / the line's width, >= 0; t across it, 0 at the left edge
//    (as the line runs, seen from above) to 1 at the right, in [0, 1];
//  - skirts and objects: any finite values.
inline constexpr double kSkinTextureRepeat = 64.0;
inline constexpr double kSkinTextureWrap = 4096.0;  ///< a multiple of the repeat
/// (metres from the grid origin to the module's NW corner) mod kSkinTextureWrap.
inline double skinTextureOffset(double metres) {
  return metres - kSkinTextureWrap * std::floor(metres / kSkinTextureWrap);
}

/// One run of triangles with one material, priority and grid triangle.
struct Group {
  std::uint32_t square = 0;      ///< row-major square index in the level: sz * squaresX + sx
  Half half = Half::upper;
  std::uint8_t priority = kPrioritySkin;
  std::uint16_t material = 0;    ///< class id from the material table
  std::uint32_t firstIndex = 0;  ///< into Level::indices
  std::uint32_t indexCount = 0;  ///< a multiple of 3 (triangle list)
};

struct Level {
  double spacing = 0;               ///< nominal post spacing of this level, metres
  std::uint32_t squaresX = 0;       ///< squares across (may be fewer at the east edge)
  std::uint32_t squaresZ = 0;
  std::vector<Vertex> vertices;
  std::vector<std::uint32_t> indices;
  /// Sorted by (priority, square, half, material): draw in order for
  /// priority order (skin first, roads last).
  std::vector<Group> groups;
  /// Highest vertex y in each square (skin and decals), row-major.
  std::vector<float> maxHeight;
  float skirtDepth = 0;  ///< how far skirts hang below the edge vertices, metres
  /// Per vertex, octahedral unit normal (octEncode): empty = absent (always
  /// so from version 1, which has no place for them).
  std::vector<std::uint32_t> normals;
  /// Height quantisation step the level was decoded with, metres: every y
  /// is within heightStep / 2 (plus half a float ulp) of what was encoded.
  /// 0 = exact (version 1, or a version 2 level stored exact). Not encoded
  /// from here: encode takes EncodeOptions::heightStep.
  double heightStep = 0;
  /// Version 5: the base elevation of each of Module::objects on this
  /// level's triangles, metres (same size as Module::objects).
  std::vector<float> objectY;
};

/// Octahedral normal (seed: none; Cigolle et al. 2014), folded about y (up):
/// u = x / (|x|+|y|+|z|), v = z / (...), reflected for y < 0; each as snorm16
/// (round(c * 32767)), u in bits 0..15, v in bits 16..31. An upward normal
/// is 0. The input need not be unit length; (0,0,0) encodes as up.
std::uint32_t octEncode(float x, float y, float z);
/// Inverse of octEncode, unit length (x, y, z).
std::array<float, 3> octDecode(std::uint32_t packed);

/// A static object standing on the terrain (version 5): one instance of an
/// icon. Its base elevation on each level is Level::objectY[k].
struct Object {
  std::uint16_t icon = 0;                         ///< index into icons.pack
  std::uint16_t cls = kObjectClassExplicit;       ///< material class that placed it
  float x = 0, z = 0;                             ///< module-local metres
  std::uint16_t heading = 0;                      ///< clockwise from north, 65536 per turn
  float scale = 1;                                ///< times the icon's size
  float radius = 0, height = 0;                   ///< bounding cylinder, scaled
  /// Stable name (version 6; docs/FORMAT.md §9.11): a scattered tree's is
  /// scatteredId(rule, i, j) (bit 63 set), an explicit object's is its rank
  /// in the module's explicit list. Version 5 decodes give the list index.
  std::uint64_t id = 0;
};

/// One scatter rule as a module stores it (version 6): everything that
/// regenerates its trees from the level-0 skin (scatter.h).
struct ScatterRule {
  std::uint16_t icon = 0;
  std::uint16_t classId = 0;  ///< area class scattered over (Object::cls of its trees)
  std::uint16_t index = 0;    ///< the rule's number in the build's scatter list: in every key and id, <= 0x7fff
  double cell = 10;           ///< jitter cell edge, metres, world-anchored
  std::uint64_t seed = 1;
  double scaleMin = 1, scaleMax = 1;  ///< materials::Variation
  float radius = 0, height = 0;       ///< the icon's bounding cylinder at scale 1
  bool operator==(const ScatterRule&) const = default;
};

/// The rules of a module and the rectangle they fill: the module's
/// north-west corner in the database frame and the extent in which a
/// candidate is the module's (0 <= x < width, 0 <= z < depth).
struct Scattering {
  double x0 = 0, z0 = 0;
  double width = 0, depth = 0;
  std::vector<ScatterRule> rules;
  bool operator==(const Scattering&) const = default;
};

/// Bit 63 of Object::id: a scattered tree; bits 48..62 the rule's index,
/// 24..47 the cell column i and 0..23 the row j (two's complement, 24 bits).
inline constexpr std::uint64_t kScatteredId = 1ull << 63;
inline constexpr std::int64_t kMaxCellIndex = (1 << 23) - 1;  ///< |i|, |j| of an id, and -kMaxCellIndex - 1
inline constexpr std::uint64_t scatteredId(std::uint16_t rule, std::int64_t i, std::int64_t j) {
  return kScatteredId | std::uint64_t(rule & 0x7fff) << 48 | (std::uint64_t(i) & 0xffffff) << 24 |
         (std::uint64_t(j) & 0xffffff);
}
inline constexpr bool isScattered(std::uint64_t id) { return (id & kScatteredId) != 0; }
inline constexpr std::uint16_t idRule(std::uint64_t id) { return std::uint16_t(id >> 48 & 0x7fff); }
inline constexpr std::int64_t idCellI(std::uint64_t id) { return std::int64_t((id >> 24 & 0xffffff) ^ 0x800000) - 0x800000; }
inline constexpr std::int64_t idCellJ(std::uint64_t id) { return std::int64_t((id & 0xffffff) ^ 0x800000) - 0x800000; }

/// Heading in radians of an Object::heading code.
inline double headingRadians(std::uint16_t code) { return double(code) * (6.283185307179586 / 65536.0); }
/// Nearest heading code of an angle in radians (any value; wraps).
inline std::uint16_t headingCode(double radians) {
  const double turns = radians / 6.283185307179586;
  return static_cast<std::uint16_t>(std::llround((turns - std::floor(turns)) * 65536.0) & 0xffff);
}

struct Module {
  std::uint32_t kx = 0;  ///< column of the module, from the west edge
  std::uint32_t kz = 0;  ///< row of the module, from the north edge
  std::vector<Level> levels;  ///< [0] is the finest
  /// Static objects (version 5; empty from older versions): each level's
  /// objectY has one elevation per object.
  std::vector<Object> objects;
  /// Version 6: the rules whose trees are among `objects` (empty rules: the
  /// objects are all explicit). Decode fills it; encode to version 6 stores
  /// a rule for the objects it reproduces bit for bit, the rest explicit.
  Scattering scattering = {};
};

/// The tallest object of every level-0 grid square of `level`, row-major
/// (squaresX * squaresZ): the index of the object whose top
/// (objectY + height) is highest among those whose (x, z) lies in the
/// square, or kNoObject. The first level of the entity issue's collision
/// test; derived from the objects, not stored (docs/FORMAT.md §9.10).
inline constexpr std::uint32_t kNoObject = 0xffffffffu;
std::vector<std::uint32_t> tallestObjects(const Module& m, std::size_t level);

/// What encode needs and the bytes cannot say: 1 to 16 levels, squares
/// counts 1..65536, maxHeight sized squaresX * squaresZ, and every group's
/// firstIndex equal to the sum of the indexCounts before it (the groups
/// cover Level::indices contiguously, in order). Fails with the first
/// violation (no file; the message starts "module: "). Everything else
/// (indices below the vertex count, group order, squares in range) is
/// checked by decode.
Status checkEncodable(const Module& m);

/// Exact size of encode(m, {.version = 1}) in bytes, plus version 5's
/// objects section when m has objects; a version 2 to 5 encoding
/// is smaller for every module a builder makes (it is an upper bound used
/// to refuse oversized modules before encoding).
std::uint64_t encodedBytes(const Module& m);

struct EncodeOptions {
  std::uint32_t version = kNewestVersion;  ///< 1 to 6 (objects need 5 or 6; older versions drop them)
  double heightStep = kDefaultHeightStep;  ///< versions 2 to 4; <= 0 stores exact float heights
  /// Version 6: a scatter rule may be stored as "regenerate on the first
  /// level, less these" (small on disk, costly to decode: a skin search per
  /// candidate) when that reproduces its trees; false stores every rule as a
  /// bitmap of its kept candidates (a hash per tree to decode). A pack's
  /// coarse record is written with false: the pager reads it on the hole
  /// path, and its first level is not level 0 anyway (docs/FORMAT.md §9.11).
  bool regenerateRules = true;
};

/// Uncompressed bytes of a module (little-endian, layout above and in
/// docs/FORMAT.md). Deterministic. Asserts checkEncodable(m).ok() in debug
/// builds; in release builds it still writes a well-formed container (a
/// short maxHeight is padded with 0, firstIndex is ignored). Version 1 has
/// no normals (they are dropped); version 2 quantises heights (above).
std::vector<std::byte> encode(const Module& m, const EncodeOptions& options = {});

/// The format version of encoded bytes (1, 2 or 3), from the magic and the
/// version field; 0 when they are neither (decode says why).
std::uint32_t encodedVersion(std::span<const std::byte> bytes);

/// Decodes and checks structure: both CRCs, counts within the bytes, indices
/// within the vertices, groups within the indices and in (priority, square,
/// half, material) order, squares within the level. Never over-allocates:
/// every count is checked against the bytes that remain before anything is
/// sized. Stops at the first problem. Problems name `file` and the offset
/// `baseOffset` + the offset in `bytes`; messages start with "module: ".
/// Group::firstIndex is recomputed as the running sum. Thread-safe.
Result<Module> decode(std::span<const std::byte> bytes, const std::string& file,
                      std::uint64_t baseOffset = 0);

/// decode into `out`, reusing the capacity of its vectors: a reader that
/// decodes module after module into one Module allocates nothing once its
/// vectors have grown to the largest module. On failure returns decode's
/// problem and leaves `out` in an unspecified but valid state.
Status decodeInto(std::span<const std::byte> bytes, const std::string& file, std::uint64_t baseOffset,
                  Module& out);

}  // namespace sandtable::module
