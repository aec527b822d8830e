#pragma once
// Model import for icons (seed V.E): any format assimp reads becomes one
// flattened, triangulated model in metres with Y up, its materials' base
// colours and textures kept, and levels of detail from meshoptimizer's
// simplifier.
//
// Thread safety: importModel and makeLevels are reentrant (each call owns
// its assimp importer); a Model is a value type.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "sandtable/base/result.h"

namespace sandtable::icons {

/// The up axis of the scene as assimp delivers it. assimp already turns
/// some formats to Y up (3DS); others keep the file's axes (OBJ, OFF, STL
/// from CAD tools are often Z up).
enum class UpAxis : std::uint8_t {
  kFromFile,  ///< the file's "UpAxis" metadata where assimp reports one (FBX, Collada), else Y
  kY,         ///< already Y up (glTF, 3DS through assimp, OBJ by convention)
  kZ,         ///< Z up: rotated -90 degrees about X, so (x, y, z) -> (x, z, -y)
};

struct ImportOptions {
  /// Metres per source unit; 0 takes the file's "UnitScaleFactor" metadata
  /// (centimetres in FBX) where assimp reports one, else 1.
  double unitMetres = 0;
  /// Scale applied after the unit conversion (the definition file's scale).
  double scale = 1;
  UpAxis up = UpAxis::kFromFile;
  /// More triangles than this, after triangulation, is an error: an icon
  /// is drawn instanced thousands of times, so a 5 M-triangle scan is a
  /// mistake, not an icon.
  std::uint64_t maxTriangles = 1u << 20;
};

/// One material: the base colour, and a texture where the model has one.
struct Material {
  std::string name;
  std::array<float, 4> baseColour{1, 1, 1, 1};  ///< linear RGBA
  std::string texture;        ///< the path as the model names it ("" = none; "*0" = embedded)
  std::string texturePath;    ///< the file found for it ("" = embedded or not found)
  bool textureEmbedded = false;
  /// The image file's bytes (PNG, JPEG) of an embedded compressed texture;
  /// empty otherwise.
  std::vector<std::byte> embeddedBytes;
};

/// Triangles of one material, in model space (metres, Y up).
struct Mesh {
  std::uint32_t material = 0;      ///< index into Model::materials
  std::vector<float> positions;    ///< x, y, z per vertex
  std::vector<float> normals;      ///< x, y, z per vertex, unit length
  std::vector<float> texcoords;    ///< s, t per vertex, or empty when the mesh has none
  std::vector<std::uint32_t> indices;  ///< three per triangle
  std::size_t vertexCount() const { return positions.size() / 3; }
  std::size_t triangleCount() const { return indices.size() / 3; }
};

struct Bounds {
  std::array<float, 3> min{0, 0, 0}, max{0, 0, 0};
};

struct Model {
  std::string source;               ///< the file imported
  std::uint32_t sourceMeshes = 0;   ///< meshes in the file, before flattening
  std::vector<Material> materials;
  std::vector<Mesh> meshes;         ///< one per source mesh with triangles, node transforms applied
  Bounds bounds;
  std::size_t vertexCount() const;
  std::size_t triangleCount() const;
};

/// Imports `path` through assimp: triangulated, identical vertices joined,
/// smooth normals generated where the file has none, the node hierarchy
/// flattened into the vertices, then converted to metres and Y up.
/// Errors (named with the file): assimp cannot read it, no triangles, a
/// vertex that is not finite, more than ImportOptions::maxTriangles.
/// Warnings: a texture that cannot be found (the base colour is used),
/// points and lines dropped.
Result<Model> importModel(const std::string& path, const ImportOptions& o = {});

/// Vertex cache order, then vertex fetch order, for every mesh; then the
/// bounds. importModel ends with it; procedural models call it too.
void optimiseModel(Model& m);

/// One level of detail: per mesh of the model, the indices kept.
struct Level {
  float ratio = 1;                 ///< target fraction of the model's triangles
  float error = 0;                 ///< meshoptimizer's relative error reached (largest over the meshes)
  float errorMetres = 0;           ///< that error in metres (relative error times the mesh's extent)
  std::vector<std::vector<std::uint32_t>> indices;  ///< per Model::meshes entry
  std::size_t triangleCount() const;
};

/// The default ratios of the levels: full, 1/2, 1/4, 1/10 (docs/ICONS.md).
inline const std::vector<float>& defaultLevelRatios() {
  static const std::vector<float> r{1.0f, 0.5f, 0.25f, 0.1f};
  return r;
}

/// Levels of detail with meshopt_simplify, each mesh on its own so that
/// material borders stay put, then reordered for the vertex cache
/// (meshopt_optimizeVertexCache). Level 0 (ratio 1) is the model itself,
/// cache-optimised. `maxError` bounds the simplifier's relative error.
std::vector<Level> makeLevels(const Model& m, const std::vector<float>& ratios = defaultLevelRatios(),
                              float maxError = 0.05f);

}  // namespace sandtable::icons
