#pragma once
// Exports load modules as standard meshes for inspection in other tools
// (docs/EXPORT.md): Wavefront OBJ + MTL, or glTF 2.0 (.gltf with the
// buffer embedded as base64, or binary .glb).
//
// Frame: metres, X east, Y up (elevation above the vertical datum, as in
// the database), Z south, origin at the north-west corner of the exported
// range. That frame is right-handed and Y-up, glTF's own convention, so
// nothing is mirrored: north is -Z. Skin and decal triangles keep the
// modules' winding, counter-clockwise seen from above (glTF front faces).
//
// One part (OBJ usemtl group, glTF primitive) per material class, named
// after the class in the material table and coloured with its upper-
// triangle colour; skirts form one more part, "skirt".
//
// Thread safety: none needed; a MeshBuilder is used by one thread.
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "sandtable/formats/materials.h"
#include "sandtable/formats/module.h"

namespace sandtable::mesh_export {

/// Name of the part that holds the skirts.
inline constexpr const char* kSkirtPart = "skirt";
/// Colour of parts whose class is not in the table, and of the skirts.
inline constexpr std::uint32_t kUnknownRgb = 0x808080;
inline constexpr std::uint32_t kSkirtRgb = 0x4d4d4d;

struct Options {
  std::uint32_t level = 0;  ///< 0 = finest
  bool skirts = true;       ///< false: leave the skirts out
  /// Class names and colours; null or a missing id: "class_<id>", grey.
  const materials::Table* materials = nullptr;
};

/// Part::texture of a part without a texture.
inline constexpr std::int32_t kNoTexture = -1;

/// The triangles of one material.
struct Part {
  std::string name;    ///< unique in the mesh; letters, digits, '_', '-', '.' only
  std::uint32_t rgb = kUnknownRgb;  ///< 0xRRGGBB (sRGB)
  bool skirt = false;  ///< the skirt part (vertical walls: draw double-sided)
  /// Index into the document's textures (glTF baseColorTexture over
  /// TEXCOORD_0), or kNoTexture. OBJ ignores it.
  std::int32_t texture = kNoTexture;
  std::vector<std::uint32_t> indices;  ///< triangle list into Mesh vertices
};

/// A mesh ready to write: shared vertices, one index list per part.
struct Mesh {
  std::vector<std::array<float, 3>> positions;  ///< x east, y up, z south
  std::vector<std::array<float, 2>> texcoords;  ///< module s, t (roads: along, across); icons: glTF's (v down)
  /// One per position, or empty (glTF viewers then shade flat).
  std::vector<std::array<float, 3>> normals;
  std::vector<Part> parts;  ///< skin classes, decal classes by priority, skirts last
  std::array<float, 3> min{}, max{};  ///< bounds of positions (0 when empty)

  std::size_t triangles() const;
  /// Recomputes min and max from the positions.
  void updateBounds();
};

/// An image a part refers to: PNG or JPEG bytes, written into the glTF
/// buffer as they are.
struct Texture {
  std::string name;
  std::string mimeType;  ///< "image/png" or "image/jpeg"
  std::vector<std::byte> bytes;
};

/// One mesh drawn at many places (glTF EXT_mesh_gpu_instancing): one node
/// whose instances are TRANSLATION, ROTATION and SCALE accessors.
struct InstancedMesh {
  std::string name;
  Mesh mesh;
  std::vector<std::array<float, 3>> translations;
  std::vector<std::array<float, 4>> rotations;  ///< unit quaternions x, y, z, w
  std::vector<std::array<float, 3>> scales;
};

/// What a glTF document holds besides the main mesh.
struct GltfExtras {
  std::vector<InstancedMesh> instanced;  ///< each becomes a node with EXT_mesh_gpu_instancing
  std::vector<Texture> textures;         ///< Part::texture indexes these
};

/// Collects modules into one mesh. Vertices are shared within a module and
/// only those used by an exported triangle are kept.
class MeshBuilder {
 public:
  explicit MeshBuilder(Options o);
  /// Appends one module, its north-west corner placed at (x, z) of the
  /// output frame. Fails (no file; messages start "export: ") on a module
  /// it cannot export, e.g. one without that level.
  Status add(const module::Module& m, double x, double z);
  /// The mesh, parts in draw order. The builder is empty afterwards.
  Mesh finish();

 private:
  struct PartState {
    Part part;
    std::uint8_t priority = 255;  ///< lowest group priority seen
    std::uint16_t material = 0;
  };
  Options o_;
  Mesh mesh_;
  std::map<std::pair<bool, std::uint16_t>, PartState> parts_;  ///< (skirt, material)
  std::vector<std::uint32_t> remap_;  ///< reused per module
};

/// Wavefront OBJ text: `mtllib <mtlName>`, v/vt per vertex, one
/// `usemtl` group per part. `header` lines are written as comments.
std::string toObj(const Mesh& m, const std::string& mtlName, const std::vector<std::string>& header);
/// The MTL for toObj: one `newmtl` per part, Kd from its colour.
std::string toMtl(const Mesh& m);

/// glTF 2.0 JSON with the buffer embedded as a base64 data URI. `extras`
/// (may be null) is stored as the asset's extras; `more` adds instanced
/// meshes and textures.
std::string toGltf(const Mesh& m, const nlohmann::json& extras, const GltfExtras& more = {});
/// Binary glTF 2.0 (GLB): the same document with the buffer in a BIN chunk.
std::vector<std::byte> toGlb(const Mesh& m, const nlohmann::json& extras, const GltfExtras& more = {});

/// The glTF document for `m` and its binary buffer (exposed for tests).
/// `embedUri`: put the buffer in buffers[0].uri as base64. Node 0 / mesh 0
/// is `m` (buffer views 0, 1 and 2: its positions, texcoords and indices;
/// then its normals when it has them); each instanced mesh adds a node and
/// a mesh, and each texture an image, in order.
std::pair<nlohmann::json, std::vector<std::byte>> gltfDocument(const Mesh& m, const nlohmann::json& extras,
                                                               bool embedUri, const GltfExtras& more = {});

/// RFC 4648 base64 (with padding).
std::string base64(const std::vector<std::byte>& bytes);
/// sRGB (0..255) to the linear 0..1 value glTF colour factors use.
double srgbToLinear(std::uint8_t c);

}  // namespace sandtable::mesh_export
