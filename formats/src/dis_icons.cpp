// DIS entity type -> icon (docs/ICONS.md §3.1).
#include "sandtable/formats/dis_icons.h"

#include <algorithm>
#include <charconv>

namespace sandtable::iconpack {
namespace {

constexpr std::uint32_t kFieldMax[kDisFields] = {255, 255, 65535, 255, 255, 255, 255};

void setField(DisType& t, std::size_t k, std::uint32_t v) {
  const auto b = static_cast<std::uint8_t>(v);
  switch (k) {
    case 0: t.kind = b; break;
    case 1: t.domain = b; break;
    case 2: t.country = static_cast<std::uint16_t>(v); break;
    case 3: t.category = b; break;
    case 4: t.subcategory = b; break;
    case 5: t.specific = b; break;
    default: t.extra = b; break;
  }
}

/// The fallbacks relax the type: these fields match anything. Category is
/// kept in the first because SISO-REF-010 numbers a platform's category by
/// kind and domain alone (land 1 tank, 2 armoured fighting vehicle, ... 7
/// large wheeled utility vehicle), for every country; the subcategory and
/// below are numbered per country, so they say nothing across countries.
constexpr std::uint8_t kIgnoreAllButCategory = 0x7F & ~0x01 & ~0x02 & ~0x08;  // keep kind, domain, category
constexpr std::uint8_t kIgnoreAllButKindDomain = 0x7F & ~0x01 & ~0x02;

}  // namespace

std::optional<DisPattern> parseDisPattern(std::string_view text, std::string& why) {
  DisPattern p;
  p.wild = kDisAllWild;
  std::size_t k = 0;
  std::string_view s = text;
  while (true) {
    const std::size_t dot = s.find('.');
    const std::string_view f = s.substr(0, dot);
    if (k == kDisFields) {
      why = "has more than 7 fields (kind.domain.country.category.subcategory.specific.extra)";
      return std::nullopt;
    }
    if (f == "*") {
      // stays a wildcard
    } else {
      std::uint32_t v = 0;
      const auto r = std::from_chars(f.data(), f.data() + f.size(), v);
      if (f.empty() || r.ec != std::errc() || r.ptr != f.data() + f.size() || v > kFieldMax[k]) {
        why = "field " + std::to_string(k + 1) + " (" + disFieldName(k) + ") '" + std::string(f) +
              "' is not a number from 0 to " + std::to_string(kFieldMax[k]) + " or *";
        return std::nullopt;
      }
      setField(p.type, k, v);
      p.wild = static_cast<std::uint8_t>(p.wild & ~(1u << k));
    }
    ++k;
    if (dot == std::string_view::npos) break;
    s.remove_prefix(dot + 1);
  }
  return p;
}

std::string disText(const DisPattern& p) {
  std::size_t n = kDisFields;
  while (n > 0 && ((p.wild >> (n - 1)) & 1) != 0) --n;
  if (n == 0) return "*";
  std::string s;
  for (std::size_t k = 0; k < n; ++k) {
    if (k) s += '.';
    s += ((p.wild >> k) & 1) != 0 ? std::string("*") : std::to_string(disField(p.type, k));
  }
  return s;
}

bool matches(const DisPattern& p, const DisType& t) {
  for (std::size_t k = 0; k < kDisFields; ++k) {
    if (((p.wild >> k) & 1) == 0 && disField(p.type, k) != disField(t, k)) return false;
  }
  return true;
}

const std::vector<DefaultIconName>& defaultIconNames() {
  static const std::vector<DefaultIconName> names{
      {1, 1, {"tank"}},           {1, 2, {"jet", "aircraft"}}, {1, 3, {"boat", "ship"}},
      {1, 4, {"submarine", "boat"}}, {2, -1, {"missile", "munition"}}, {3, -1, {"soldier", "lifeform"}},
  };
  return names;
}

DisIconMap::DisIconMap(std::span<const Icon> icons) : iconCount_(static_cast<std::uint32_t>(icons.size())) {
  for (std::uint32_t i = 0; i < icons.size(); ++i) {
    for (const DisPattern& p : icons[i].dis) entries_.push_back({p, specificity(p), i});
  }
  // Most specific first; a stable sort keeps pack order (icon, then line) among equals.
  std::stable_sort(entries_.begin(), entries_.end(),
                   [](const Entry& a, const Entry& b) { return a.specificity > b.specificity; });
  for (const DefaultIconName& d : defaultIconNames()) {
    for (std::string_view name : d.names) {
      const auto it = std::find_if(icons.begin(), icons.end(), [&](const Icon& i) { return i.name == name; });
      if (it != icons.end()) {
        defaults_.push_back({d.kind, d.domain, static_cast<std::uint32_t>(it - icons.begin())});
        break;
      }
    }
  }
}

std::optional<std::uint32_t> DisIconMap::best(const DisType& t, std::uint8_t ignore) const {
  for (const Entry& e : entries_) {
    DisPattern p = e.pattern;
    p.wild |= ignore;
    if (matches(p, t)) return e.icon;
  }
  return std::nullopt;
}

DisMatch DisIconMap::match(const DisType& t) const {
  if (auto i = best(t, 0)) return {*i, DisMatchBy::pattern};
  if (auto i = best(t, kIgnoreAllButCategory)) return {*i, DisMatchBy::category};
  if (auto i = best(t, kIgnoreAllButKindDomain)) return {*i, DisMatchBy::kindDomain};
  for (const Default& d : defaults_) {
    if (d.kind == t.kind && (d.domain < 0 || d.domain == t.domain)) return {d.icon, DisMatchBy::defaultName};
  }
  if (iconCount_ > 0) return {0, DisMatchBy::firstIcon};
  return {};
}

DisMatch DisIconMap::lookup(const DisType& t) {
  const std::uint64_t key = packedDisType(t);
  if (const auto it = cache_.find(key); it != cache_.end()) return it->second;
  if (cache_.size() >= kCacheEntries) cache_.clear();
  const DisMatch m = match(t);
  cache_.emplace(key, m);
  return m;
}

}  // namespace sandtable::iconpack
