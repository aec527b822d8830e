// Model import through assimp, flattening and levels of detail through
// meshoptimizer. See model.h.
#include "sandtable/icons/model.h"

#include <assimp/Importer.hpp>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <span>
#include <limits>

namespace sandtable::icons {
namespace fs = std::filesystem;

std::size_t Model::vertexCount() const {
  std::size_t n = 0;
  for (const Mesh& m : meshes) n += m.vertexCount();
  return n;
}
std::size_t Model::triangleCount() const {
  std::size_t n = 0;
  for (const Mesh& m : meshes) n += m.triangleCount();
  return n;
}
std::size_t Level::triangleCount() const {
  std::size_t n = 0;
  for (const auto& i : indices) n += i.size() / 3;
  return n;
}

namespace {

Problem problem(const std::string& path, const std::string& what) { return Problem{path, 0, "icons: " + what}; }

/// Whether a path leaves the folder it is taken in: absolute, or with a
/// ".." part.
bool leavesFolder(const fs::path& p) {
  if (p.is_absolute()) return true;
  return std::any_of(p.begin(), p.end(), [](const fs::path& part) { return part == ".."; });
}

/// A texture file named by a model, looked for only inside the model's
/// folder, so that a model from elsewhere cannot make the pack embed any
/// file of the machine (map_Kd /etc/passwd): as named when the name stays
/// inside, else by its file name alone in the model's folder (3DS files from
/// Windows tools often carry an absolute path); in any letter case too.
std::string findTexture(const fs::path& modelDir, const std::string& name) {
  std::error_code ec;
  std::string n = name;
  std::replace(n.begin(), n.end(), '\\', '/');
  const fs::path named(n);
  const fs::path given = leavesFolder(named) ? modelDir / named.filename() : modelDir / named;
  if (fs::is_regular_file(given, ec)) return given.string();
  auto lower = [](std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return s;
  };
  const std::string leaf = lower(named.filename().string());
  for (const fs::path& dir : {given.parent_path(), modelDir}) {
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      if (e.is_regular_file(ec) && lower(e.path().filename().string()) == leaf) return e.path().string();
    }
  }
  return {};
}

/// What bytes start like: the icon texture decoder (render/src/icon_textures.cpp)
/// reads PNG and JPEG; other images are named so the warning can say why
/// they are not kept. Empty: a texture that is a decodable image.
std::string textureProblem(std::span<const unsigned char> b) {
  auto starts = [&](std::initializer_list<unsigned char> magic) {
    return b.size() >= magic.size() && std::equal(magic.begin(), magic.end(), b.begin());
  };
  if (starts({0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'}) || starts({0xFF, 0xD8, 0xFF})) return {};
  const bool webp = starts({'R', 'I', 'F', 'F'}) && b.size() >= 12 && b[8] == 'W' && b[9] == 'E' && b[10] == 'B' &&
                    b[11] == 'P';
  const char* kind = starts({'I', 'I', 42, 0}) || starts({'M', 'M', 0, 42}) ? "a TIFF"
                     : starts({'B', 'M'})                                   ? "a BMP"
                     : starts({'G', 'I', 'F', '8'})                         ? "a GIF"
                     : webp                                                 ? "a WebP"
                                                                            : nullptr;
  if (kind) return std::string("is ") + kind + " image, which the viewer does not decode (PNG or JPEG only)";
  return "is not an image (PNG or JPEG)";
}

/// The first bytes of a file (at most 12), enough for textureProblem.
std::vector<unsigned char> fileHead(const std::string& path) {
  std::vector<unsigned char> head(12);
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(head.data()), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return head;
}

Material readMaterial(const aiMaterial& am, const aiScene& scene, const fs::path& dir, const std::string& path,
                      Warnings& warnings) {
  Material m;
  aiString name;
  if (am.Get(AI_MATKEY_NAME, name) == AI_SUCCESS) m.name = name.C_Str();
  aiColor4D c;
  if (am.Get(AI_MATKEY_BASE_COLOR, c) == AI_SUCCESS || am.Get(AI_MATKEY_COLOR_DIFFUSE, c) == AI_SUCCESS) {
    m.baseColour = {c.r, c.g, c.b, c.a};
  }
  aiString tex;
  if (am.GetTexture(aiTextureType_BASE_COLOR, 0, &tex) != AI_SUCCESS &&
      am.GetTexture(aiTextureType_DIFFUSE, 0, &tex) != AI_SUCCESS) {
    return m;
  }
  m.texture = tex.C_Str();
  if (const aiTexture* t = scene.GetEmbeddedTexture(tex.C_Str())) {
    m.textureEmbedded = true;
    // mHeight 0: pcData holds mWidth bytes of a compressed image file.
    if (t->mHeight == 0 && t->pcData) {
      const auto* b = reinterpret_cast<const std::byte*>(t->pcData);
      m.embeddedBytes.assign(b, b + t->mWidth);
      const std::span head(reinterpret_cast<const unsigned char*>(t->pcData), std::min<std::size_t>(t->mWidth, 12));
      if (const std::string why = textureProblem(head); !why.empty()) {
        m.embeddedBytes.clear();
        warnings.push_back(problem(path, "embedded texture \"" + m.texture + "\" of material \"" + m.name +
                                             "\" " + why + "; its base colour is used"));
      }
    } else {
      warnings.push_back(problem(path, "embedded texture \"" + m.texture + "\" of material \"" + m.name +
                                           "\" is raw texels, which icons do not keep; its base colour is used"));
    }
    return m;
  }
  std::string named = m.texture;
  std::replace(named.begin(), named.end(), '\\', '/');
  if (leavesFolder(fs::path(named))) {
    warnings.push_back(problem(path, "texture \"" + m.texture + "\" of material \"" + m.name +
                                         "\" points outside the model's folder; only its file name \"" +
                                         fs::path(named).filename().string() + "\" is looked for there"));
  }
  m.texturePath = findTexture(dir, m.texture);
  if (m.texturePath.empty()) {
    warnings.push_back(problem(path, "texture \"" + m.texture + "\" of material \"" + m.name +
                                         "\" not found beside the model; its base colour is used"));
  } else if (const std::string why = textureProblem(fileHead(m.texturePath)); !why.empty()) {
    warnings.push_back(problem(path, "texture " + m.texturePath + " of material \"" + m.name + "\" " + why +
                                         "; its base colour is used"));
    m.texturePath.clear();
  }
  return m;
}

/// The model-to-output transform: units, scale and up axis.
aiMatrix4x4 outputTransform(const aiScene& scene, const ImportOptions& o) {
  double unit = o.unitMetres;
  double factor = 0;
  if (unit <= 0) {
    // assimp reports UnitScaleFactor in centimetres (FBX's convention).
    unit = scene.mMetaData && scene.mMetaData->Get("UnitScaleFactor", factor) && factor > 0 ? factor / 100.0 : 1.0;
  }
  UpAxis up = o.up;
  if (up == UpAxis::kFromFile) {
    int axis = 1;
    up = scene.mMetaData && scene.mMetaData->Get("UpAxis", axis) && axis == 2 ? UpAxis::kZ : UpAxis::kY;
  }
  aiMatrix4x4 s;
  aiMatrix4x4::Scaling(aiVector3D(static_cast<float>(unit * o.scale)), s);
  if (up == UpAxis::kZ) {
    aiMatrix4x4 r;
    aiMatrix4x4::RotationX(static_cast<float>(-M_PI / 2), r);  // +Z up becomes +Y up
    return r * s;
  }
  return s;
}

/// Appends `am`, transformed by `t`, as one output mesh.
Status appendMesh(const aiMesh& am, const aiMatrix4x4& t, const std::string& path, Model& out) {
  Mesh m;
  m.material = am.mMaterialIndex;
  const aiMatrix3x3 nt = aiMatrix3x3(t).Inverse().Transpose();
  m.positions.reserve(std::size_t(am.mNumVertices) * 3);
  for (unsigned v = 0; v < am.mNumVertices; ++v) {
    const aiVector3D p = t * am.mVertices[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      return problem(path, "vertex " + std::to_string(v) + " of mesh \"" + am.mName.C_Str() +
                               "\" is not a finite number; fix or re-export the model");
    }
    m.positions.insert(m.positions.end(), {p.x, p.y, p.z});
    aiVector3D n = am.mNormals ? nt * am.mNormals[v] : aiVector3D(0, 1, 0);
    const float len = n.Length();
    n = std::isfinite(len) && len > 0 ? n / len : aiVector3D(0, 1, 0);
    m.normals.insert(m.normals.end(), {n.x, n.y, n.z});
    if (am.mTextureCoords[0]) {
      m.texcoords.insert(m.texcoords.end(), {am.mTextureCoords[0][v].x, am.mTextureCoords[0][v].y});
    }
  }
  // A mirroring transform turns the winding; keep faces front-facing.
  const bool flip = t.Determinant() < 0;
  m.indices.reserve(std::size_t(am.mNumFaces) * 3);
  for (unsigned f = 0; f < am.mNumFaces; ++f) {
    const aiFace& face = am.mFaces[f];
    if (face.mNumIndices != 3) continue;  // points and lines: counted as dropped by the caller
    m.indices.insert(m.indices.end(), {face.mIndices[0], face.mIndices[flip ? 2 : 1], face.mIndices[flip ? 1 : 2]});
  }
  if (!m.indices.empty()) out.meshes.push_back(std::move(m));
  return {};
}

Status flatten(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, const std::string& path,
               Model& out) {
  const aiMatrix4x4 t = parent * node.mTransformation;
  for (unsigned k = 0; k < node.mNumMeshes; ++k) {
    const aiMesh* am = scene.mMeshes[node.mMeshes[k]];
    if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    if (Status st = appendMesh(*am, t, path, out); !st) return st;
  }
  for (unsigned c = 0; c < node.mNumChildren; ++c) {
    if (Status st = flatten(scene, *node.mChildren[c], t, path, out); !st) return st;
  }
  return {};
}

/// Vertex cache order, then vertex fetch order, mesh by mesh.
void optimise(Mesh& m) {
  const std::size_t nv = m.vertexCount();
  meshopt_optimizeVertexCache(m.indices.data(), m.indices.data(), m.indices.size(), nv);
  std::vector<unsigned> remap(nv);
  const std::size_t kept = meshopt_optimizeVertexFetchRemap(remap.data(), m.indices.data(), m.indices.size(), nv);
  meshopt_remapIndexBuffer(m.indices.data(), m.indices.data(), m.indices.size(), remap.data());
  auto remapStream = [&](std::vector<float>& s, std::size_t width) {
    if (s.empty()) return;
    std::vector<float> o(kept * width);
    meshopt_remapVertexBuffer(o.data(), s.data(), nv, width * sizeof(float), remap.data());
    s = std::move(o);
  };
  remapStream(m.positions, 3);
  remapStream(m.normals, 3);
  remapStream(m.texcoords, 2);
}

Bounds boundsOf(const Model& m) {
  Bounds b;
  b.min.fill(std::numeric_limits<float>::infinity());
  b.max.fill(-std::numeric_limits<float>::infinity());
  for (const Mesh& mesh : m.meshes) {
    for (std::size_t v = 0; v < mesh.positions.size(); v += 3) {
      for (int a = 0; a < 3; ++a) {
        b.min[a] = std::min(b.min[a], mesh.positions[v + a]);
        b.max[a] = std::max(b.max[a], mesh.positions[v + a]);
      }
    }
  }
  return b;
}

}  // namespace

void optimiseModel(Model& m) {
  for (Mesh& mesh : m.meshes) optimise(mesh);
  m.bounds = boundsOf(m);
}

Result<Model> importModel(const std::string& path, const ImportOptions& o) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return problem(path, "model file not found; check the path");
  if (!fs::is_regular_file(path, ec)) {
    return problem(path, "not a regular file (a directory, device or FIFO); give a model file");
  }
  Assimp::Importer importer;
  // Lines and points go to their own meshes, which are then dropped.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  // An icon vertex is a position, a normal and one texture coordinate:
  // without this, tangents and colours that are never drawn would keep
  // apart vertices that are otherwise the same.
  importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS, aiComponent_TANGENTS_AND_BITANGENTS | aiComponent_COLORS |
                                                          aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS |
                                                          aiComponent_CAMERAS | aiComponent_LIGHTS);
  const unsigned flags = aiProcess_RemoveComponent | aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_GenSmoothNormals |
                         aiProcess_SortByPType |
                         aiProcess_ValidateDataStructure;  // no FindInvalidData: it drops a NaN mesh unnamed
  const aiScene* scene = importer.ReadFile(path, flags);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE)) {
    const std::string why = importer.GetErrorString();
    return problem(path, "assimp cannot read the model: " + (why.empty() ? std::string("incomplete scene") : why));
  }
  Model m;
  m.source = path;
  m.sourceMeshes = scene->mNumMeshes;
  Warnings warnings;
  const fs::path dir = fs::path(path).parent_path();
  for (unsigned k = 0; k < scene->mNumMaterials; ++k) {
    m.materials.push_back(readMaterial(*scene->mMaterials[k], *scene, dir, path, warnings));
  }
  if (m.materials.empty()) {
    Material fallback;
    fallback.name = "default";
    m.materials.push_back(fallback);
  }
  if (Status st = flatten(*scene, *scene->mRootNode, outputTransform(*scene, o), path, m); !st) {
    return st.problems();
  }
  if (m.meshes.empty()) return problem(path, "the model has no triangles (no faces, or only points and lines)");
  if (m.triangleCount() > o.maxTriangles) {
    return problem(path, std::to_string(m.triangleCount()) + " triangles, more than the limit of " +
                             std::to_string(o.maxTriangles) + " (ImportOptions::maxTriangles); simplify the model");
  }
  for (Mesh& mesh : m.meshes) {
    if (mesh.material >= m.materials.size()) mesh.material = 0;
  }
  optimiseModel(m);
  Result<Model> r(std::move(m));
  r.addWarnings(warnings);
  return r;
}

std::vector<Level> makeLevels(const Model& m, const std::vector<float>& ratios, float maxError) {
  std::vector<Level> levels;
  for (const float ratio : ratios) {
    Level l;
    l.ratio = ratio;
    for (const Mesh& mesh : m.meshes) {
      std::vector<std::uint32_t> out(mesh.indices.size());
      std::size_t n = mesh.indices.size();
      float err = 0;
      if (ratio < 1) {
        const auto target = static_cast<std::size_t>(double(mesh.indices.size() / 3) * ratio) * 3;
        n = meshopt_simplify(out.data(), mesh.indices.data(), mesh.indices.size(), mesh.positions.data(),
                             mesh.vertexCount(), 3 * sizeof(float), target, maxError, 0, &err);
        out.resize(n);
        meshopt_optimizeVertexCache(out.data(), out.data(), n, mesh.vertexCount());
      } else {
        out = mesh.indices;
      }
      l.error = std::max(l.error, err);
      if (ratio < 1) {
        const float scale = meshopt_simplifyScale(mesh.positions.data(), mesh.vertexCount(), 3 * sizeof(float));
        l.errorMetres = std::max(l.errorMetres, err * scale);
      }
      l.indices.push_back(std::move(out));
    }
    levels.push_back(std::move(l));
  }
  return levels;
}

}  // namespace sandtable::icons
