#pragma once
// What moves or changes in a frame, as plain values for the renderer
// (docs/VIEWER.md, "Entities"): entities drawn with an icon and a full
// orientation, munition trails, detonation flashes, and the static objects
// whose look a simulation changed. The application (the viewer, which
// links the simulator) fills a DynamicScene per frame on its main thread;
// the renderer, which never sees the simulator, only reads it. Layering:
// scene and render know nothing of sim/ (docs/ARCHITECTURE.md).
//
// World frame (terrain.h): x east and z south of the grid's north-west
// post, y up, metres. Body frame (the icons'): forward -Z, up +Y, right +X.
//
// Thread safety: plain values; one thread fills a DynamicScene, another
// reads it only after the hand-over (the display buffer's).
#include <algorithm>
#include <array>
#include <cstdint>
#include <tuple>
#include <utility>
#include <vector>

namespace sandtable::scene {

/// An entity to draw this frame.
struct DynamicInstance {
  std::uint16_t icon = 0;  ///< index into icons.pack
  bool dead = false;       ///< draw the icon's dead state (its alive state when it has none)
  /// Stands on the terrain (land vehicles, ships): its y is on the finest
  /// surface (level 0), and the renderer moves it by the difference to the
  /// level of detail drawn under it, so it neither floats nor sinks.
  bool onSurface = false;
  /// Draw a soft contact shadow on the ground under it (land vehicles).
  bool shadow = false;
  double x = 0, y = 0, z = 0;  ///< the icon's origin, world metres
  /// Body-to-world rotation, a unit quaternion (x, y, z, w).
  std::array<float, 4> orientation{0, 0, 0, 1};
  /// The icon's `turret` part (and its children) turned about its ring,
  /// degrees clockwise seen from above, relative to the hull.
  float turretAzimuthDeg = 0;
  /// The icon's `gun` part (and its children) pitched about its own X
  /// axis at its origin (the trunnion), degrees, positive raising the
  /// muzzle; in the turret's frame when the gun hangs from the turret.
  float gunElevationDeg = 0;
  std::uint8_t force = 0;  ///< 0 neutral, 1 blue, 2 red, 3 green
  float scale = 1;
};

/// One point of a trail and how long ago it was passed.
struct TrailPoint {
  double x = 0, y = 0, z = 0;
  float ageS = 0;
};

/// A munition's smoke or tracer: its last positions, newest last; it fades
/// with age and is gone at lifeS.
struct Trail {
  std::vector<TrailPoint> points;
  std::array<std::uint8_t, 3> rgb{236, 236, 228};
  float lifeS = 2;
};

/// A detonation's flash: an expanding fireball for durationS seconds.
struct Flash {
  double x = 0, y = 0, z = 0;
  float ageS = 0;
  float durationS = 0.5f;
  float radiusM = 6;  ///< at its largest
};

/// What a static object of the load modules has become (seed Table 6).
enum class ObjectLook : std::uint8_t {
  standing,     ///< as built (an override to this is a no-op)
  knockedOver,  ///< its alive model lying on the ground
  stump,        ///< its dead model (the alive one when it has none)
  ruins,        ///< its dead model (the alive one when it has none)
  destroyed,    ///< not drawn
};

/// Object `index` of module (moduleX, moduleZ) looks like `look`.
struct ObjectOverride {
  std::uint32_t moduleX = 0, moduleZ = 0, index = 0;
  ObjectLook look = ObjectLook::standing;
  auto key() const { return std::tie(moduleZ, moduleX, index); }
  bool operator<(const ObjectOverride& o) const { return key() < o.key(); }
};

struct DynamicScene {
  std::vector<DynamicInstance> instances;
  std::vector<Trail> trails;
  std::vector<Flash> flashes;
  /// Sorted (operator<), one per object.
  std::vector<ObjectOverride> objectOverrides;

  void clear() {
    instances.clear();
    trails.clear();
    flashes.clear();
    objectOverrides.clear();
  }
  bool empty() const { return instances.empty() && trails.empty() && flashes.empty() && objectOverrides.empty(); }
};

/// The overrides of module (kx, kz) in a sorted list: [first, last).
inline std::pair<const ObjectOverride*, const ObjectOverride*> overridesOfModule(
    const std::vector<ObjectOverride>& sorted, std::uint32_t kx, std::uint32_t kz) {
  ObjectOverride lo, hi;
  lo.moduleX = hi.moduleX = kx;
  lo.moduleZ = hi.moduleZ = kz;
  lo.index = 0;
  hi.index = UINT32_MAX;
  const auto* begin = sorted.data();
  const auto* end = begin + sorted.size();
  const auto* first = std::lower_bound(begin, end, lo);
  const auto* last = std::upper_bound(first, end, hi, [](const ObjectOverride& a, const ObjectOverride& b) {
    return a.key() < b.key();
  });
  return {first, last};
}

}  // namespace sandtable::scene
