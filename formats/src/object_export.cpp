#include "sandtable/formats/object_export.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace sandtable::mesh_export {
namespace {

std::uint32_t rgbOf(const iconpack::Icon& icon, std::uint32_t material) {
  if (material >= icon.materials.size()) return 0xFFFFFF;
  const auto& c = icon.materials[material].rgba;
  return std::uint32_t(c[0]) << 16 | std::uint32_t(c[1]) << 8 | std::uint32_t(c[2]);
}

/// The export texture of a material: appended on first use.
std::int32_t textureOf(const iconpack::Pack& pack, const iconpack::Icon& icon, std::uint32_t material,
                       std::vector<Texture>& textures, std::vector<std::int32_t>& map) {
  if (material >= icon.materials.size()) return kNoTexture;
  const std::uint32_t t = icon.materials[material].texture;
  if (t == iconpack::kNoTexture || t >= pack.textures.size()) return kNoTexture;
  map.resize(pack.textures.size(), kNoTexture);
  if (map[t] == kNoTexture) {
    const iconpack::Texture& src = pack.textures[t];
    const std::string mime = imageMimeType(src.bytes);
    if (mime.empty()) return kNoTexture;  // glTF carries PNG and JPEG only
    textures.push_back({src.name, mime, src.bytes});
    map[t] = std::int32_t(textures.size() - 1);
  }
  return map[t];
}

}  // namespace

std::string imageMimeType(const std::vector<std::byte>& bytes) {
  static const unsigned char png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (bytes.size() >= 8 && std::memcmp(bytes.data(), png, 8) == 0) return "image/png";
  if (bytes.size() >= 3 && bytes[0] == std::byte{0xff} && bytes[1] == std::byte{0xd8} && bytes[2] == std::byte{0xff}) {
    return "image/jpeg";
  }
  return {};
}

Mesh iconMesh(const iconpack::Pack& pack, std::size_t iconIndex, std::size_t level, std::vector<Texture>& textures,
              std::vector<std::int32_t>& textureMap) {
  Mesh out;
  if (iconIndex >= pack.icons.size()) return out;
  const iconpack::Icon& icon = pack.icons[iconIndex];
  std::vector<std::int32_t> partOf(icon.materials.size() + 1, -1);  // material -> part
  for (std::size_t p = 0; p < icon.parts.size(); ++p) {
    const iconpack::Part& part = icon.parts[p];
    if (part.state != iconpack::State::alive) continue;
    const auto origin = iconpack::partOrigin(icon, p);
    for (const iconpack::Mesh& m : part.meshes) {
      if (m.levels.empty()) continue;
      const auto& indices = m.levels[std::min(level, m.levels.size() - 1)];
      const std::size_t slot = std::min<std::size_t>(m.material, icon.materials.size());
      if (partOf[slot] < 0) {
        Part np;
        np.name = icon.name + "_" + std::to_string(slot);
        np.rgb = rgbOf(icon, m.material);
        np.texture = textureOf(pack, icon, m.material, textures, textureMap);
        out.parts.push_back(std::move(np));
        partOf[slot] = std::int32_t(out.parts.size() - 1);
      }
      const auto first = std::uint32_t(out.positions.size());
      const bool uv = m.texcoords.size() == 2 * m.vertexCount();
      for (std::size_t v = 0; v < m.vertexCount(); ++v) {
        out.positions.push_back({m.positions[3 * v] + origin[0], m.positions[3 * v + 1] + origin[1],
                                 m.positions[3 * v + 2] + origin[2]});
        out.normals.push_back({m.normals[3 * v], m.normals[3 * v + 1], m.normals[3 * v + 2]});
        // icons.pack keeps assimp's bottom-left origin; glTF's is top-left.
        out.texcoords.push_back(uv ? std::array<float, 2>{m.texcoords[2 * v], 1.0f - m.texcoords[2 * v + 1]}
                                   : std::array<float, 2>{0, 0});
      }
      auto& dst = out.parts[std::size_t(partOf[slot])].indices;
      for (const std::uint32_t i : indices) dst.push_back(first + i);
    }
  }
  out.updateBounds();
  return out;
}

ObjectCollector::ObjectCollector(const iconpack::Pack& pack, std::uint32_t terrainLevel, std::uint32_t iconLevel)
    : pack_(pack), terrainLevel_(terrainLevel), iconLevel_(iconLevel), placed_(pack.icons.size()),
      perIcon_(pack.icons.size(), 0) {}

Status ObjectCollector::add(const module::Module& m, double x, double z) {
  const std::string name = "module (" + std::to_string(m.kx) + "," + std::to_string(m.kz) + ")";
  if (m.objects.empty()) return {};
  if (terrainLevel_ >= m.levels.size() || m.levels[terrainLevel_].objectY.size() != m.objects.size()) {
    return Problem{"", 0, "export: " + name + " has no object elevations for level " + std::to_string(terrainLevel_)};
  }
  const auto& y = m.levels[terrainLevel_].objectY;
  for (std::size_t k = 0; k < m.objects.size(); ++k) {
    const module::Object& o = m.objects[k];
    if (o.icon >= placed_.size()) {
      return Problem{"", 0, "export: " + name + " has an object of icon " + std::to_string(o.icon) +
                                ", but icons.pack has " + std::to_string(placed_.size()) +
                                " icons; run `sandtable validate`"};
    }
    placed_[o.icon].push_back({{float(double(o.x) + x), y[k], float(double(o.z) + z)},
                               float(module::headingRadians(o.heading)),
                               o.scale});
    ++perIcon_[o.icon];
    ++objects_;
  }
  return {};
}

GltfExtras ObjectCollector::instanced() const {
  GltfExtras out;
  std::vector<std::int32_t> map;
  for (std::size_t i = 0; i < placed_.size(); ++i) {
    if (placed_[i].empty()) continue;
    InstancedMesh im;
    im.name = pack_.icons[i].name;
    im.mesh = iconMesh(pack_, i, iconLevel_, out.textures, map);
    for (const Placed& p : placed_[i]) {
      im.translations.push_back(p.base);
      // The viewer turns (x, z) by the heading h as x' = x cos h - z sin h,
      // z' = x sin h + z cos h: a rotation of -h about +Y.
      const float half = -0.5f * p.heading;
      im.rotations.push_back({0.0f, std::sin(half), 0.0f, std::cos(half)});
      im.scales.push_back({p.scale, p.scale, p.scale});
    }
    out.instanced.push_back(std::move(im));
  }
  return out;
}

void ObjectCollector::flattenInto(Mesh& mesh, std::vector<Texture>& textures) const {
  std::vector<std::int32_t> map;
  for (std::size_t i = 0; i < placed_.size(); ++i) {
    if (placed_[i].empty()) continue;
    const Mesh icon = iconMesh(pack_, i, iconLevel_, textures, map);
    const std::size_t firstPart = mesh.parts.size();
    for (const Part& p : icon.parts) {
      Part np = p;
      np.indices.clear();
      mesh.parts.push_back(std::move(np));
    }
    const bool normals = !mesh.normals.empty() || mesh.positions.empty();
    for (const Placed& p : placed_[i]) {
      const auto first = std::uint32_t(mesh.positions.size());
      const float c = std::cos(p.heading), s = std::sin(p.heading);
      for (std::size_t v = 0; v < icon.positions.size(); ++v) {
        const auto& q = icon.positions[v];
        const float x = q[0] * p.scale, yy = q[1] * p.scale, z = q[2] * p.scale;
        mesh.positions.push_back({x * c - z * s + p.base[0], yy + p.base[1], x * s + z * c + p.base[2]});
        mesh.texcoords.push_back(icon.texcoords[v]);
        if (normals) {
          const auto& n = icon.normals[v];
          mesh.normals.push_back({n[0] * c - n[2] * s, n[1], n[0] * s + n[2] * c});
        }
      }
      for (std::size_t k = 0; k < icon.parts.size(); ++k) {
        auto& dst = mesh.parts[firstPart + k].indices;
        for (const std::uint32_t idx : icon.parts[k].indices) dst.push_back(first + idx);
      }
    }
  }
  mesh.updateBounds();
}

}  // namespace sandtable::mesh_export
