#include "sandtable/formats/mesh_export.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>

#include "sandtable/formats/bytes.h"

namespace sandtable::mesh_export {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

/// Letters, digits, '_', '-' and '.' are kept; anything else becomes '_'.
std::string safeName(const std::string& s) {
  std::string out;
  for (const char c : s) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '_' || c == '-' || c == '.';
    out += keep ? c : '_';
  }
  return out.empty() ? "_" : out;
}

/// Shortest text that reads back as the same float.
void putFloat(std::string& out, float v) {
  char b[32];
  const auto r = std::to_chars(b, b + sizeof b, v);
  out.append(b, r.ptr);
}

void putUint(std::string& out, std::uint64_t v) {
  char b[24];
  const auto r = std::to_chars(b, b + sizeof b, v);
  out.append(b, r.ptr);
}

std::string colour01(std::uint32_t rgb) {
  std::string s;
  for (int shift : {16, 8, 0}) {
    char b[16];
    std::snprintf(b, sizeof b, "%.6f", double((rgb >> shift) & 0xff) / 255.0);
    if (!s.empty()) s += ' ';
    s += b;
  }
  return s;
}

}  // namespace

std::size_t Mesh::triangles() const {
  std::size_t n = 0;
  for (const Part& p : parts) n += p.indices.size() / 3;
  return n;
}

void Mesh::updateBounds() {
  min = max = {0, 0, 0};
  if (positions.empty()) return;
  min = max = positions.front();
  for (const auto& p : positions) {
    for (int k = 0; k < 3; ++k) {
      min[k] = std::min(min[k], p[k]);
      max[k] = std::max(max[k], p[k]);
    }
  }
}

MeshBuilder::MeshBuilder(Options o) : o_(o) {}

Status MeshBuilder::add(const module::Module& m, double x, double z) {
  auto fail = [](const std::string& msg) { return Status(Problem{"", 0, msg}); };
  if (o_.level >= m.levels.size()) {
    return fail("export: module (" + std::to_string(m.kx) + "," + std::to_string(m.kz) + ") has " +
           std::to_string(m.levels.size()) + " levels; there is no level " + std::to_string(o_.level));
  }
  const module::Level& lv = m.levels[o_.level];
  remap_.assign(lv.vertices.size(), kNone);
  for (const module::Group& g : lv.groups) {
    const bool skirt = g.half == module::Half::skirt;
    if (skirt && !o_.skirts) continue;
    if (std::uint64_t(g.firstIndex) + g.indexCount > lv.indices.size()) {
      return fail("export: module (" + std::to_string(m.kx) + "," + std::to_string(m.kz) +
             ") has a group past its indices; run `sandtable validate`");
    }
    PartState& ps = parts_[{skirt, skirt ? std::uint16_t(0) : g.material}];
    ps.priority = std::min(ps.priority, g.priority);
    ps.material = g.material;
    ps.part.skirt = skirt;
    for (std::uint32_t k = g.firstIndex; k < g.firstIndex + g.indexCount; ++k) {
      const std::uint32_t v = lv.indices[k];
      if (v >= lv.vertices.size()) {
        return fail("export: module (" + std::to_string(m.kx) + "," + std::to_string(m.kz) +
               ") has an index past its vertices; run `sandtable validate`");
      }
      if (remap_[v] == kNone) {
        if (mesh_.positions.size() >= kNone) return fail("export: more than 2^32 vertices; export fewer modules");
        remap_[v] = std::uint32_t(mesh_.positions.size());
        const module::Vertex& p = lv.vertices[v];
        mesh_.positions.push_back({float(double(p.x) + x), p.y, float(double(p.z) + z)});
        mesh_.texcoords.push_back({p.s, p.t});
      }
      ps.part.indices.push_back(remap_[v]);
    }
  }
  return {};
}

Mesh MeshBuilder::finish() {
  std::vector<PartState*> order;
  for (auto& [key, ps] : parts_) {
    if (!ps.part.indices.empty()) order.push_back(&ps);
  }
  // Draw order: skin classes, then decals by priority, skirts last.
  std::stable_sort(order.begin(), order.end(), [](const PartState* a, const PartState* b) {
    if (a->part.skirt != b->part.skirt) return b->part.skirt;
    if (a->priority != b->priority) return a->priority < b->priority;
    return a->material < b->material;
  });
  std::set<std::string> taken = {kSkirtPart};
  for (PartState* ps : order) {
    Part& p = ps->part;
    if (p.skirt) {
      p.name = kSkirtPart;
      p.rgb = kSkirtRgb;
    } else {
      const materials::Class* c = nullptr;
      if (o_.materials) {
        for (const auto& k : o_.materials->classes) {
          if (k.id == ps->material) c = &k;
        }
      }
      p.name = c ? safeName(c->name) : "class_" + std::to_string(ps->material);
      p.rgb = c ? c->upperRgb : kUnknownRgb;
      if (taken.count(p.name)) p.name += "_" + std::to_string(ps->material);
      taken.insert(p.name);
    }
    mesh_.parts.push_back(std::move(p));
  }
  mesh_.updateBounds();
  parts_.clear();
  Mesh out = std::move(mesh_);
  mesh_ = Mesh{};
  return out;
}

// ---------------------------------------------------------------- OBJ

std::string toObj(const Mesh& m, const std::string& mtlName, const std::vector<std::string>& header) {
  std::string s;
  s.reserve(m.positions.size() * 48 + m.triangles() * 40 + 1024);
  for (const auto& line : header) s += "# " + line + "\n";
  s += "mtllib " + mtlName + "\n";
  s += "o sandtable\n";
  for (const auto& p : m.positions) {
    s += "v ";
    putFloat(s, p[0]);
    s += ' ';
    putFloat(s, p[1]);
    s += ' ';
    putFloat(s, p[2]);
    s += '\n';
  }
  for (const auto& t : m.texcoords) {
    s += "vt ";
    putFloat(s, t[0]);
    s += ' ';
    putFloat(s, t[1]);
    s += '\n';
  }
  for (const Part& p : m.parts) {
    s += "g " + p.name + "\nusemtl " + p.name + "\n";
    for (std::size_t k = 0; k + 2 < p.indices.size(); k += 3) {
      s += 'f';
      for (std::size_t q = 0; q < 3; ++q) {
        const std::uint64_t i = std::uint64_t(p.indices[k + q]) + 1;
        s += ' ';
        putUint(s, i);
        s += '/';
        putUint(s, i);
      }
      s += '\n';
    }
  }
  return s;
}

std::string toMtl(const Mesh& m) {
  std::string s = "# sandtable export: one material per class (Kd = the class's upper-triangle colour)\n";
  for (const Part& p : m.parts) {
    s += "\nnewmtl " + p.name + "\n";
    s += "Ka 0.000000 0.000000 0.000000\n";
    s += "Kd " + colour01(p.rgb) + "\n";
    s += "Ks 0.000000 0.000000 0.000000\n";
    s += "d 1\nillum 1\n";
  }
  return s;
}

// ---------------------------------------------------------------- glTF

std::string base64(const std::vector<std::byte>& bytes) {
  static const char* d = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string s;
  s.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t k = 0;
  for (; k + 2 < bytes.size(); k += 3) {
    const std::uint32_t v = std::uint32_t(bytes[k]) << 16 | std::uint32_t(bytes[k + 1]) << 8 |
                            std::uint32_t(bytes[k + 2]);
    s += d[v >> 18];
    s += d[(v >> 12) & 63];
    s += d[(v >> 6) & 63];
    s += d[v & 63];
  }
  if (k < bytes.size()) {
    const bool two = k + 1 < bytes.size();
    const std::uint32_t v = std::uint32_t(bytes[k]) << 16 | (two ? std::uint32_t(bytes[k + 1]) << 8 : 0u);
    s += d[v >> 18];
    s += d[(v >> 12) & 63];
    s += two ? d[(v >> 6) & 63] : '=';
    s += '=';
  }
  return s;
}

double srgbToLinear(std::uint8_t c) {
  const double v = double(c) / 255.0;
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

namespace {

constexpr int kFloat = 5126, kUint = 5125, kArrayBuffer = 34962, kElementArrayBuffer = 34963, kTriangles = 4;

/// Appends buffer views and accessors to one binary buffer; every view
/// starts on a 4-byte boundary.
class GltfWriter {
 public:
  /// A view over `bytes` bytes copied from `data`; target 0: none.
  std::size_t view(const void* data, std::size_t bytes, int target) {
    while (bin_.size() % 4) bin_.push_back(std::byte{0});
    const std::size_t at = bin_.size();
    bin_.resize(at + bytes);
    if (bytes > 0) std::memcpy(bin_.data() + at, data, bytes);
    nlohmann::json v = {{"buffer", 0}, {"byteOffset", at}, {"byteLength", bytes}};
    if (target != 0) v["target"] = target;
    views_.push_back(std::move(v));
    return views_.size() - 1;
  }
  template <std::size_t N>
  std::size_t floats(const std::vector<std::array<float, N>>& v, const char* type, bool bounds,
                     int target = kArrayBuffer) {
    const std::size_t view = this->view(v.data(), v.size() * N * 4, target);
    nlohmann::json a = {{"bufferView", view}, {"componentType", kFloat}, {"count", v.size()}, {"type", type}};
    if (bounds) {
      std::array<float, N> lo{}, hi{};
      if (!v.empty()) lo = hi = v.front();
      for (const auto& x : v) {
        for (std::size_t k = 0; k < N; ++k) lo[k] = std::min(lo[k], x[k]), hi[k] = std::max(hi[k], x[k]);
      }
      a["min"] = lo;
      a["max"] = hi;
    }
    return accessor(std::move(a));
  }
  std::size_t accessor(nlohmann::json a) {
    accessors_.push_back(std::move(a));
    return accessors_.size() - 1;
  }
  /// A material for `p`, textured when it has a texture.
  std::size_t material(const Part& p) {
    const auto r = std::uint8_t(p.rgb >> 16), g = std::uint8_t(p.rgb >> 8), b = std::uint8_t(p.rgb);
    nlohmann::json pbr = {{"baseColorFactor", {srgbToLinear(r), srgbToLinear(g), srgbToLinear(b), 1.0}},
                          {"metallicFactor", 0.0},
                          {"roughnessFactor", 1.0}};
    if (p.texture != kNoTexture) pbr["baseColorTexture"] = {{"index", p.texture}};
    materials_.push_back({{"name", p.name}, {"pbrMetallicRoughness", pbr}, {"doubleSided", p.skirt}});
    return materials_.size() - 1;
  }
  /// A glTF mesh: shared attributes, one primitive per part, all of the
  /// parts' indices in one view.
  nlohmann::json mesh(const Mesh& m, const std::string& name) {
    nlohmann::json attributes;
    nlohmann::json a = {{"componentType", kFloat}, {"count", m.positions.size()}, {"type", "VEC3"},
                        {"min", m.min}, {"max", m.max}};
    a["bufferView"] = view(m.positions.data(), m.positions.size() * 12, kArrayBuffer);
    attributes["POSITION"] = accessor(std::move(a));
    attributes["TEXCOORD_0"] = floats(m.texcoords, "VEC2", false);
    std::vector<std::uint32_t> all;
    for (const Part& p : m.parts) all.insert(all.end(), p.indices.begin(), p.indices.end());
    const std::size_t indexView = view(all.data(), all.size() * 4, kElementArrayBuffer);
    if (!m.normals.empty()) attributes["NORMAL"] = floats(m.normals, "VEC3", false);
    nlohmann::json primitives = nlohmann::json::array();
    std::size_t offset = 0;
    for (const Part& p : m.parts) {
      const std::size_t indices = accessor({{"bufferView", indexView},
                                            {"byteOffset", offset * 4},
                                            {"componentType", kUint},
                                            {"count", p.indices.size()},
                                            {"type", "SCALAR"}});
      offset += p.indices.size();
      primitives.push_back(
          {{"attributes", attributes}, {"indices", indices}, {"material", material(p)}, {"mode", kTriangles}});
    }
    return {{"name", name}, {"primitives", primitives}};
  }
  std::vector<std::byte> bin_;
  nlohmann::json views_ = nlohmann::json::array(), accessors_ = nlohmann::json::array();
  nlohmann::json materials_ = nlohmann::json::array();
};

}  // namespace

std::pair<nlohmann::json, std::vector<std::byte>> gltfDocument(const Mesh& m, const nlohmann::json& extras,
                                                               bool embedUri, const GltfExtras& more) {
  using nlohmann::json;
  GltfWriter w;
  json meshes = json::array({w.mesh(m, "sandtable")});
  json nodes = json::array({{{"name", "sandtable"}, {"mesh", 0}}});
  json sceneNodes = json::array({0});
  for (const InstancedMesh& im : more.instanced) {
    meshes.push_back(w.mesh(im.mesh, im.name));
    const json instancing = {{"attributes",
                              {{"TRANSLATION", w.floats(im.translations, "VEC3", false, 0)},
                               {"ROTATION", w.floats(im.rotations, "VEC4", false, 0)},
                               {"SCALE", w.floats(im.scales, "VEC3", false, 0)}}}};
    nodes.push_back({{"name", im.name},
                     {"mesh", meshes.size() - 1},
                     {"extensions", {{"EXT_mesh_gpu_instancing", instancing}}}});
    sceneNodes.push_back(nodes.size() - 1);
  }
  json images = json::array(), textures = json::array();
  for (const Texture& t : more.textures) {
    images.push_back({{"name", t.name}, {"mimeType", t.mimeType}, {"bufferView", w.view(t.bytes.data(), t.bytes.size(), 0)}});
    textures.push_back({{"source", images.size() - 1}, {"sampler", 0}});
  }
  json buffer = {{"byteLength", w.bin_.size()}};
  if (embedUri) buffer["uri"] = "data:application/octet-stream;base64," + base64(w.bin_);
  json asset = {{"version", "2.0"}, {"generator", std::string("sandtable ") + SANDTABLE_VERSION}};
  if (!extras.is_null()) asset["extras"] = extras;
  json doc = {{"asset", asset},
              {"scene", 0},
              {"scenes", json::array({{{"nodes", sceneNodes}}})},
              {"nodes", nodes},
              {"meshes", meshes},
              {"materials", w.materials_},
              {"accessors", w.accessors_},
              {"bufferViews", w.views_},
              {"buffers", json::array({buffer})}};
  if (!more.textures.empty()) {
    // Linear filtering with mipmaps, repeating: what the models were made for.
    doc["samplers"] = json::array({{{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 10497}, {"wrapT", 10497}}});
    doc["images"] = images;
    doc["textures"] = textures;
  }
  if (!more.instanced.empty()) {
    // Without the extension a viewer would draw each icon once, at the origin.
    doc["extensionsUsed"] = json::array({"EXT_mesh_gpu_instancing"});
    doc["extensionsRequired"] = json::array({"EXT_mesh_gpu_instancing"});
  }
  return {std::move(doc), std::move(w.bin_)};
}

std::string toGltf(const Mesh& m, const nlohmann::json& extras, const GltfExtras& more) {
  return gltfDocument(m, extras, true, more).first.dump(1) + "\n";
}

std::vector<std::byte> toGlb(const Mesh& m, const nlohmann::json& extras, const GltfExtras& more) {
  auto [doc, bin] = gltfDocument(m, extras, false, more);
  std::string json = doc.dump();
  while (json.size() % 4) json += ' ';
  const std::size_t binPadded = (bin.size() + 3) / 4 * 4;
  const std::size_t total = 12 + 8 + json.size() + 8 + binPadded;
  std::vector<std::byte> out(total, std::byte{0});
  std::byte* p = out.data();
  storeLE<std::uint32_t>(p, 0x46546C67u);  // "glTF"
  storeLE<std::uint32_t>(p + 4, 2);
  storeLE<std::uint32_t>(p + 8, std::uint32_t(total));
  storeLE<std::uint32_t>(p + 12, std::uint32_t(json.size()));
  storeLE<std::uint32_t>(p + 16, 0x4E4F534Au);  // "JSON"
  std::memcpy(p + 20, json.data(), json.size());
  std::byte* c = p + 20 + json.size();
  storeLE<std::uint32_t>(c, std::uint32_t(binPadded));
  storeLE<std::uint32_t>(c + 4, 0x004E4942u);  // "BIN\0"
  if (!bin.empty()) std::memcpy(c + 8, bin.data(), bin.size());
  return out;
}

}  // namespace sandtable::mesh_export
