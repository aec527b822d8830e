#pragma once
// Munitions (seed VII.C.1, Figures 27 and 59): ballistic and guided flight,
// the impact with the terrain found by a binary search along the last
// step's segment, and swept volumes against objects and entities.
//
// Thread safety: pure functions of their arguments.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/sim/entity.h"
#include "sandtable/sim/sim_world.h"

namespace sandtable::sim {

/// A kind of munition. The built-in table holds a guided missile and a
/// ballistic tank round.
/// The crater a munition leaves where it hits the ground (dynamic terrain,
/// docs/DYNAMIC.md): the seed's small, medium and large (edits/profile.h
/// gives their radius and depth), or none.
enum class CraterSize : std::uint8_t { none, small, medium, large };
const char* craterSizeName(CraterSize s);

struct MunitionType {
  std::string name;
  bool guided = false;
  double speedMs = 300;       ///< muzzle or cruise speed
  double turnRateDegS = 30;   ///< guided: steering limit
  double lifeS = 20;          ///< detonates in the air after this long
  double radius = 0.2;        ///< its own size for the swept tests
  CraterSize crater = CraterSize::none;  ///< left where it hits the ground
};
const std::vector<MunitionType>& builtinMunitions();

/// Where the segment a -> b first meets the ground (Figure 27): a is above
/// the ground, b is not; the crossing is bracketed and halved until the
/// bracket is shorter than `toleranceM`. nullopt when b is above the
/// ground too or off the grid.
std::optional<Eigen::Vector3d> terrainImpact(const SimWorld& world, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                             double toleranceM = 0.01);

/// The fraction t in [0, 1] along a -> b at which a sphere of `r` around
/// the segment first touches the upright cylinder (centre (cx, cz), radius,
/// from baseY up `height`), or nullopt: the swept volume of Figure 59.
std::optional<double> sweptHitsCylinder(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r, double cx,
                                        double cz, double radius, double baseY, double height);

/// The fraction t along a -> b at which the segment comes within `r` of
/// `centre`, or nullopt.
std::optional<double> sweptHitsSphere(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r,
                                      const Eigen::Vector3d& centre);

/// One step of a munition's flight: ballistic under gravity, or guided
/// towards `target` (when given) at its speed with the turn-rate limit.
void stepMunition(Entity& m, const MunitionType& type, const std::optional<Eigen::Vector3d>& target, double dt);

}  // namespace sandtable::sim
