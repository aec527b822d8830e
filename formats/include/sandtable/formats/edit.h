#pragma once
// One change to the terrain while the world runs (dynamic terrain, issue
// 37; seed chapter V.G): a crater where a round hit, a berm or a ditch
// along a line, a polygon flattened to a height, or a change to a static
// object. An edit is a plain value: the journal stores it
// (edit_journal.h, docs/FORMAT.md), DIS carries it (Point and Linear Object
// State PDUs), and runtime/edits applies it. Applying it is a
// deterministic function of its parameters and the heights under it
// (docs/DYNAMIC.md gives the profiles), so two processes that apply the
// same edits in the same order hold bit-identical heights.
//
// Positions are in the database frame (world X east, Z south of the grid's
// north-west post, metres; docs/ARCHITECTURE.md): the edit needs no
// projection to be applied, and a receiver converts from geocentric once.
//
// Thread safety: plain values.
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace sandtable::edit {

enum class Kind : std::uint8_t {
  crater = 1,         ///< bowl and rim at points[0]: radius, depth (at the centre, below the ground before)
  berm = 2,           ///< raised trapezoid along points: width (crest), height, sideSlope
  ditch = 3,          ///< sunk trapezoid along points: width (floor), height (depth), sideSlope
  flatten = 4,        ///< polygon points set to height (absolute, metres), sideSlope blends outside
  addObject = 5,      ///< a static object of icon `icon` at points[0], heading, scale
  removeObject = 6,   ///< object `object` (module object id, in module `module`) removed
  switchObject = 7,   ///< object `object` shows icon `icon` (the seed's model switching)
  scaleObject = 8,    ///< object `object` scaled by `scale` (the seed's scaling)
};
inline constexpr std::uint8_t kMaxKind = 8;

/// "crater", "berm", ... ; "unknown" for a value out of range.
std::string_view kindName(Kind k);

/// Who made an edit: 0 is this process's own (the CLI, a scenario line,
/// the local simulation); a DIS sender is site << 16 | application.
using Origin = std::uint32_t;

struct Edit {
  std::uint64_t id = 0;     ///< unique per origin, increasing in the order the origin made them
  double time = 0;          ///< simulation seconds when it was made
  Origin origin = 0;
  Kind kind = Kind::crater;
  /// Database-frame (x, z) metres: crater and addObject one point, berm and
  /// ditch a polyline of at least two, flatten a polygon of at least three
  /// (closed implicitly).
  std::vector<std::array<double, 2>> points;
  double radius = 0;     ///< crater: rim crest radius, metres
  double depth = 0;      ///< crater: centre depth below the ground before, metres
  double width = 0;      ///< berm crest / ditch floor width, metres
  double height = 0;     ///< berm height, ditch depth, flatten's absolute height, metres
  double sideSlope = 0;  ///< rise over run of the sides (berm, ditch, flatten's blend), > 0
  std::uint16_t icon = 0;      ///< addObject, switchObject
  double heading = 0;          ///< addObject, radians clockwise from north
  double scale = 1;            ///< addObject, scaleObject
  std::uint32_t moduleX = 0, moduleZ = 0;  ///< removeObject/switchObject/scaleObject: the object's module
  std::uint64_t object = 0;    ///< module object id (module::Object::id)
  std::uint16_t munition = 0;  ///< crater: the munition kind that made it (0: unknown); informative
  bool operator==(const Edit&) const = default;
};

/// True for the kinds that change heights (crater .. flatten).
inline constexpr bool changesHeights(Kind k) { return k >= Kind::crater && k <= Kind::flatten; }

/// Checks the parameters an edit of its kind needs (finite, positive where
/// they must be, enough points); the message names the field
/// ("edit: crater: Edit::radius must be > 0 (got -1)"; the CLI maps the
/// field to its flag). Empty when valid.
std::string checkEdit(const Edit& e);

}  // namespace sandtable::edit
