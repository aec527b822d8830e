#pragma once
// The icon database (icons.pack), version 2 (seed V.E, Figure 19): every
// icon a database places, with its states (alive, dead), its articulated
// components, its materials and textures, and its levels of detail as
// index lists over one vertex set per mesh. Written by the build, listed in
// the manifest, read by validate, info and the viewer. Byte layout:
// docs/FORMAT.md §12. All integers and floats little-endian. Version 2
// stores DIS entity-type patterns (with wildcards) where version 1 stored one
// exact type; decode reads both, encode writes version 2.
//
// Thread safety: encode and decode are reentrant; a Pack is a value type.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::iconpack {

inline constexpr const char* kFileName = "icons.pack";
inline constexpr std::array<char, 8> kMagic{'S', 'T', 'I', 'C', 'O', 'N', 'S', '\0'};
inline constexpr std::uint32_t kVersion = 2;
/// The oldest version decode still reads (one exact DIS type per icon).
inline constexpr std::uint32_t kOldestVersion = 1;
inline constexpr std::size_t kHeaderBytes = 40;
/// Largest icons.pack readFile accepts (textures are embedded).
inline constexpr std::uint64_t kMaxFileBytes = 1ull << 30;
/// Limits decode enforces before it allocates anything.
inline constexpr std::uint32_t kMaxIcons = 65535;
inline constexpr std::uint32_t kMaxLevels = 8;
inline constexpr std::uint32_t kMaxNameBytes = 255;
/// DIS patterns per icon (`dis` lines): a model stands for a few types.
inline constexpr std::uint32_t kMaxDisPatterns = 64;
/// Material::texture when the material has none.
inline constexpr std::uint32_t kNoTexture = 0xFFFFFFFFu;
/// Part::parent of a part attached to the icon's own frame.
inline constexpr std::int32_t kBody = -1;

/// An image file embedded whole (PNG or JPEG bytes as the model had them).
struct Texture {
  std::string name;               ///< as the model named it, for messages
  std::vector<std::byte> bytes;
  bool operator==(const Texture&) const = default;
};

struct Material {
  std::array<std::uint8_t, 4> rgba{255, 255, 255, 255};  ///< base colour as the model gives it, 8 bits a channel
  std::uint32_t texture = kNoTexture;                     ///< index into Pack::textures
  bool operator==(const Material&) const = default;
};

/// One mesh of one part: a vertex set, and per level of detail the
/// triangles kept (three indices each into the vertex set).
struct Mesh {
  std::uint32_t material = 0;          ///< index into Icon::materials
  std::vector<float> positions;        ///< x, y, z per vertex, metres, Y up, in the part's frame
  std::vector<float> normals;          ///< x, y, z per vertex
  std::vector<float> texcoords;        ///< s, t per vertex, or empty
  std::vector<std::vector<std::uint32_t>> levels;  ///< one index list per Icon::ranges entry
  std::size_t vertexCount() const { return positions.size() / 3; }
  bool operator==(const Mesh&) const = default;
};

enum class State : std::uint8_t { alive = 0, dead = 1 };

/// A rigid part: the hull of one state, or an articulated component (a
/// turret) whose frame sits at `offset` in its parent's frame; the
/// articulation point is the origin of that frame (seed Figure 19, F lines).
struct Part {
  std::string name;                    ///< "" for a state's hull
  State state = State::alive;
  std::int32_t parent = kBody;         ///< kBody, or the index of an earlier part
  std::array<float, 3> offset{0, 0, 0};
  std::vector<Mesh> meshes;
  bool operator==(const Part&) const = default;
};

/// DIS entity type (IEEE 1278.1 6.2.30): kind.domain.country.category.
/// subcategory.specific.extra.
struct DisType {
  std::uint8_t kind = 0, domain = 0;
  std::uint16_t country = 0;
  std::uint8_t category = 0, subcategory = 0, specific = 0, extra = 0;
  bool operator==(const DisType&) const = default;
};

/// The seven fields of a DisType in their order, numbered as the bits of
/// DisPattern::wild: kind is bit 0, extra bit 6.
enum class DisField : std::uint8_t { kind, domain, country, category, subcategory, specific, extra };
inline constexpr std::size_t kDisFields = 7;
inline constexpr std::uint8_t kDisAllWild = 0x7F;

/// A `dis` line of the definition file: a DIS type whose fields with their
/// bit set in `wild` match any value (docs/ICONS.md §3). A wildcard field
/// stores 0, so each pattern has one form.
struct DisPattern {
  DisType type;
  std::uint8_t wild = 0;
  bool operator==(const DisPattern&) const = default;
};

struct Icon {
  std::string name;
  bool armed = false;
  bool resupply = false;
  /// The DIS types this icon stands for (at most kMaxDisPatterns); the
  /// matcher (dis_icons.h) picks the best icon for a type.
  std::vector<DisPattern> dis;
  std::array<float, 6> bounds{0, 0, 0, 0, 0, 0};  ///< min x, y, z, max x, y, z of the alive state
  float cylinderRadius = 0;           ///< about the Y axis through the origin
  float cylinderHeight = 0;           ///< from y = 0 up
  std::vector<Material> materials;
  /// Far switch range of each level in metres: level i is drawn from
  /// ranges[i-1] (0 for level 0) up to ranges[i]; beyond the last, nothing.
  std::vector<float> ranges;
  std::vector<Part> parts;            ///< at least one alive hull (name "")
  bool operator==(const Icon&) const = default;
};

struct Pack {
  std::vector<Texture> textures;
  std::vector<Icon> icons;
  bool operator==(const Pack&) const = default;
};

/// Field k (DisField order: 0 kind ... 6 extra) of a type, and its name.
std::uint32_t disField(const DisType& t, std::size_t k);
const char* disFieldName(std::size_t k);

/// The origin of part `part`'s frame in the icon's body frame: its offsets
/// summed up the parent chain (a static object never turns its turret).
std::array<float, 3> partOrigin(const Icon& icon, std::size_t part);

/// Triangles of `icon` at `level`, summed over every part of `state`.
std::uint64_t triangleCount(const Icon& icon, std::size_t level, State state = State::alive);

/// The whole file, in version kVersion. Fails (naming the icon and the field) when the pack
/// breaks a rule decode would reject, so a written pack always reads back.
Result<std::vector<std::byte>> encode(const Pack& p);

/// Parses and checks every byte: magic, version (1 or 2), both CRCs, every count
/// against the bytes left before allocating, indices inside their vertex
/// set, material, texture and parent references, finite floats. Every
/// problem names `file` and the byte offset where it was found.
Result<Pack> decode(std::span<const std::byte> bytes, const std::string& file);

/// readSmallFile(path, kMaxFileBytes), then decode.
Result<Pack> readFile(const std::string& path);

/// encode, then writeFileAtomic.
Status writeFile(const std::string& path, const Pack& p);

}  // namespace sandtable::iconpack
