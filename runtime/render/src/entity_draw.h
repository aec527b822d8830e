#pragma once
// Drawing what moves (docs/VIEWER.md, "Entities"): the DisplayBuffer's
// DynamicScene (scene/dynamic.h) — entities with their icons, munition
// trails and detonation flashes — and the static objects a simulation
// changed (knocked over, stumps, ruins), which the object pass hands over.
// Private to the renderer; every GL call on the render thread.
//
// Meshes. At create() every icon is flattened per state (alive, dead) and
// per level of detail into three groups: the body (every part but these
// two), the turret (the first part named "turret" and its children), and
// the gun (the first part named "gun" and its children, taken out of the
// turret when it hangs from it). The levels share one vertex run per state;
// each has its own index lists, split into the same groups, so the turret
// turns and the gun elevates at every level. The turret's vertices are in
// its own frame so that it turns about its ring (its origin,
// iconpack::partOrigin), the gun's in its own so that it elevates about its
// trunnion (its origin). An icon without dead parts draws its alive parts
// when dead.
//
// Levels. An entity takes its icon's level by the object pass's rule
// (iconLevelAt, no fade) at the near side of its bounding sphere, so it is
// drawn out to where that sphere leaves the far range (capped at the view
// distance), as before the levels; with RenderSettings::objectLod false
// every entity is drawn at level 0 out to there (the benchmark's
// baseline). No impostors, no thinning: entities are not trees.
//
// Instances. Each draw has its origin, scale, a body-to-world quaternion,
// the turret's pivot and angle and the gun's trunnion and elevation (zero
// where the group does not move so); the vertex stage pitches the gun about
// X at its trunnion (in the turret's frame), turns it with the turret about
// Y at the ring (the hull's gun does not turn), then rotates by the
// quaternion (full pitch, roll and heading, where static objects take a
// heading only). Instances are sorted by group: one instanced draw per
// (icon state, level, group) in view, however many entities show it.
//
// Ground. An instance marked onSurface stands on the finest surface (the
// simulator's); it is moved by the difference between the surface drawn
// under it (the level and morph the terrain pass drew there, after the
// upload budget's fallback) and the finest one, so it stands on what is
// drawn (seed Figure 23), as static objects do.
//
// Effects, after the opaque meshes, blended, depth-tested without depth
// writes: a soft contact shadow under every entity that asks for one (a dark rounded
// rectangle over its footprint, in its own tilt, pulled towards the eye by
// a polygon offset), so that what stands on the ground is seen to; trails
// are camera-facing ribbons (at least ~1.5 pixels wide), fading with age;
// flashes are camera-facing fireballs that grow and fade (at least ~10
// pixels across). All built on the CPU each frame.
#include <epoxy/gl.h>

#include <Eigen/Dense>
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "object_draw.h"
#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/render/gl_program.h"
#include "sandtable/render/renderer.h"
#include "sandtable/scene/display_buffer.h"
#include "sandtable/world/ground.h"

namespace sandtable::render::detail {

class ModuleRenderer;

/// One icon state's three groups at one level of detail in the entity
/// buffers (the levels of a state share its vertices and pivots).
struct EntityShape {
  IconLevelRange body, turret, gun;     ///< count 0: none
  std::array<float, 3> pivot{0, 0, 0};  ///< the turret's ring, body frame
  /// The gun's trunnion: in the turret's frame (relative to `pivot`) when
  /// the gun hangs from the turret (gunTurns), else in the body frame.
  std::array<float, 3> gunPivot{0, 0, 0};
  bool gunTurns = false;
  bool textured = false;
};

/// One icon state's shapes, one per level of the icon (Icon::ranges; one,
/// with no indices, when it has none).
using EntityLevels = std::vector<EntityShape>;

/// Every icon flattened for entities: [icon][state][level], state 0 alive,
/// 1 dead (the alive shapes again when the icon has no dead parts). Pure CPU.
struct EntityMeshes {
  std::vector<IconVertex> vertices;
  std::vector<std::uint32_t> indices;
  std::vector<std::array<EntityLevels, 2>> shapes;
  std::vector<float> reach;  ///< per icon: farthest vertex from the origin (bounding sphere), unscaled
  /// Per icon: its alive body's extent (min x, y, z, max x, y, z), the
  /// turret and gun left out (the gun overhangs): the contact shadow's footprint.
  std::vector<std::array<float, 6>> footprint;
};
EntityMeshes flattenEntityIcons(const iconpack::Pack& pack);

/// Body-to-world quaternion (x, y, z, w) of a heading (degrees clockwise
/// from north, seen from above).
std::array<float, 4> headingQuaternion(double headingDeg);
/// A knocked-over object: its heading, then laid down forward (turned
/// -90 degrees about its right axis), so its top points along the heading.
std::array<float, 4> lyingQuaternion(double headingDeg);

/// One entity draw: 64 bytes, divisor 1.
struct EntityInstanceGpu {
  float x, y, z, scale;    ///< origin relative to the buffer origin
  float q[4];              ///< body to world
  float px, py, pz;        ///< turret pivot, body frame (0 for the body)
  float turretRad;         ///< turret angle, clockwise from above (0 for the body)
  float gx, gy, gz;        ///< gun trunnion, turret frame (0 for the body and turret)
  float gunRad;            ///< gun elevation, muzzle up (0 for the body and turret)
};
static_assert(sizeof(EntityInstanceGpu) == 64, "instance layout is shared with the shader");

/// A trail or flash vertex: 24 bytes.
struct EffectVertex {
  float x, y, z;  ///< relative to the buffer origin
  float u, v;     ///< flash: position in the disc (-1..1); trail: v across the ribbon (-1..1)
  std::uint32_t rgba;
};
static_assert(sizeof(EffectVertex) == 24, "vertex layout is shared with the shader");

/// What the effects need of the camera (buffer-relative eye and axes).
struct EffectView {
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();
  Eigen::Vector3d right = Eigen::Vector3d::UnitX(), up = Eigen::Vector3d::UnitY();
  double focal = 1000;  ///< pixels per metre at one metre
  double originX = 0, originZ = 0;
};
EffectView effectViewOf(const scene::DisplayBuffer& buf, std::uint32_t imageHeight);

/// Appends a trail's ribbon (two triangles per segment) facing the eye,
/// at least `minPixels` wide; alpha 0.85 falling to 0 at the trail's life.
void appendTrail(const scene::Trail& trail, const EffectView& view, double minPixels, std::vector<EffectVertex>& out);
/// Appends the contact shadow of an icon with footprint `bounds` (min x,
/// y, z, max x, y, z; EntityMeshes::footprint) standing at `origin` (buffer-relative) turned by
/// `orientation` (x, y, z, w): its footprint grown by 0.5 m, 6 cm up,
/// moved half the way the fixed sun would cast it (terrain_shading.h).
void appendShadow(const Eigen::Vector3d& origin, const std::array<float, 4>& orientation, float scale,
                  const std::array<float, 6>& bounds, std::vector<EffectVertex>& out);
/// Appends a flash's disc (two triangles) facing the eye: its radius grows
/// from 35 % to 100 % of radiusM over its duration, and at least
/// `minPixels` across; nothing once its age passes its duration.
void appendFlash(const scene::Flash& flash, const EffectView& view, double minPixels, std::vector<EffectVertex>& out);

class EntityRenderer {
 public:
  EntityRenderer() = default;
  ~EntityRenderer();
  EntityRenderer(const EntityRenderer&) = delete;
  EntityRenderer& operator=(const EntityRenderer&) = delete;

  /// Compiles the programs and uploads every icon of s.icons (not null).
  /// `textures`: the icon texture array the object pass uploaded (0: this
  /// renderer uploads its own when the pack has textures).
  Status create(const RenderSettings& s, GLuint textures);
  /// The models pass's entities, diverted static objects and effects.
  /// `modules` is null in grid-mesh mode (nothing to re-base on).
  void draw(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, const ModuleRenderer* modules,
            const std::vector<scene::DynamicInstance>& diverted, RenderStats& stats);
  /// One entity, trail and flash into the warm-up frame (llvmpipe compiles at the first draw).
  void warmUp(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection);

 private:
  /// The instance's y on the drawn surface (onSurface), else its own.
  double drawnY(const scene::DisplayBuffer& buf, const ModuleRenderer* modules, const scene::DynamicInstance& d);
  void collect(const scene::DisplayBuffer& buf, const ModuleRenderer* modules, const std::vector<scene::DynamicInstance>& diverted,
               RenderStats& stats);
  void add(const scene::DisplayBuffer& buf, const scene::DynamicInstance& d, double y, const std::array<Eigen::Vector4d, 5>& planes,
           RenderStats& stats);
  void submit(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, RenderStats& stats);
  void drawEffects(const scene::DisplayBuffer& buf, const Eigen::Matrix4f& viewProjection, RenderStats& stats);

  RenderSettings settings_;
  GlProgram program_, texturedProgram_, effectProgram_;
  GLuint textures_ = 0;
  bool ownTextures_ = false;
  GLuint vao_ = 0, vertexBuffer_ = 0, indexBuffer_ = 0, instanceBuffer_ = 0;
  GLuint effectVao_ = 0, effectBuffer_ = 0;
  /// The level instance `d` is drawn at, `distance` metres from the eye
  /// with a bounding sphere of `radius`; -1: not drawn (beyond the far range).
  int levelOf(const scene::DynamicInstance& d, double distance, double radius, double viewDistance) const;

  std::vector<std::array<EntityLevels, 2>> shapes_;
  std::vector<float> reach_;
  std::vector<double> farRange_;  ///< per icon: its last switch range (infinite without ranges)
  std::optional<world::GroundClamp> clamp_;  ///< module mode: the surfaces of every level
  std::uint32_t clampLevels_ = 0;
  // Per-frame scratch (capacity kept).
  struct Draw {
    IconLevelRange range;
    bool textured = false;
  };
  std::vector<Draw> draws_;                ///< per instance of stream_: its group
  std::vector<EntityInstanceGpu> stream_;  ///< in the order the entities came
  std::vector<std::uint32_t> order_;       ///< stream_ sorted by group
  std::vector<EntityInstanceGpu> sorted_;  ///< what is uploaded: stream_ in order_
  std::vector<EffectVertex> shadowVertices_, trailVertices_, flashVertices_;
  std::vector<std::array<float, 6>> footprint_;  ///< per icon (EntityMeshes::footprint)
};

}  // namespace sandtable::render::detail
