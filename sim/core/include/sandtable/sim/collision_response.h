#pragma once
// Collision response (seed VII.C, Table 6 and Figures 62-66), once a
// collision has been detected:
//  - moving/static: the entity/object response table (Table 6) as
//    editable text ("sandtable-collisions 1", docs/COLLISIONS.md), its
//    speed bins and the lookup;
//  - moving/moving: Figure 64's rule by impact angle and speed, with the
//    glancing bounce of Figure 66;
//  - the contact point: one ray from A's origin to B's origin through
//    both icons' triangles (Figures 62-63).
//
// Frames: world positions in the moving/moving part are 2D (x east,
// z south, metres), headings are degrees clockwise from north (north is
// -z). Icon triangles are in the icon's body frame; an Affine3d takes
// them to the world.
//
// Thread safety: pure functions over values; a CollisionTable is a value
// that may be read from any number of threads at once. The built-in
// table is built once, on first use, thread-safely.
#include <array>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "sandtable/base/result.h"

namespace sandtable::sim {

// ------------------------------------------------------------ moving/static

/// What a collision does to the moving entity.
enum class EntityResult { none, stop, destroyed };
/// What a collision does to the static object.
enum class ObjectResult { none, knockedOver, stump, ruins, destroyed };

/// The table's words: "none", "stop", "destroyed"; "none",
/// "knocked-over", "stump", "ruins", "destroyed".
std::string_view resultName(EntityResult r);
std::string_view resultName(ObjectResult r);

/// One cell of Table 6: entity result / object result.
struct StaticOutcome {
  EntityResult entity = EntityResult::stop;
  ObjectResult object = ObjectResult::none;
  bool operator==(const StaticOutcome&) const = default;
};

/// Slow below mediumKmh, medium from mediumKmh below fastKmh, fast from
/// fastKmh up (mediumKmh <= fastKmh; equal edges leave no medium bin).
struct SpeedEdges {
  double mediumKmh = 0;
  double fastKmh = 0;
  bool operator==(const SpeedEdges&) const = default;
};

enum class SpeedBin { slow = 0, medium = 1, fast = 2 };

/// The three cells of one row, indexed by SpeedBin.
using BinOutcomes = std::array<StaticOutcome, 3>;

/// A parsed collision table. Class names are case-sensitive; the
/// simulator's classes are "tank" (land vehicles), "airplane" (air),
/// "missile" (munitions) and "tree", "house" (houses and buildings),
/// "rock" (every other object).
struct CollisionTable {
  /// Entity class -> its speed bins.
  std::map<std::string, SpeedEdges, std::less<>> speeds;
  /// Entity class -> object class -> the row's three cells. Every entity
  /// class here has a speeds entry (the parser insists).
  std::map<std::string, std::map<std::string, BinOutcomes, std::less<>>, std::less<>> results;
  /// The answer for a pair with no row, at any speed ("default" line;
  /// stop/none when the file has none).
  StaticOutcome unknown{EntityResult::stop, ObjectResult::none};
  bool operator==(const CollisionTable&) const = default;
};

/// Parses the text of a collision table. `name` is the file name the
/// problems carry. Every problem has Problem::offset at the bad token and
/// a message "line N, column M: what is wrong and how to fix it".
Result<CollisionTable> parseCollisionTable(std::string_view text, const std::string& name);

/// Reads and parses the file at `path` (at most 1 MiB).
Result<CollisionTable> readCollisionTable(const std::string& path);

/// The built-in table: seed Table 6, the same text as samples/collisions.txt.
const CollisionTable& defaultCollisionTable();
/// Its text, for a user to copy and edit.
std::string_view defaultCollisionTableText();

/// The bin of `speedMs` (m/s; its magnitude counts, NaN is slow) for
/// `entityClass`. An edge speed falls in the faster bin; the edges are
/// compared as kmh / 3.6, so a caller passing edge / 3.6 lands exactly on
/// it. A class with no speeds line is always slow.
SpeedBin speedBin(const CollisionTable& table, std::string_view entityClass, double speedMs);

/// Table 6's cell for an entity of `entityClass` hitting an object of
/// `objectClass` at `speedMs`; table.unknown when the pair has no row.
StaticOutcome lookup(const CollisionTable& table, std::string_view entityClass, std::string_view objectClass,
                     double speedMs);

// ------------------------------------------------------------ moving/moving

/// Figure 64's sectors of the impact angle.
enum class ImpactKind { front, right, rear, left, glancing };

/// The sector of a bearing relative to the entity's heading, degrees
/// clockwise (any value; reduced to [0, 360)). Bounds are inclusive as in
/// Figure 64: front <= 5 or >= 355, right 85..95, rear 175..185, left
/// 265..275, anything else (and NaN) glancing.
ImpactKind classifyImpact(double relativeBearingDeg);

/// One moving entity in the ground plane.
struct MovingState {
  Eigen::Vector2d position{0, 0};  ///< x east, z south, metres
  Eigen::Vector2d velocity{0, 0};  ///< m/s, same axes
  double headingDeg = 0;           ///< clockwise from north
};

struct MovingOutcome {
  bool killA = false, killB = false;  ///< catastrophic kill (velocities zero)
  bool stopA = false, stopB = false;  ///< stopped, alive (velocities zero)
  Eigen::Vector2d newVelocityA{0, 0}, newVelocityB{0, 0};
  double newHeadingA = 0, newHeadingB = 0;  ///< degrees [0, 360)
  ImpactKind kindA = ImpactKind::glancing;  ///< B's bearing seen from A; decides the response
  ImpactKind kindB = ImpactKind::glancing;  ///< A's bearing seen from B; reported only
};

/// The fraction of speed a glancing bounce keeps unless told otherwise.
inline constexpr double kDefaultBounceKeep = 0.5;

/// Figure 64. The impact angle is B's bearing from A relative to A's
/// heading (snapped to a whole degree when within 1e-9 of one, so that
/// positions built from an edge angle land on it). Front, right, rear or
/// left: when the closing speed |vA - vB| (the relative speed) is above
/// killSpeedMs both are killed, else both stop. Glancing: each velocity's
/// component along the line of centres is turned to point away from the
/// other (reflected when it points at the other, kept when it already
/// points away), the tangential component is kept, and the whole is
/// scaled by bounceKeep (clamped to [0, 1]); headings follow the new
/// velocities (unchanged where a velocity is zero). Coincident positions
/// count as a front impact along A's heading.
MovingOutcome resolveMoving(const MovingState& a, const MovingState& b, double killSpeedMs,
                            double bounceKeep = kDefaultBounceKeep);

// ------------------------------------------------------------ contact point

/// One icon triangle in its body frame.
struct Triangle {
  Eigen::Vector3f a, b, c;
};

/// Möller-Trumbore: the t >= 0 at which origin + t * dir meets the
/// triangle (edges included, to 1e-9 in barycentric terms), or nullopt
/// (a miss, a ray parallel to the plane, a degenerate triangle). t is in
/// units of |dir|.
std::optional<double> rayTriangle(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Triangle& tri);

struct Contact {
  bool hit = false;
  Eigen::Vector3d worldPoint{0, 0, 0};
  Eigen::Vector3d bodyPointA{0, 0, 0}, bodyPointB{0, 0, 0};
  double distA = 0;  ///< A's origin to where the ray leaves A's triangles (0: no hit on A)
  double distB = 0;  ///< B's origin back along the ray to where it leaves B's triangles
};

/// Figures 62-63: one ray from A's origin to B's origin. distA is the
/// farthest hit on A's triangles along it, distB the farthest hit on B's
/// triangles along the reversed ray from B's origin (world metres). When
/// distA + distB < the distance between the origins there is no collision
/// (hit = false); otherwise hit, and the contact point is the middle of
/// the overlap [D - distB, distA] along the ray, given in world and in
/// each body frame. Coincident origins: hit, at the origin.
Contact contactPoint(const std::vector<Triangle>& trisA, const Eigen::Affine3d& bodyToWorldA,
                     const std::vector<Triangle>& trisB, const Eigen::Affine3d& bodyToWorldB);

}  // namespace sandtable::sim
