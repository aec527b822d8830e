// The icon database icons.pack, version 2, and the reading of version 1
// (docs/FORMAT.md §12).
//
// Every rule a pack keeps is written once below, as a function of values
// that says what is wrong and where within the field. The decoder applies
// the rules to the bytes as it reads them; the encoder applies the same
// rules to the Pack as it writes it, at the offset the field gets. So what
// encode writes always decodes, and what decode refuses encode refuses with
// the same message and offset (the encoder adds only the checks of shape
// that bytes cannot express, such as normals that do not match positions).
#include "sandtable/formats/icon_pack.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string_view>
#include <unordered_map>

#include "sandtable/formats/bytes.h"

namespace sandtable::iconpack {
namespace {

/// Header field offsets.
namespace field {
constexpr std::size_t magic = 0;
constexpr std::size_t version = 8;
constexpr std::size_t headerBytes = 12;
constexpr std::size_t iconCount = 16;
constexpr std::size_t textureCount = 20;
constexpr std::size_t bodyBytes = 24;
constexpr std::size_t bodyCrc = 32;
constexpr std::size_t headerCrc = 36;
}  // namespace field

constexpr std::uint32_t kMaxMaterials = 65535;
constexpr std::uint32_t kMaxParts = 256;
constexpr std::uint32_t kMaxMeshes = 65535;
constexpr std::uint32_t kMaxVertices = 1u << 24;

constexpr std::uint32_t kIconArmed = 1u << 0;
constexpr std::uint32_t kIconResupply = 1u << 1;
constexpr std::uint32_t kIconHasDisV1 = 1u << 2;  // version 1 only: the icon has its one DIS type
constexpr std::uint32_t kIconFlags = kIconArmed | kIconResupply;
constexpr std::uint32_t kIconFlagsV1 = kIconFlags | kIconHasDisV1;
constexpr std::uint32_t kMeshTexcoords = 1u << 0;

// The smallest encoding of each record, to check a count against the bytes
// left before anything is sized by it.
constexpr std::uint64_t kMinTextureBytes = 2 + 4;                 // empty name, no bytes
constexpr std::uint64_t kMinPartBytes = 2 + 4 + 4 + 12 + 4;       // empty name, no meshes
constexpr std::uint64_t kDisPatternBytes = 1 + 8;  // wildcard mask, then the type
/// An icon of a 1-byte name, no DIS pattern (version 2) or its 8 DIS bytes
/// (version 1), bounds and cylinder, one material, one level, one part.
constexpr std::uint64_t minIconBytes(std::uint32_t version) {
  return (2 + 1) + 4 + (version == 1 ? 8 : 2) + 24 + 8 + 4 + 8 + 4 + 4 + 4 + kMinPartBytes;
}
constexpr std::uint64_t kMaterialBytes = 4 + 4;
constexpr std::uint64_t minMeshBytes(std::uint64_t levels) { return 4 + 4 + 4 + 24 + 4 * levels; }
constexpr std::uint64_t vertexBytes(bool texcoords) { return texcoords ? 32 : 24; }

std::string str(std::uint64_t v) { return std::to_string(v); }

/// Shortest form that reads back exactly ("nan", "inf" as they are).
std::string num(float v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, end) : std::to_string(v);
}

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", v);
  return buf;
}

/// The record a problem is in: "texture 1 'camo.png'", "icon 2 'tree',
/// part 0, mesh 1", or nothing (the pack itself). The name is added once
/// it is read.
struct Where {
  const char* kind = nullptr;  // "texture", "icon" or nullptr
  std::size_t index = 0;
  const std::string* name = nullptr;
  std::optional<std::size_t> part, mesh;

  std::string str() const {
    if (!kind) {
      return "";
    }
    std::string s = std::string(kind) + " " + std::to_string(index);
    if (name) {
      s += " '" + *name + "'";
    }
    if (part) {
      s += ", part " + std::to_string(*part);
    }
    if (mesh) {
      s += ", mesh " + std::to_string(*mesh);
    }
    return s;
  }
};

/// "icons.pack: " + where + " " + why.
std::string message(const Where& w, const std::string& why) {
  const std::string at = w.str();
  return "icons.pack: " + (at.empty() ? why : at + " " + why);
}

// ---------------------------------------------------------------- rules

/// A broken rule: what is wrong, and where from the start of the field
/// (or record) the rule was given.
struct Fault {
  std::string why;
  std::uint64_t at = 0;
};
using Check = std::optional<Fault>;

Check countRule(const char* what, std::uint64_t n, std::uint64_t lo, std::uint64_t hi) {
  if (n >= lo && n <= hi) {
    return {};
  }
  return Fault{std::string(what) + " " + str(n) + " is out of range (" + str(lo) + " to " + str(hi) + ")"};
}

Check nameLengthRule(std::uint64_t n) {
  if (n <= kMaxNameBytes) {
    return {};
  }
  return Fault{"name is " + str(n) + " bytes, more than " + str(kMaxNameBytes)};
}

/// A name as stored (u16 length, bytes): at most kMaxNameBytes printable
/// bytes (0x80 and above are allowed: UTF-8); `required`: not empty.
Check nameRule(std::string_view s, bool required) {
  if (Check c = nameLengthRule(s.size())) {
    return c;
  }
  if (required && s.empty()) {
    return Fault{"name is empty; every icon needs a name"};
  }
  for (std::size_t k = 0; k < s.size(); ++k) {
    const auto c = static_cast<unsigned char>(s[k]);
    if (c < 0x20 || c == 0x7F) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "0x%02X", c);
      return Fault{"name has control byte " + std::string(buf) + " at byte " + str(k) + "; names are printable text",
                   2 + k};
    }
  }
  return {};
}

/// Version 1's one DIS type.
Check disV1Rule(bool hasDis, const DisType& d) {
  if (hasDis || d == DisType{}) {
    return {};
  }
  return Fault{"has DIS type bytes that are not zero but flag bit 2 (has DIS type) is clear; an icon without a "
               "DIS type stores zeros"};
}

/// Offset of each DIS field in a pattern record (after the mask byte).
constexpr std::uint64_t kDisFieldAt[kDisFields] = {1, 2, 3, 5, 6, 7, 8};

/// DIS pattern `d` (the record's first byte, its wildcard mask): bit 7
/// clear, and every wildcard field stored as 0 (one form per pattern).
Check disPatternRule(std::size_t d, const DisPattern& p) {
  if ((p.wild & ~kDisAllWild) != 0) {
    return Fault{"DIS pattern " + str(d) + " wildcard mask 0x" + hex32(p.wild).substr(8) +
                 " has bit 7 set; bits 0 to 6 are kind to extra"};
  }
  for (std::size_t k = 0; k < kDisFields; ++k) {
    const std::uint32_t v = disField(p.type, k);
    if (((p.wild >> k) & 1) != 0 && v != 0) {
      return Fault{"DIS pattern " + str(d) + " " + disFieldName(k) + " is a wildcard but stores " + str(v) +
                       "; a wildcard field stores 0",
                   kDisFieldAt[k]};
    }
  }
  return {};
}

/// The first value of `v` that is not finite; `per` values make an item
/// (3 for a vertex position), named in the message when not 0.
Check finiteRule(const char* what, std::span<const float> v, std::size_t per = 0, const char* item = "vertex") {
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (!std::isfinite(v[k])) {
      return Fault{std::string(what) + "[" + str(k) + "]" +
                       (per ? " (" + std::string(item) + " " + str(k / per) + ")" : std::string()) + " is " +
                       num(v[k]) + "; every value must be finite",
                   4 * k};
    }
  }
  return {};
}

Check boundsRule(const std::array<float, 6>& b) {
  if (Check c = finiteRule("bounds", b)) {
    return c;
  }
  static const char* axis[3] = {"x", "y", "z"};
  for (std::size_t a = 0; a < 3; ++a) {
    if (b[a] > b[a + 3]) {
      return Fault{"bounds min " + std::string(axis[a]) + " (" + num(b[a]) + ") is greater than max " + axis[a] +
                       " (" + num(b[a + 3]) + ")",
                   4 * a};
    }
  }
  return {};
}

Check nonNegativeRule(const char* what, float v) {
  if (std::isfinite(v) && v >= 0) {
    return {};
  }
  return Fault{std::string(what) + " " + num(v) + " is not a finite number >= 0"};
}

/// Material `m`'s texture (the field 4 bytes into the material record).
Check textureRule(std::size_t m, std::uint32_t texture, std::uint64_t textures) {
  if (texture == kNoTexture || texture < textures) {
    return {};
  }
  return Fault{"material " + str(m) + " texture " + str(texture) + " is not below the pack's " + str(textures) +
                   " textures (nor " + str(kNoTexture) + ", no texture)",
               4};
}

Check rangesRule(std::span<const float> r) {
  for (std::size_t k = 0; k < r.size(); ++k) {
    if (!std::isfinite(r[k]) || !(r[k] > 0)) {
      return Fault{"range " + str(k) + " (" + num(r[k]) + ") is not a finite number > 0", 4 * k};
    }
    if (k > 0 && !(r[k] > r[k - 1])) {
      return Fault{"range " + str(k) + " (" + num(r[k]) + ") is not greater than range " + str(k - 1) + " (" +
                       num(r[k - 1]) + "); ranges must increase strictly",
                   4 * k};
    }
  }
  return {};
}

Check stateRule(std::uint8_t s) {
  if (s <= static_cast<std::uint8_t>(State::dead)) {
    return {};
  }
  return Fault{"state " + str(s) + " is not 0 (alive) or 1 (dead)"};
}

/// Part `p`'s parent.
Check parentRule(std::int32_t parent, std::size_t p) {
  if (parent == kBody || (parent >= 0 && static_cast<std::size_t>(parent) < p)) {
    return {};
  }
  return Fault{"parent " + std::to_string(parent) + " is neither -1 (the icon's body) nor an earlier part" +
               (p == 0 ? std::string(" (part 0 has none before it)") : " (0 to " + str(p - 1) + ")")};
}

Check materialRule(std::uint32_t m, std::size_t materials) {
  if (m < materials) {
    return {};
  }
  return Fault{"material " + str(m) + " is not below the icon's " + str(materials) + " materials"};
}

Check indexCountRule(std::size_t level, std::uint64_t n) {
  if (n % 3 == 0) {
    return {};
  }
  return Fault{"level " + str(level) + " index count " + str(n) + " is not a multiple of 3"};
}

/// Level `level`'s indices (the field holding the first of them).
Check indicesRule(std::size_t level, std::span<const std::uint32_t> idx, std::uint64_t vertices) {
  for (std::size_t k = 0; k < idx.size(); ++k) {
    if (idx[k] >= vertices) {
      return Fault{"level " + str(level) + " index " + str(k) + " is " + str(idx[k]) + ", not below the vertex count " +
                       str(vertices),
                   4 * k};
    }
  }
  return {};
}

Check hullRule(const std::vector<Part>& parts) {
  for (const Part& p : parts) {
    if (p.state == State::alive && p.parent == kBody && p.name.empty()) {
      return {};
    }
  }
  return Fault{"has no alive hull: one part must have state alive (0), parent -1 and an empty name"};
}

Check duplicateRule(const std::string& name, std::size_t first) {
  return Fault{"name '" + name + "' is already used by icon " + str(first) + "; give every icon its own name"};
}

// ---------------------------------------------------------------- decode

/// Reads a whole pack; stops at the first problem.
class Decoder {
 public:
  Decoder(std::span<const std::byte> bytes, const std::string& file) : b_(bytes), file_(file) {}

  Result<Pack> run() {
    Pack pack;
    if (!header() || !body(pack)) {
      return *problem_;
    }
    return pack;
  }

 private:
  bool fail(std::uint64_t at, std::string msg) {
    problem_ = Problem{file_, at, std::move(msg)};
    return false;
  }

  /// Fails with the rule's problem, at `fieldAt` plus the fault's place.
  bool check(std::uint64_t fieldAt, const Check& c) { return !c || fail(fieldAt + c->at, message(where_, c->why)); }

  std::uint64_t left() const { return b_.size() - pos_; }

  std::string truncatedIn(const char* what) const {
    const std::string at = where_.str();
    return "icons.pack: truncated in " + (at.empty() ? std::string() : at + " ") + what + ": ";
  }

  /// `n` more bytes for `what`, or a truncation problem at the position.
  bool need(std::uint64_t n, const char* what) {
    if (n <= left()) {
      return true;
    }
    return fail(pos_, truncatedIn(what) + "needs " + str(n) + " bytes, the body has " + str(left()) + " left");
  }

  /// `count` records of at least (or, `exact`, exactly) `each` bytes fit in
  /// the bytes left, checked before anything is sized by `count`; the
  /// problem is at the count's field, `countAt`. `of` says what the bytes
  /// hold when `what` does not.
  bool fits(std::uint64_t countAt, std::uint64_t count, std::uint64_t each, const char* what, const char* countName,
            bool exact = false, const char* of = nullptr) {
    const std::uint64_t n = count * each;  // count < 2^32, each < 2^32: no overflow
    if (n <= left()) {
      return true;
    }
    return fail(countAt, truncatedIn(what) + countName + " " + str(count) + " needs " + (exact ? "" : "at least ") +
                             str(n) + " bytes" + (of ? std::string(" of ") + of : std::string()) + ", the body has " +
                             str(left()) + " left");
  }

  /// A byte count read at `countAt` fits in the bytes left.
  bool fitsBytes(std::uint64_t countAt, std::uint64_t n, const char* what) {
    if (n <= left()) {
      return true;
    }
    return fail(countAt, truncatedIn(what) + "needs " + str(n) + " bytes, the body has " + str(left()) + " left");
  }

  template <typename T>
  T take() {
    const T v = loadLE<T>(b_.data() + pos_);
    pos_ += sizeof(T);
    return v;
  }

  template <typename T>
  bool read(T& v, const char* what) {
    if (!need(sizeof(T), what)) {
      return false;
    }
    v = take<T>();
    return true;
  }

  /// `n` floats (checked to fit) into `v`.
  void takeFloats(std::vector<float>& v, std::size_t n) {
    v.resize(n);
    std::memcpy(v.data(), b_.data() + pos_, 4 * n);
    pos_ += 4 * n;
  }

  /// A string field; `at` is set to its offset, `view` to its bytes in the input.
  bool readString(std::string& out, bool required, const char* what, std::uint64_t& at, std::string_view& view) {
    at = pos_;
    std::uint16_t n = 0;
    if (!read(n, what) || !check(at, nameLengthRule(n)) || !fitsBytes(at, n, what)) {
      return false;
    }
    view = std::string_view(reinterpret_cast<const char*>(b_.data() + pos_), n);
    pos_ += n;
    if (!check(at, nameRule(view, required))) {
      return false;
    }
    out.assign(view);
    return true;
  }

  bool header() {
    const std::size_t size = b_.size();
    if (size < kHeaderBytes) {
      return fail(size, "icons.pack: truncated header: the header needs " + str(kHeaderBytes) +
                            " bytes, the file ends at byte " + str(size) + "; rebuild the database");
    }
    const std::byte* h = b_.data();
    if (std::memcmp(h + field::magic, kMagic.data(), kMagic.size()) != 0) {
      return fail(field::magic, "icons.pack: bad magic: not a sandtable icon database (expected \"STICONS\\0\")");
    }
    version_ = loadLE<std::uint32_t>(h + field::version);
    if (version_ < kOldestVersion || version_ > kVersion) {
      return fail(field::version, "icons.pack: version " + str(version_) +
                                      " is not supported (this reader knows versions 1 and 2); use a matching "
                                      "sandtable");
    }
    const auto headerBytes = loadLE<std::uint32_t>(h + field::headerBytes);
    if (headerBytes != kHeaderBytes) {
      return fail(field::headerBytes, "icons.pack: header size " + str(headerBytes) + " must be " + str(kHeaderBytes));
    }
    const auto storedHeaderCrc = loadLE<std::uint32_t>(h + field::headerCrc);
    const auto headerCrc = crc32(b_.first(field::headerCrc));
    if (storedHeaderCrc != headerCrc) {
      return fail(field::headerCrc, "icons.pack: header checksum mismatch (stored " + crcHex(storedHeaderCrc) +
                                        ", computed " + crcHex(headerCrc) +
                                        "): the header is corrupt; rebuild the database");
    }
    const auto bodyBytes = loadLE<std::uint64_t>(h + field::bodyBytes);
    if (bodyBytes != size - kHeaderBytes) {
      const bool shorter = bodyBytes > size - kHeaderBytes;
      return fail(shorter ? size : kHeaderBytes + bodyBytes,
                  "icons.pack: file is " + str(size) + " bytes but the header says " + str(kHeaderBytes) + " + " +
                      str(bodyBytes) + (shorter ? ": truncated" : ": trailing bytes") + "; rebuild the database");
    }
    const auto storedBodyCrc = loadLE<std::uint32_t>(h + field::bodyCrc);
    const auto bodyCrc = crc32(b_.subspan(kHeaderBytes));
    if (storedBodyCrc != bodyCrc) {
      return fail(field::bodyCrc, "icons.pack: body checksum mismatch (stored " + crcHex(storedBodyCrc) +
                                      ", computed " + crcHex(bodyCrc) + "): the file is corrupt; rebuild the database");
    }
    pos_ = kHeaderBytes;
    return true;
  }

  bool body(Pack& pack) {
    const auto icons = loadLE<std::uint32_t>(b_.data() + field::iconCount);
    const auto textures = loadLE<std::uint32_t>(b_.data() + field::textureCount);
    if (!check(field::iconCount, countRule("icon count", icons, 0, kMaxIcons)) ||
        !fits(field::textureCount, textures, kMinTextureBytes, "textures", "texture count")) {
      return false;
    }
    pack.textures.reserve(textures);
    for (std::size_t t = 0; t < textures; ++t) {
      where_ = Where{"texture", t, nullptr, {}, {}};
      if (!texture(pack.textures.emplace_back())) {
        return false;
      }
    }
    where_ = Where{};
    if (!fits(field::iconCount, icons, minIconBytes(version_), "icons", "icon count")) {
      return false;
    }
    pack.icons.reserve(icons);
    names_.reserve(icons);
    for (std::size_t i = 0; i < icons; ++i) {
      where_ = Where{"icon", i, nullptr, {}, {}};
      if (!icon(pack.icons.emplace_back(), textures)) {
        return false;
      }
    }
    where_ = Where{};
    if (pos_ != b_.size()) {
      return fail(pos_, "icons.pack: trailing bytes: the last icon ends at byte " + str(pos_) + ", the body at byte " +
                            str(b_.size()));
    }
    return true;
  }

  bool texture(Texture& t) {
    std::uint64_t at = 0;
    std::string_view view;
    if (!readString(t.name, false, "name", at, view)) {
      return false;
    }
    where_.name = &t.name;
    const std::uint64_t countAt = pos_;
    std::uint32_t n = 0;
    if (!read(n, "byte count") || !fitsBytes(countAt, n, "bytes")) {
      return false;
    }
    t.bytes.assign(b_.begin() + static_cast<std::ptrdiff_t>(pos_), b_.begin() + static_cast<std::ptrdiff_t>(pos_ + n));
    pos_ += n;
    return true;
  }

  bool icon(Icon& icon, std::uint64_t textures) {
    std::uint64_t at = 0;
    std::string_view view;
    if (!readString(icon.name, true, "name", at, view)) {
      return false;
    }
    where_.name = &icon.name;
    if (const auto [it, fresh] = names_.emplace(view, where_.index); !fresh) {
      return check(at, duplicateRule(icon.name, it->second));
    }
    const std::uint64_t flagsAt = pos_;
    std::uint32_t flags = 0;
    if (!read(flags, "flags")) {
      return false;
    }
    if ((flags & ~(version_ == 1 ? kIconFlagsV1 : kIconFlags)) != 0) {
      return fail(flagsAt, message(where_, "flags " + hex32(flags) +
                                               (version_ == 1 ? " have bits set other than bit 0 (armed), 1 "
                                                                "(resupply) and 2 (has DIS type)"
                                                              : " have bits set other than bit 0 (armed) and 1 "
                                                                "(resupply)")));
    }
    icon.armed = (flags & kIconArmed) != 0;
    icon.resupply = (flags & kIconResupply) != 0;
    if (!(version_ == 1 ? disV1(icon, (flags & kIconHasDisV1) != 0) : disPatterns(icon))) {
      return false;
    }
    const std::uint64_t boundsAt = pos_;
    if (!need(24, "bounds")) {
      return false;
    }
    for (float& v : icon.bounds) {
      v = take<float>();
    }
    if (!check(boundsAt, boundsRule(icon.bounds))) {
      return false;
    }
    std::uint64_t fieldAt = pos_;
    if (!read(icon.cylinderRadius, "cylinder radius") ||
        !check(fieldAt, nonNegativeRule("cylinder radius", icon.cylinderRadius))) {
      return false;
    }
    fieldAt = pos_;
    if (!read(icon.cylinderHeight, "cylinder height") ||
        !check(fieldAt, nonNegativeRule("cylinder height", icon.cylinderHeight))) {
      return false;
    }
    return materials(icon, textures) && ranges(icon) && parts(icon);
  }

  DisType takeDisType() {
    DisType t;
    t.kind = take<std::uint8_t>();
    t.domain = take<std::uint8_t>();
    t.country = take<std::uint16_t>();
    t.category = take<std::uint8_t>();
    t.subcategory = take<std::uint8_t>();
    t.specific = take<std::uint8_t>();
    t.extra = take<std::uint8_t>();
    return t;
  }

  /// Version 1: 8 bytes of one exact type, zeros without flag bit 2; read
  /// as one pattern without wildcards.
  bool disV1(Icon& icon, bool hasDis) {
    const std::uint64_t disAt = pos_;
    if (!need(8, "DIS type")) {
      return false;
    }
    const DisType t = takeDisType();
    if (!check(disAt, disV1Rule(hasDis, t))) {
      return false;
    }
    if (hasDis) {
      icon.dis.push_back({t, 0});
    }
    return true;
  }

  /// Version 2: a u16 count, then 9 bytes a pattern.
  bool disPatterns(Icon& icon) {
    const std::uint64_t countAt = pos_;
    std::uint16_t n = 0;
    if (!read(n, "DIS pattern count") ||
        !check(countAt, countRule("DIS pattern count", n, 0, kMaxDisPatterns)) ||
        !fits(countAt, n, kDisPatternBytes, "DIS patterns", "DIS pattern count", true)) {
      return false;
    }
    icon.dis.resize(n);
    for (std::size_t d = 0; d < n; ++d) {
      const std::uint64_t at = pos_;
      DisPattern& p = icon.dis[d];
      p.wild = take<std::uint8_t>();
      p.type = takeDisType();
      if (!check(at, disPatternRule(d, p))) {
        return false;
      }
    }
    return true;
  }

  bool materials(Icon& icon, std::uint64_t textures) {
    const std::uint64_t countAt = pos_;
    std::uint32_t n = 0;
    if (!read(n, "material count") || !check(countAt, countRule("material count", n, 1, kMaxMaterials)) ||
        !fits(countAt, n, kMaterialBytes, "materials", "material count", true)) {
      return false;
    }
    icon.materials.resize(n);
    for (std::size_t m = 0; m < n; ++m) {
      Material& mat = icon.materials[m];
      const std::uint64_t at = pos_;
      for (std::uint8_t& c : mat.rgba) {
        c = take<std::uint8_t>();
      }
      mat.texture = take<std::uint32_t>();
      if (!check(at, textureRule(m, mat.texture, textures))) {
        return false;
      }
    }
    return true;
  }

  bool ranges(Icon& icon) {
    const std::uint64_t countAt = pos_;
    std::uint32_t n = 0;
    if (!read(n, "level count") || !check(countAt, countRule("level count", n, 1, kMaxLevels)) ||
        !fits(countAt, n, 4, "ranges", "level count", true)) {
      return false;
    }
    const std::uint64_t at = pos_;
    takeFloats(icon.ranges, n);
    return check(at, rangesRule(icon.ranges));
  }

  bool parts(Icon& icon) {
    const std::uint64_t countAt = pos_;
    std::uint32_t n = 0;
    if (!read(n, "part count") || !check(countAt, countRule("part count", n, 1, kMaxParts)) ||
        !fits(countAt, n, kMinPartBytes, "parts", "part count")) {
      return false;
    }
    icon.parts.reserve(n);
    for (std::size_t p = 0; p < n; ++p) {
      where_.part = p;
      if (!part(icon, p, icon.parts.emplace_back())) {
        return false;
      }
    }
    where_.part.reset();
    return check(countAt, hullRule(icon.parts));
  }

  bool part(const Icon& icon, std::size_t p, Part& part) {
    std::uint64_t at = 0;
    std::string_view view;
    if (!readString(part.name, false, "name", at, view)) {
      return false;
    }
    const std::uint64_t stateAt = pos_;
    if (!need(4, "state")) {
      return false;
    }
    const auto state = take<std::uint8_t>();
    const auto reserved8 = take<std::uint8_t>();
    const auto reserved16 = take<std::uint16_t>();
    if (!check(stateAt, stateRule(state))) {
      return false;
    }
    part.state = static_cast<State>(state);
    if (reserved8 != 0 || reserved16 != 0) {
      return fail(stateAt + (reserved8 != 0 ? 1 : 2),
                  message(where_, "reserved bytes after the state are not zero"));
    }
    const std::uint64_t parentAt = pos_;
    if (!read(part.parent, "parent") || !check(parentAt, parentRule(part.parent, p))) {
      return false;
    }
    const std::uint64_t offsetAt = pos_;
    if (!need(12, "offset")) {
      return false;
    }
    for (float& v : part.offset) {
      v = take<float>();
    }
    if (!check(offsetAt, finiteRule("offset", part.offset))) {
      return false;
    }
    const std::uint64_t countAt = pos_;
    std::uint32_t n = 0;
    if (!read(n, "mesh count") || !check(countAt, countRule("mesh count", n, 0, kMaxMeshes)) ||
        !fits(countAt, n, minMeshBytes(icon.ranges.size()), "meshes", "mesh count")) {
      return false;
    }
    part.meshes.reserve(n);
    for (std::size_t m = 0; m < n; ++m) {
      where_.mesh = m;
      if (!mesh(icon, part.meshes.emplace_back())) {
        return false;
      }
    }
    where_.mesh.reset();
    return true;
  }

  bool mesh(const Icon& icon, Mesh& mesh) {
    const std::uint64_t materialAt = pos_;
    if (!read(mesh.material, "material") || !check(materialAt, materialRule(mesh.material, icon.materials.size()))) {
      return false;
    }
    const std::uint64_t countAt = pos_;
    std::uint32_t n = 0;
    if (!read(n, "vertex count") || !check(countAt, countRule("vertex count", n, 1, kMaxVertices))) {
      return false;
    }
    const std::uint64_t flagsAt = pos_;
    std::uint32_t flags = 0;
    if (!read(flags, "flags")) {
      return false;
    }
    if ((flags & ~kMeshTexcoords) != 0) {
      return fail(flagsAt, message(where_, "flags " + hex32(flags) + " have bits set other than bit 0 (has texcoords)"));
    }
    const bool texcoords = (flags & kMeshTexcoords) != 0;
    if (!fits(countAt, n, vertexBytes(texcoords), "positions", "vertex count", true,
              texcoords ? "positions, normals and texcoords" : "positions and normals")) {
      return false;
    }
    std::uint64_t at = pos_;
    takeFloats(mesh.positions, 3 * std::size_t{n});
    if (!check(at, finiteRule("positions", mesh.positions, 3))) {
      return false;
    }
    at = pos_;
    takeFloats(mesh.normals, 3 * std::size_t{n});
    if (!check(at, finiteRule("normals", mesh.normals, 3))) {
      return false;
    }
    if (texcoords) {
      at = pos_;
      takeFloats(mesh.texcoords, 2 * std::size_t{n});
      if (!check(at, finiteRule("texcoords", mesh.texcoords, 2))) {
        return false;
      }
    }
    mesh.levels.resize(icon.ranges.size());
    for (std::size_t l = 0; l < mesh.levels.size(); ++l) {
      const std::uint64_t indexCountAt = pos_;
      std::uint32_t count = 0;
      if (!read(count, "index count") || !check(indexCountAt, indexCountRule(l, count)) ||
          !fits(indexCountAt, count, 4, "indices", "index count", true)) {
        return false;
      }
      auto& idx = mesh.levels[l];
      idx.resize(count);
      std::memcpy(idx.data(), b_.data() + pos_, 4 * std::size_t{count});
      at = pos_;
      pos_ += 4 * std::uint64_t{count};
      if (!check(at, indicesRule(l, idx, n))) {
        return false;
      }
    }
    return true;
  }

  std::span<const std::byte> b_;
  const std::string& file_;
  std::uint64_t pos_ = 0;
  std::uint32_t version_ = kVersion;
  Where where_;
  std::unordered_map<std::string_view, std::size_t> names_;  // icon names (views into the input)
  std::optional<Problem> problem_;
};

// ---------------------------------------------------------------- encode

/// Writes a whole pack, checking each field before it writes it; stops at
/// the first problem (file "", offset where the field would have been).
class Encoder {
 public:
  explicit Encoder(const Pack& p) : p_(p) {}

  Result<std::vector<std::byte>> run() {
    out_.assign(kHeaderBytes, std::byte{0});
    if (!body()) {
      return *problem_;
    }
    std::byte* h = out_.data();
    std::memcpy(h + field::magic, kMagic.data(), kMagic.size());
    storeLE<std::uint32_t>(h + field::version, kVersion);
    storeLE<std::uint32_t>(h + field::headerBytes, kHeaderBytes);
    storeLE<std::uint32_t>(h + field::iconCount, static_cast<std::uint32_t>(p_.icons.size()));
    storeLE<std::uint32_t>(h + field::textureCount, static_cast<std::uint32_t>(p_.textures.size()));
    storeLE<std::uint64_t>(h + field::bodyBytes, out_.size() - kHeaderBytes);
    storeLE<std::uint32_t>(h + field::bodyCrc, crc32(std::span(out_).subspan(kHeaderBytes)));
    storeLE<std::uint32_t>(h + field::headerCrc, crc32(std::span(out_).first(field::headerCrc)));
    return std::move(out_);
  }

 private:
  bool fail(std::uint64_t at, const std::string& why) {
    problem_ = Problem{"", at, message(where_, why)};
    return false;
  }

  bool check(std::uint64_t fieldAt, const Check& c) { return !c || fail(fieldAt + c->at, c->why); }

  std::uint64_t at() const { return out_.size(); }

  template <typename T>
  void put(T v) {
    const std::size_t n = out_.size();
    out_.resize(n + sizeof(T));
    storeLE<T>(out_.data() + n, v);
  }

  void putBytes(const void* data, std::size_t n) {
    const auto* b = static_cast<const std::byte*>(data);
    out_.insert(out_.end(), b, b + n);
  }

  template <typename T>
  void putArray(std::span<const T> v) {
    putBytes(v.data(), v.size_bytes());
  }

  bool putString(const std::string& s, bool required) {
    if (!check(at(), nameRule(s, required))) {
      return false;
    }
    put<std::uint16_t>(static_cast<std::uint16_t>(s.size()));
    putBytes(s.data(), s.size());
    return true;
  }

  bool body() {
    if (!check(field::iconCount, countRule("icon count", p_.icons.size(), 0, kMaxIcons)) ||
        !check(field::textureCount, countRule("texture count", p_.textures.size(), 0, kNoTexture - 1))) {
      return false;
    }
    for (std::size_t t = 0; t < p_.textures.size(); ++t) {
      where_ = Where{"texture", t, nullptr, {}, {}};
      if (!texture(p_.textures[t])) {
        return false;
      }
    }
    std::unordered_map<std::string_view, std::size_t> names;
    for (std::size_t i = 0; i < p_.icons.size(); ++i) {
      where_ = Where{"icon", i, nullptr, {}, {}};
      const Icon& icon = p_.icons[i];
      const std::uint64_t nameAt = at();
      if (!putString(icon.name, true)) {
        return false;
      }
      where_.name = &icon.name;
      if (const auto [it, fresh] = names.emplace(icon.name, i); !fresh) {
        return check(nameAt, duplicateRule(icon.name, it->second));
      }
      if (!iconFields(icon)) {
        return false;
      }
    }
    return true;
  }

  bool texture(const Texture& t) {
    if (!putString(t.name, false)) {
      return false;
    }
    where_.name = &t.name;
    if (t.bytes.size() > 0xFFFFFFFFu) {
      return fail(at(), "is " + str(t.bytes.size()) + " bytes, more than 4294967295");
    }
    put<std::uint32_t>(static_cast<std::uint32_t>(t.bytes.size()));
    putArray<std::byte>(t.bytes);
    return true;
  }

  bool iconFields(const Icon& icon) {
    put<std::uint32_t>((icon.armed ? kIconArmed : 0) | (icon.resupply ? kIconResupply : 0));
    if (!check(at(), countRule("DIS pattern count", icon.dis.size(), 0, kMaxDisPatterns))) {
      return false;
    }
    put<std::uint16_t>(static_cast<std::uint16_t>(icon.dis.size()));
    for (std::size_t d = 0; d < icon.dis.size(); ++d) {
      const DisPattern& p = icon.dis[d];
      if (!check(at(), disPatternRule(d, p))) {
        return false;
      }
      put(p.wild);
      put(p.type.kind);
      put(p.type.domain);
      put(p.type.country);
      put(p.type.category);
      put(p.type.subcategory);
      put(p.type.specific);
      put(p.type.extra);
    }
    if (!check(at(), boundsRule(icon.bounds))) {
      return false;
    }
    putArray<float>(icon.bounds);
    if (!check(at(), nonNegativeRule("cylinder radius", icon.cylinderRadius))) {
      return false;
    }
    put(icon.cylinderRadius);
    if (!check(at(), nonNegativeRule("cylinder height", icon.cylinderHeight))) {
      return false;
    }
    put(icon.cylinderHeight);
    if (!check(at(), countRule("material count", icon.materials.size(), 1, kMaxMaterials))) {
      return false;
    }
    put<std::uint32_t>(static_cast<std::uint32_t>(icon.materials.size()));
    for (std::size_t m = 0; m < icon.materials.size(); ++m) {
      const Material& mat = icon.materials[m];
      if (!check(at(), textureRule(m, mat.texture, p_.textures.size()))) {
        return false;
      }
      putArray<std::uint8_t>(mat.rgba);
      put(mat.texture);
    }
    if (!check(at(), countRule("level count", icon.ranges.size(), 1, kMaxLevels))) {
      return false;
    }
    put<std::uint32_t>(static_cast<std::uint32_t>(icon.ranges.size()));
    if (!check(at(), rangesRule(icon.ranges))) {
      return false;
    }
    putArray<float>(icon.ranges);
    const std::uint64_t partsAt = at();
    if (!check(partsAt, countRule("part count", icon.parts.size(), 1, kMaxParts))) {
      return false;
    }
    put<std::uint32_t>(static_cast<std::uint32_t>(icon.parts.size()));
    for (std::size_t p = 0; p < icon.parts.size(); ++p) {
      where_.part = p;
      if (!part(icon, p, icon.parts[p])) {
        return false;
      }
    }
    where_.part.reset();
    return check(partsAt, hullRule(icon.parts));
  }

  bool part(const Icon& icon, std::size_t p, const Part& part) {
    if (!putString(part.name, false) || !check(at(), stateRule(static_cast<std::uint8_t>(part.state)))) {
      return false;
    }
    put(static_cast<std::uint8_t>(part.state));
    put<std::uint8_t>(0);
    put<std::uint16_t>(0);
    if (!check(at(), parentRule(part.parent, p))) {
      return false;
    }
    put(part.parent);
    if (!check(at(), finiteRule("offset", part.offset))) {
      return false;
    }
    putArray<float>(part.offset);
    if (!check(at(), countRule("mesh count", part.meshes.size(), 0, kMaxMeshes))) {
      return false;
    }
    put<std::uint32_t>(static_cast<std::uint32_t>(part.meshes.size()));
    for (std::size_t m = 0; m < part.meshes.size(); ++m) {
      where_.mesh = m;
      if (!mesh(icon, part.meshes[m])) {
        return false;
      }
    }
    where_.mesh.reset();
    return true;
  }

  /// The shape a Mesh must have to be stored (bytes cannot say otherwise).
  bool meshShape(const Icon& icon, const Mesh& mesh) {
    const std::size_t n = mesh.positions.size() / 3;
    if (mesh.positions.size() % 3 != 0) {
      return fail(at(), "has " + str(mesh.positions.size()) + " position values, not 3 per vertex");
    }
    if (Check c = countRule("vertex count", n, 1, kMaxVertices)) {
      return check(at(), c);
    }
    if (mesh.normals.size() != mesh.positions.size()) {
      return fail(at(), "has " + str(mesh.normals.size()) + " normal values for " + str(n) + " vertices (needs " +
                            str(3 * n) + ")");
    }
    if (!mesh.texcoords.empty() && mesh.texcoords.size() != 2 * n) {
      return fail(at(), "has " + str(mesh.texcoords.size()) + " texcoord values for " + str(n) +
                            " vertices (needs 0 or " + str(2 * n) + ")");
    }
    if (mesh.levels.size() != icon.ranges.size()) {
      return fail(at(), "has " + str(mesh.levels.size()) + " index lists for the icon's " +
                            str(icon.ranges.size()) + " levels");
    }
    return true;
  }

  bool mesh(const Icon& icon, const Mesh& mesh) {
    if (!check(at(), materialRule(mesh.material, icon.materials.size()))) {
      return false;
    }
    put(mesh.material);
    if (!meshShape(icon, mesh)) {
      return false;
    }
    const std::size_t n = mesh.vertexCount();
    put<std::uint32_t>(static_cast<std::uint32_t>(n));
    put<std::uint32_t>(mesh.texcoords.empty() ? 0 : kMeshTexcoords);
    if (!check(at(), finiteRule("positions", mesh.positions, 3))) {
      return false;
    }
    putArray<float>(mesh.positions);
    if (!check(at(), finiteRule("normals", mesh.normals, 3))) {
      return false;
    }
    putArray<float>(mesh.normals);
    if (!check(at(), finiteRule("texcoords", mesh.texcoords, 2))) {
      return false;
    }
    putArray<float>(mesh.texcoords);
    for (std::size_t l = 0; l < mesh.levels.size(); ++l) {
      const auto& idx = mesh.levels[l];
      if (idx.size() > 0xFFFFFFFFu) {
        return fail(at(), "level " + str(l) + " has " + str(idx.size()) + " indices, more than 4294967295");
      }
      if (!check(at(), indexCountRule(l, idx.size()))) {
        return false;
      }
      put<std::uint32_t>(static_cast<std::uint32_t>(idx.size()));
      if (!check(at(), indicesRule(l, idx, n))) {
        return false;
      }
      putArray<std::uint32_t>(idx);
    }
    return true;
  }

  const Pack& p_;
  std::vector<std::byte> out_;
  Where where_;
  std::optional<Problem> problem_;
};

}  // namespace

std::uint32_t disField(const DisType& t, std::size_t k) {
  switch (k) {
    case 0: return t.kind;
    case 1: return t.domain;
    case 2: return t.country;
    case 3: return t.category;
    case 4: return t.subcategory;
    case 5: return t.specific;
    default: return t.extra;
  }
}

const char* disFieldName(std::size_t k) {
  static const char* const names[kDisFields] = {"kind",        "domain",   "country", "category",
                                                "subcategory", "specific", "extra"};
  return k < kDisFields ? names[k] : "?";
}

std::array<float, 3> partOrigin(const Icon& icon, std::size_t part) {
  std::array<float, 3> o{0, 0, 0};
  // Parents are earlier parts (decode refuses others); anything else ends the chain.
  std::int32_t p = part < icon.parts.size() ? std::int32_t(part) : kBody;
  while (p != kBody) {
    const Part& at = icon.parts[std::size_t(p)];
    for (int k = 0; k < 3; ++k) o[k] += at.offset[k];
    p = at.parent >= 0 && at.parent < p ? at.parent : kBody;
  }
  return o;
}

std::uint64_t triangleCount(const Icon& icon, std::size_t level, State state) {
  std::uint64_t n = 0;
  for (const Part& p : icon.parts) {
    if (p.state != state) {
      continue;
    }
    for (const Mesh& m : p.meshes) {
      if (level < m.levels.size()) {
        n += m.levels[level].size() / 3;
      }
    }
  }
  return n;
}

Result<std::vector<std::byte>> encode(const Pack& p) { return Encoder(p).run(); }

Result<Pack> decode(std::span<const std::byte> bytes, const std::string& file) { return Decoder(bytes, file).run(); }

Result<Pack> readFile(const std::string& path) {
  auto bytes = readSmallFile(path, kMaxFileBytes);
  if (!bytes) {
    return Problem{path, 0, "icons.pack: " + bytes.message()};
  }
  return decode(bytes.value(), path);
}

Status writeFile(const std::string& path, const Pack& p) {
  auto bytes = encode(p);
  if (!bytes) {
    std::vector<Problem> problems = bytes.problems();
    for (Problem& q : problems) {
      q.file = path;
    }
    return problems;
  }
  return writeFileAtomic(path, bytes.value());
}

}  // namespace sandtable::iconpack
