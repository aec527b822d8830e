#pragma once
// Scenario files (`sandtable-scenario 1`, docs/SCRIPTS.md §5): the
// entities a simulation starts with, one `entity` line each, `group`
// lines that scatter many entities at random (placed by the seed), and
// pre-placed terrain edits (`crater`, `berm`, `ditch`, `flatten`: the ground
// as it is when the simulation starts; docs/DYNAMIC.md). The reader checks
// every word and reports each problem with its line and column; positions
// stay as written (lon/lat or easting/northing): the simulator converts
// them to the database frame with its own transformer.
//
// The enums here name the file's words. They carry a Scenario prefix so
// that they never clash with the simulator's own entity types, which map
// from them.
//
// Thread safety: pure functions on caller-owned values.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/edit.h"

namespace sandtable::sim {

enum class ScenarioFrame { lonLat, projected };
enum class ScenarioDomain { land, sea, air, munition };
/// How an entity moves: `simple` is the seed's Table 5 first-order
/// control; the others are the simulator's dynamics models.
enum class ScenarioMobility { simple, tracked, wheeled, ship, aircraft };

/// Force numbers of the force names; any 0..255 may be written.
inline constexpr std::uint8_t kScenarioNeutral = 0;
inline constexpr std::uint8_t kScenarioBlue = 1;
inline constexpr std::uint8_t kScenarioRed = 2;
inline constexpr std::uint8_t kScenarioGreen = 3;

/// Computer-generated behaviours (seed chapter VII) an entity runs.
struct ScenarioBehaviour {
  bool zigzag = false;       ///< random course changes
  bool environment = false;  ///< steer away from terrain it cannot cross
  bool edge = false;         ///< turn back at the database edge
  bool fight = false;        ///< fight or flight when an enemy is near
  bool engage = false;       ///< armed: fire at enemies in range and sight (beyond the seed)
  bool any() const { return zigzag || environment || edge || fight || engage; }
  bool operator==(const ScenarioBehaviour&) const = default;
};

/// One entity as the file gives it.
struct EntitySpec {
  std::string name;
  std::string icon;
  std::uint8_t force = kScenarioNeutral;
  ScenarioDomain domain = ScenarioDomain::land;
  ScenarioMobility mobility = ScenarioMobility::tracked;
  /// at=A,B as written: lon,lat (lonLat true) or easting,northing.
  /// Unset only for a scripted entity without at= (its script places it).
  std::optional<double> a, b;
  bool lonLat = true;
  double headingDeg = 0;  ///< clockwise from north, [0, 360)
  double speedMs = 0;     ///< the file's km/h in m/s
  std::optional<double> altitude;  ///< metres above the datum (air, munition)
  std::optional<double> agl;       ///< metres above the ground (air, munition)
  ScenarioBehaviour behaviour;
  std::string script;                       ///< resolved path, "" when none
  std::optional<std::uint32_t> scriptEntity;  ///< Entity_Number in the script
  std::string aircraft;                     ///< resolved path, "" when none
  bool driven = false;
  double fuel = 1.0;  ///< fraction of a full tank, 0..1
  int line = 0;
};

/// `group COUNT ...`: COUNT entities scattered over an area.
struct GroupSpec {
  std::string name;  ///< name= or "groupN" (N: the group's place among groups, from 1)
  int count = 0;
  std::string icon;
  std::uint8_t force = kScenarioNeutral;
  ScenarioDomain domain = ScenarioDomain::land;
  ScenarioMobility mobility = ScenarioMobility::tracked;
  /// area=MINA,MINB,MAXA,MAXB in the file's frame.
  double minA = 0, minB = 0, maxA = 0, maxB = 0;
  bool lonLat = true;
  double headingMinDeg = 0, headingMaxDeg = 360;
  double speedMinMs = 0, speedMaxMs = 0;
  std::optional<double> altitudeMin, altitudeMax;
  std::optional<double> aglMin, aglMax;
  ScenarioBehaviour behaviour;
  std::string aircraft;
  double fuel = 1.0;
  int line = 0;
};

/// Caps the reader checks before it allocates: points in one line= or
/// polygon=, and terrain edit lines in a file.
inline constexpr std::size_t kMaxScenarioEditPoints = 4096;
inline constexpr std::size_t kMaxScenarioEdits = 100000;
/// A berm's, ditch's or flatten's side slope (rise over run) when the line
/// gives no slope=.
inline constexpr double kScenarioDefaultSlope = 0.5;

/// One `crater`, `berm`, `ditch` or `flatten` line: a terrain edit made
/// before the first step. The fields are edit::Edit's (edit.h), with the
/// points in the file's frame as written; makeTerrainEdits (scenario_load.h)
/// converts them to the database frame.
struct TerrainEditSpec {
  edit::Kind kind = edit::Kind::crater;  ///< crater, berm, ditch or flatten
  /// at= (crater, one point), line= (berm and ditch, a polyline of 2 or
  /// more) or polygon= (flatten, 3 or more, closed implicitly): A,B pairs
  /// as written, lon,lat (lonLat true) or easting,northing.
  std::vector<std::array<double, 2>> points;
  bool lonLat = true;
  double radius = 0;     ///< crater: rim crest radius, metres (size= or radius=)
  double depth = 0;      ///< crater: centre depth below the ground before, metres
  double width = 0;      ///< berm crest / ditch floor width, metres
  double height = 0;     ///< berm height= , ditch depth=, flatten height= (absolute, above the datum), metres
  double sideSlope = 0;  ///< berm, ditch, flatten: slope=, rise over run (kScenarioDefaultSlope)
  int line = 0;
};

struct Scenario {
  ScenarioFrame frame = ScenarioFrame::lonLat;
  std::optional<std::uint64_t> seed;
  std::vector<EntitySpec> entities;
  std::vector<GroupSpec> groups;
  std::vector<TerrainEditSpec> terrainEdits;  ///< file order
  std::optional<std::size_t> driven;  ///< index into entities
  std::string source;                 ///< the file name given to the reader
};

/// Reads a scenario. `name` is the file: relative script= and aircraft=
/// paths are resolved against its directory. Every problem (up to 20) is
/// reported with Problem::file = name, Problem::offset = the byte offset of
/// the bad word and a message "line N, column M: what; how to fix".
Result<Scenario> parseScenario(std::string_view text, const std::string& name);
Result<Scenario> readScenarioFile(const std::string& path);

/// The k-th member (1-based) of a group, placed and set going by `seed`
/// (deterministic: splitmix64 of the seed, the group's name and k, never
/// std::random): uniform over the area (in the file's frame), heading
/// and speed uniform over their ranges, altitude / agl likewise. Named
/// "NAME.k" ('.' is not allowed in names, so no entity has it).
EntitySpec groupMember(const GroupSpec& group, int k, std::uint64_t seed);
/// Every member, k = 1 .. count.
std::vector<EntitySpec> expandGroup(const GroupSpec& group, std::uint64_t seed);

/// The file's words for the enums ("land", "tracked", "lonlat").
std::string_view scenarioWord(ScenarioDomain d);
std::string_view scenarioWord(ScenarioMobility m);
std::string_view scenarioWord(ScenarioFrame f);

}  // namespace sandtable::sim
