#pragma once
// Exports the static objects of load modules (version 5) and the icons of
// icons.pack with the terrain meshes of mesh_export.h (docs/EXPORT.md,
// "Objects" and "One icon"):
//  - instanced: one glTF mesh per icon used, drawn at every object by one
//    node with EXT_mesh_gpu_instancing (TRANSLATION, ROTATION, SCALE);
//  - flattened: every object's triangles moved into place and appended to
//    the terrain mesh as parts of their own (OBJ and glTF alike).
// Objects stand on the elevation stored for the exported terrain level
// (Level::objectY), so they meet that level's ground exactly; each is
// drawn with its icon's level of detail `iconLevel` (0: full detail).
// Icons keep their materials' base colours and, in glTF, their textures.
//
// Frame: as mesh_export.h (metres, X east, Y up, Z south). An icon turns
// about +Y by its heading, clockwise from north seen from above, exactly
// as the viewer draws it: a glTF rotation of -heading about Y.
//
// Thread safety: none needed; an ObjectCollector is used by one thread.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/formats/mesh_export.h"
#include "sandtable/formats/module.h"

namespace sandtable::mesh_export {

enum class ObjectMode : std::uint8_t { none, instanced, flattened };

/// "image/png", "image/jpeg", or "" for bytes that are neither.
std::string imageMimeType(const std::vector<std::byte>& bytes);

/// Icon `icon`'s alive state at level of detail `level` (clamped to its
/// last) in its body frame: one part per material, named `<icon>_<k>`,
/// with positions, normals and texture coordinates (t flipped to glTF's
/// top-left origin). A textured material refers to `textures`: the pack
/// texture is appended there the first time (`textureMap`, one entry per
/// pack texture, -1 until then, keeps them unique).
Mesh iconMesh(const iconpack::Pack& pack, std::size_t icon, std::size_t level, std::vector<Texture>& textures,
              std::vector<std::int32_t>& textureMap);

/// Collects the objects of the modules added, then hands them over.
class ObjectCollector {
 public:
  /// `pack` must outlive the collector.
  ObjectCollector(const iconpack::Pack& pack, std::uint32_t terrainLevel, std::uint32_t iconLevel);
  /// Adds m's objects, its north-west corner at (x, z) of the output frame.
  /// Fails (no file; messages start "export: ") for an object whose icon
  /// is not in the pack, or a module without that level.
  Status add(const module::Module& m, double x, double z);
  std::uint64_t objects() const { return objects_; }
  /// Objects per icon index (size: the pack's icons).
  const std::vector<std::uint64_t>& perIcon() const { return perIcon_; }

  /// One instanced mesh per icon used, and their textures.
  GltfExtras instanced() const;
  /// Appends every object's triangles to `mesh` (one part per icon
  /// material) and the textures they use to `textures`.
  void flattenInto(Mesh& mesh, std::vector<Texture>& textures) const;

 private:
  struct Placed {
    std::array<float, 3> base;
    float heading, scale;  ///< radians clockwise from north; times the icon's size
  };
  const iconpack::Pack& pack_;
  std::uint32_t terrainLevel_, iconLevel_;
  std::vector<std::vector<Placed>> placed_;  ///< per icon
  std::vector<std::uint64_t> perIcon_;
  std::uint64_t objects_ = 0;
};

}  // namespace sandtable::mesh_export
