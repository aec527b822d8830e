#pragma once
// Entity scripts (seed chapter VIII.B, Figure 71 and Figure 73; format in
// docs/SCRIPTS.md): the reader and the writer of the seed's script lines,
// the playback cursor, the dead-reckoning recorder of the driven entity,
// the merge of a played and a recorded script ("play and record"), and the
// conversion of a Table 7 path into a script.
//
// A script line, one per entity state, 15 whitespace-separated fields:
//   Hours Minutes Seconds Entity_Number Entity_Type X_Position Y_Position
//   Z_Position Direction View_Direction Gun_Elevation Above_Ground_Level
//   Speed Fire_Flag Alive_Flag
// X and Z are database coordinates in metres (x east of the grid's
// north-west corner, z south of it), Y is up and 0.0 means "follows the
// ground"; Direction is degrees clockwise from north; Speed is m/s.
//
// Thread safety: the free functions are pure. ScriptPlayer and
// ScriptRecorder are value types: distinct objects may be used from any
// threads, one object from one thread at a time.
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "sandtable/base/result.h"

namespace sandtable::world {
struct Path;
}

namespace sandtable::sim {

/// Fields of one script line (Figure 71).
inline constexpr int kScriptFields = 15;

/// The writer's time resolution, seconds: times are written to the
/// microsecond.
inline constexpr double kScriptTimeResolutionS = 1e-6;

/// One script line: a time stamp and one entity's state.
struct ScriptLine {
  /// Seconds since the start of the scenario: hours * 3600 + minutes * 60
  /// + seconds. The reader and setTime keep the four in step; the writer
  /// writes timeS (rounded to the microsecond).
  double timeS = 0;
  int hours = 0, minutes = 0;
  double seconds = 0;
  std::uint32_t entity = 0;  ///< Entity_Number
  std::uint32_t type = 0;    ///< Entity_Type (selects the icon)
  double x = 0, y = 0, z = 0;
  double directionDeg = 0;      ///< heading, degrees clockwise from north
  double viewDirectionDeg = 0;  ///< turret / view direction, degrees
  double gunElevation = 0;      ///< as the file gives it (the seed's unit is not stated)
  double aboveGroundLevel = 0;  ///< as the file gives it
  double speed = 0;             ///< m/s, along directionDeg
  bool fire = false;
  bool alive = true;
  int line = 0;  ///< source line, 0 when built in code

  /// Sets timeS and splits it into hours, minutes and seconds (rounded to
  /// the microsecond, as the writer writes them). Negative or non-finite
  /// times become 0.
  void setTime(double t);
};

/// Reads a script. Blank lines and `#` comments are allowed. Every problem
/// (up to 20) is reported with Problem::file = name, Problem::offset = the
/// byte offset of the bad token and a message "line N, column M: ...".
Result<std::vector<ScriptLine>> parseScript(std::string_view text, const std::string& name);
/// The same on a file.
Result<std::vector<ScriptLine>> readScriptFile(const std::string& path);

/// One line in the seed's layout, without the newline: "00 00 11 59 2
/// 8161.926270 0.0 8174.560547 135.989869 ...". Hours and minutes two
/// digits; seconds two digits when whole, else "%09.6f" ("05.500000");
/// entity and type as integers; the floats "%f", except a Y of exactly 0,
/// written "0.0" as the seed writes its ground-following marker; flags 0/1.
std::string formatScriptLine(const ScriptLine& line);
/// Every line, each followed by '\n'.
std::string formatScript(const std::vector<ScriptLine>& lines);

/// An entity a script drives: its number and the type of its first line.
struct ScriptEntity {
  std::uint32_t entity = 0;
  std::uint32_t type = 0;
  double firstTimeS = 0;  ///< time of its first line
};
/// Distinct entities in order of first appearance.
std::vector<ScriptEntity> scriptEntities(const std::vector<ScriptLine>& lines);

/// Where a line's entity is at `timeS` by dead reckoning: straight on at
/// the line's direction and speed from the line's time (x += sin(dir) *
/// speed * dt, z -= cos(dir) * speed * dt; north is -z). Before the line's
/// time it is at the line's position. Returns (x, z). Purely geometric: the
/// caller stops dead entities.
Eigen::Vector2d deadReckon(const ScriptLine& line, double timeS);

/// Playback (Figure 73): a cursor over the lines. Each call applies every
/// line whose time is at or before `nowS` (within half of
/// kScriptTimeResolutionS, so a line written at a step's time and read
/// back is due at that step), in order; a line whose entity
/// is dead is skipped (consumed, not applied), so a killed entity is not
/// reincarnated by its later lines (the seed's one deviation from the
/// script).
class ScriptPlayer {
 public:
  ScriptPlayer() = default;
  /// The lines, sorted by time if they are not (stable: equal times keep
  /// their order).
  explicit ScriptPlayer(std::vector<ScriptLine> lines);

  /// Applies the due lines. `isAlive` may be empty (every entity alive).
  /// Returns the number of lines applied (skipped lines not counted).
  std::size_t advance(double nowS, const std::function<bool(std::uint32_t entity)>& isAlive,
                      const std::function<void(const ScriptLine&)>& apply);
  bool finished() const { return cursor_ >= lines_.size(); }
  /// Index of the next line to apply.
  std::size_t cursor() const { return cursor_; }
  /// Back to the first line (replay for an after-action review).
  void rewind() { cursor_ = 0; }
  /// Time of the next line, or the last line's time when finished (0 when empty).
  double nextTimeS() const;
  const std::vector<ScriptLine>& lines() const { return lines_; }
  /// The entities the script drives, so the simulator can create them.
  std::vector<ScriptEntity> entities() const { return scriptEntities(lines_); }

 private:
  std::vector<ScriptLine> lines_;
  std::size_t cursor_ = 0;
};

struct RecorderOptions {
  /// A line is emitted when dead reckoning from the last line would put
  /// the entity more than this far (metres, horizontal) from where it is.
  double toleranceM = 0.005;
  /// ... or when this long has passed since the last line (a heartbeat;
  /// <= 0: none).
  double maxIntervalS = 1.0;
  /// ... or when direction, view direction or gun elevation moved by more
  /// than this (degrees, or the field's own unit for the gun).
  double angleToleranceDeg = 0.5;
  /// ... or when the speed changed by more than this, m/s.
  double speedToleranceMs = 0.05;
  /// ... or when Y or Above_Ground_Level changed by more than this, metres.
  double heightToleranceM = 0.05;
};

/// Data logging of the driven entity (seed VIII.B.2): offered the entity's
/// state every step, it keeps a line whenever the state changed beyond the
/// tolerances, or fire / alive / type changed, or dead reckoning from the
/// last line would miss the true position by more than toleranceM. Played
/// back with deadReckon, the position at every offered time is then within
/// toleranceM (plus the writer's 1e-6 rounding) of the recorded one.
class ScriptRecorder {
 public:
  explicit ScriptRecorder(RecorderOptions options = {}) : options_(options) {}

  /// Offers the state at state.timeS (hours/minutes/seconds are ignored
  /// and set from it). Returns true when a line was emitted. A state
  /// earlier than the last one offered, or not finite, is ignored
  /// (returns false).
  bool record(const ScriptLine& state);
  /// Emits the last offered state if it was not emitted, so the script
  /// ends where the entity ended.
  void finish();
  const std::vector<ScriptLine>& lines() const { return lines_; }
  std::string text() const { return formatScript(lines_); }

 private:
  bool changed(const ScriptLine& last, const ScriptLine& now) const;

  RecorderOptions options_;
  std::vector<ScriptLine> lines_;
  ScriptLine pending_;
  bool hasPending_ = false;  ///< pending_ holds a state not emitted
  bool hasOffered_ = false;
  double lastOfferedS_ = 0;
};

/// Play and record at once (seed VIII.B.2, "compound script"): the lines
/// of both, in time order; at equal times the played lines come first
/// (stable). Each input is sorted first (stable) if it is not.
std::vector<ScriptLine> mergeScriptLines(const std::vector<ScriptLine>& played,
                                         const std::vector<ScriptLine>& recorded);
/// The same, formatted (formatScript).
std::string mergeScripts(const std::vector<ScriptLine>& played, const std::vector<ScriptLine>& recorded);

/// Problem::file of scriptFromPath's problems.
inline constexpr const char* kScriptProblem = "script";

/// A resolved path (seed Table 7, world::parsePath) as a script for one
/// entity: one line per leg at the leg's start time, at the leg's start
/// waypoint, direction = the leg's bearing, speed = its mean speed (length
/// / duration, so dead reckoning to the next line lands on the next
/// waypoint); then a last line at the last waypoint with speed 0. A
/// zero-length leg (a wait) has speed 0 and keeps the bearing of the
/// nearest moving leg. x = easting - originEasting, z = originNorthing -
/// northing (origin: the grid's north-west corner); y = 0 (follows the
/// ground: the path's heights are not carried), alive 1, fire 0.
Result<std::vector<ScriptLine>> scriptFromPath(const world::Path& path, std::uint32_t entity,
                                               std::uint32_t type, double originEasting,
                                               double originNorthing);

}  // namespace sandtable::sim
