#pragma once
// DIS entity type -> icon: the `dis` patterns of an icon pack (wildcards
// allowed), the best match for a type, and the default icon for a type that
// no pattern matches. The rule, with how other tools do it, is in
// docs/ICONS.md §3.1; GL-free, for the simulator, the viewer and the monitor.
//
// Thread safety: parseDisPattern, disText, matches and specificity are
// pure. A DisIconMap is built once; match() is const and may be called from
// any number of threads; lookup() adds to a cache and must be called from one
// thread at a time (each receiving thread keeps its own map, or the caller
// locks).
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "sandtable/formats/icon_pack.h"

namespace sandtable::iconpack {

/// The type's 64 bits, kind highest: kind, domain, country (16 bits),
/// category, subcategory, specific, extra. A cache key and a total order.
constexpr std::uint64_t packedDisType(const DisType& t) {
  return std::uint64_t{t.kind} << 56 | std::uint64_t{t.domain} << 48 | std::uint64_t{t.country} << 32 |
         std::uint64_t{t.category} << 24 | std::uint64_t{t.subcategory} << 16 | std::uint64_t{t.specific} << 8 |
         std::uint64_t{t.extra};
}

/// Text "K.D.C.CAT.SUB.SPEC.EXTRA": 1 to 7 dot-separated fields, each a
/// decimal number (country 0-65535, the others 0-255) or `*`; omitted
/// trailing fields are `*`. nullopt with `why` set (what is wrong, what to
/// write) when the text is not a pattern.
std::optional<DisPattern> parseDisPattern(std::string_view text, std::string& why);

/// The canonical text: trailing wildcards left off, `*` for the others,
/// "*" for a pattern of wildcards only ("1.1.225.1", "1.2", "1.1.*.1").
std::string disText(const DisPattern& p);

/// Every field that is not a wildcard equals the type's.
bool matches(const DisPattern& p, const DisType& t);

/// How specific a pattern is: bit (6 - k) set when field k is exact. A
/// larger number is more specific, which is "more leading fields exact
/// wins": comparing two numbers compares their exact fields in field order.
constexpr std::uint8_t specificity(const DisPattern& p) {
  std::uint8_t s = 0;
  for (std::size_t k = 0; k < kDisFields; ++k) {
    if (((p.wild >> k) & 1) == 0) s |= static_cast<std::uint8_t>(1u << (kDisFields - 1 - k));
  }
  return s;
}

/// DisMatch::icon when the pack has no icon at all.
inline constexpr std::uint32_t kNoIcon = 0xFFFFFFFFu;

/// How a type found its icon; everything after `pattern` is a fallback.
enum class DisMatchBy : std::uint8_t {
  pattern,       ///< a `dis` pattern matches the type
  category,      ///< fallback: a pattern matching kind, domain and category (country and the rest ignored)
  kindDomain,    ///< fallback: a pattern matching kind and domain
  defaultName,   ///< fallback: the built-in default icon name for the kind and domain (kDefaultIconNames)
  firstIcon,     ///< fallback: icon 0
  none,          ///< the pack has no icon
};

struct DisMatch {
  std::uint32_t icon = kNoIcon;  ///< index into the pack's icons
  DisMatchBy by = DisMatchBy::none;
  bool fallback() const { return by != DisMatchBy::pattern; }
  bool operator==(const DisMatch&) const = default;
};

/// The built-in default for a type no pattern matches even by kind and
/// domain: the first icon in the pack named one of `names`.
struct DefaultIconName {
  std::uint8_t kind;
  int domain;  ///< -1: any domain
  std::vector<std::string_view> names;
};
/// Platform land "tank", air "jet" or "aircraft", surface "boat" or "ship",
/// subsurface "submarine" or "boat"; munition (kind 2, any domain)
/// "missile" or "munition"; life form (kind 3) "soldier" or "lifeform".
const std::vector<DefaultIconName>& defaultIconNames();

/// The patterns of a pack's icons, ordered once for matching, and a cache
/// of types already matched.
class DisIconMap {
 public:
  DisIconMap() = default;
  explicit DisIconMap(std::span<const Icon> icons);
  explicit DisIconMap(const Pack& pack) : DisIconMap(std::span<const Icon>(pack.icons)) {}

  /// The best icon for `t` (docs/ICONS.md §3.1): among the patterns that
  /// match, the most specific; ties go to the icon first in the pack. With
  /// none, the fallbacks in DisMatchBy order. Pure and thread-safe.
  DisMatch match(const DisType& t) const;

  /// match(), remembered by packedDisType: a type seen before costs one hash
  /// lookup. The cache holds at most kCacheEntries types and is emptied when
  /// full, so hostile traffic of random types cannot grow it. One thread.
  DisMatch lookup(const DisType& t);

  static constexpr std::size_t kCacheEntries = 1u << 16;
  std::size_t cached() const { return cache_.size(); }
  std::size_t patterns() const { return entries_.size(); }

 private:
  struct Entry {
    DisPattern pattern;
    std::uint8_t specificity = 0;
    std::uint32_t icon = 0;
  };
  /// The first entry (most specific first) matching `t` with the fields in
  /// `ignore` (a wildcard mask) treated as matching anything.
  std::optional<std::uint32_t> best(const DisType& t, std::uint8_t ignore) const;

  std::vector<Entry> entries_;  // by specificity, most specific first; then icon, then line order
  std::uint32_t iconCount_ = 0;
  struct Default {
    std::uint8_t kind;
    int domain;
    std::uint32_t icon;
  };
  std::vector<Default> defaults_;  // defaultIconNames() resolved against the pack
  std::unordered_map<std::uint64_t, DisMatch> cache_;
};

}  // namespace sandtable::iconpack
