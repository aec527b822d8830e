#pragma once
// The material cross-reference table (seed Figure 39, redone as editable
// text; grammar in docs/FORMAT.md §11). It lists the classes of soil, ground
// cover, roads and other features with their colours, material and texture
// ids and draw priority, and the rules that map source attributes (OSM
// tags, shapefile fields, GeoPackage layer names) to a class and a width.
// The table used by a build is copied into the database as materials.txt.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::materials {

inline constexpr const char* kHeaderLine = "sandtable-materials 1";
inline constexpr const char* kFileName = "materials.txt";
/// Largest table readFile accepts.
inline constexpr std::uint64_t kMaxFileBytes = 4u << 20;
/// "No class": Table::defaultLine after `default-line none`, and the class
/// of a Match from a rule whose class is `-` (the feature is ignored).
inline constexpr std::uint16_t kNoClass = 0xFFFF;
/// Rule class name that ignores the feature (e.g. `rule tunnel=yes -`).
inline constexpr const char* kIgnoreClass = "-";

enum class Kind : std::uint8_t {
  area,  ///< skin: polygons tile the terrain triangles (soil, land cover, lakes)
  line,  ///< decal: lines widened to a width (roads, rivers, railways)
};

/// One class. Area classes are skin (priority 1); line classes are decals
/// (priority 2..98, drawn in priority order over the skin).
/// Class::storey by default: metres per building level.
inline constexpr double kDefaultStorey = 3.0;
/// Soil of a class without `stick=` / `resist=` (seed VII.B.2.b): firm
/// ground. The simulator's land dynamics read them.
inline constexpr double kDefaultStickDeg = 30.0;
inline constexpr double kDefaultResist = 0.05;

struct Class {
  std::uint16_t id = 0;      ///< 0..65534; keep below 256 where the grid stores a u8
  std::string name;
  Kind kind = Kind::area;
  std::uint8_t priority = 1;   ///< 1 skin, 2..10 decals (roads 10), 99 objects
  std::uint16_t rank = 0;      ///< area classes: where two overlap, the higher rank wins
  std::uint32_t upperRgb = 0;  ///< 0xRRGGBB, upper triangle
  std::uint32_t lowerRgb = 0;  ///< 0xRRGGBB, lower triangle
  std::uint16_t material = 0;
  std::uint16_t texture = 0;
  double width = 0;            ///< line classes: default width in metres
  /// Area classes: > 0 makes the class's footprints extruded buildings
  /// (walls and a flat roof at priority 99) instead of skin polygons; the
  /// height of a footprint with neither `height` nor `building:levels`.
  double extrude = 0;
  double storey = kDefaultStorey;  ///< metres per `building:levels` level
  /// Soil (seed VII.B.2.b): the slope, degrees, at which a vehicle at rest
  /// starts to slide, and the resistive force opposing motion along the
  /// surface as a fraction of the vehicle's weight (a rolling resistance).
  double stickDeg = kDefaultStickDeg;
  double resist = kDefaultResist;
  /// Water: ships may sail here, land vehicles turn back (seed VIII.A.2).
  bool water = false;
  bool operator==(const Class&) const = default;
};

/// One mapping rule: when the feature's `key` equals `value` ("*" = any
/// non-empty value; values compare ASCII case-insensitively), it gets
/// `className`. key "layer" matches the source layer name. Rules are tried
/// in file order and only rules whose class kind fits the geometry (lines:
/// line classes, polygons: area classes) are considered; the first match
/// wins. className "-" (kIgnoreClass) ignores the feature.
struct Rule {
  std::string key;
  std::string value;
  std::string className;
  std::string widthField;  ///< optional: attribute holding a width in metres
  bool operator==(const Rule&) const = default;
};

/// How placed objects vary: a uniform scale in [scaleMin, scaleMax] and a
/// heading uniform over the turn, from a hash of the seed and the position
/// (the same object for the same seed, whatever the module size).
struct Variation {
  double scaleMin = 1, scaleMax = 1;
  bool operator==(const Variation&) const = default;
};

/// `scatter CLASS icon=NAME density=N [scale=A..B] [seed=S]`: areas of an
/// area class get the icon at N objects per hectare (seed chapter V.F,
/// beyond its hand-placed icons: forests with trees), never under a decal
/// (a road, a river) nor on another class.
struct Scatter {
  std::string className;
  std::string icon;
  double perHectare = 0;  ///< (0, 10000]
  Variation variation;
  std::uint64_t seed = 1;
  bool operator==(const Scatter&) const = default;
};

/// `place KEY=VALUE icon=NAME [scale=A..B]`: point features whose
/// attribute matches (as rules match: * any, case-insensitive) become the
/// icon. The first matching place line wins.
struct Place {
  std::string key;
  std::string value;
  std::string icon;
  Variation variation;
  bool operator==(const Place&) const = default;
};

struct Table {
  std::vector<Class> classes;
  std::vector<Rule> rules;
  std::vector<Scatter> scatters;
  std::vector<Place> places;
  std::uint16_t defaultArea = 0;  ///< class for skin not covered by any feature and for unknown areas
  std::uint16_t defaultLine = 0;  ///< class for unknown line features; kNoClass: they are ignored

  const Class* find(std::uint16_t id) const;
  const Class* findByName(const std::string& name) const;
  bool operator==(const Table&) const = default;
};

/// Parses the text format. Every problem names the file and the byte offset
/// of the offending line, with what is wrong and how to fix it.
Result<Table> parse(std::span<const std::byte> text, const std::string& file);
/// Reads and parses a file (refuses files over 4 MiB).
Result<Table> readFile(const std::string& path);
/// Canonical text; parse(format(t)) == t.
std::string format(const Table& t);

/// Attribute lookup for classification: returns the value of `key` for the
/// feature, or nullopt when it has no such attribute.
using AttributeFn = std::optional<std::string> (*)(const void* feature, const std::string& key);

/// Result of classifying one feature.
struct Match {
  std::uint16_t classId = 0;  ///< kNoClass: ignore the feature (rule "-", or default-line none)
  double width = 0;      ///< from the rule's width field, else the class default
  bool matched = false;  ///< false: fell back to a default class (a warning)
};

/// The place line a point feature matches, or nullptr.
const Place* placeFor(const Table& t, const std::string& layer, const void* feature, AttributeFn attr);

/// Applies the rules. `layer` is the source layer name; `attr` reads the
/// feature's attributes. `isLine` selects the default when no rule matches.
Match classify(const Table& t, const std::string& layer, const void* feature, AttributeFn attr,
               bool isLine);

}  // namespace sandtable::materials
