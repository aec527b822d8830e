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
  if (!mesh_.positions.empty()) {
    mesh_.min = mesh_.max = mesh_.positions.front();
    for (const auto& p : mesh_.positions) {
      for (int k = 0; k < 3; ++k) {
        mesh_.min[k] = std::min(mesh_.min[k], p[k]);
        mesh_.max[k] = std::max(mesh_.max[k], p[k]);
      }
    }
  }
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

std::pair<nlohmann::json, std::vector<std::byte>> gltfDocument(const Mesh& m, const nlohmann::json& extras,
                                                               bool embedUri) {
  using nlohmann::json;
  constexpr int kFloat = 5126, kUint = 5125, kArrayBuffer = 34962, kElementArrayBuffer = 34963, kTriangles = 4;
  const std::size_t n = m.positions.size();
  std::size_t indexCount = 0;
  for (const Part& p : m.parts) indexCount += p.indices.size();
  std::vector<std::byte> bin(n * 12 + n * 8 + indexCount * 4);
  std::byte* w = bin.data();
  for (const auto& p : m.positions) {
    std::memcpy(w, p.data(), 12);
    w += 12;
  }
  for (const auto& t : m.texcoords) {
    std::memcpy(w, t.data(), 8);
    w += 8;
  }
  json accessors = json::array();
  accessors.push_back({{"bufferView", 0}, {"componentType", kFloat}, {"count", n}, {"type", "VEC3"},
                       {"min", {m.min[0], m.min[1], m.min[2]}}, {"max", {m.max[0], m.max[1], m.max[2]}}});
  accessors.push_back({{"bufferView", 1}, {"componentType", kFloat}, {"count", n}, {"type", "VEC2"}});
  json materialsJson = json::array();
  json primitives = json::array();
  std::size_t indexOffset = 0;
  for (const Part& p : m.parts) {
    std::memcpy(w, p.indices.data(), p.indices.size() * 4);
    w += p.indices.size() * 4;
    const auto r = std::uint8_t(p.rgb >> 16), g = std::uint8_t(p.rgb >> 8), b = std::uint8_t(p.rgb);
    materialsJson.push_back({{"name", p.name},
                             {"pbrMetallicRoughness",
                              {{"baseColorFactor", {srgbToLinear(r), srgbToLinear(g), srgbToLinear(b), 1.0}},
                               {"metallicFactor", 0.0},
                               {"roughnessFactor", 1.0}}},
                             {"doubleSided", p.skirt}});
    primitives.push_back({{"attributes", {{"POSITION", 0}, {"TEXCOORD_0", 1}}},
                          {"indices", accessors.size()},
                          {"material", materialsJson.size() - 1},
                          {"mode", kTriangles}});
    accessors.push_back({{"bufferView", 2},
                         {"byteOffset", indexOffset * 4},
                         {"componentType", kUint},
                         {"count", p.indices.size()},
                         {"type", "SCALAR"}});
    indexOffset += p.indices.size();
  }
  json bufferViews = json::array();
  bufferViews.push_back({{"buffer", 0}, {"byteOffset", 0}, {"byteLength", n * 12}, {"target", kArrayBuffer}});
  bufferViews.push_back({{"buffer", 0}, {"byteOffset", n * 12}, {"byteLength", n * 8}, {"target", kArrayBuffer}});
  bufferViews.push_back({{"buffer", 0},
                         {"byteOffset", n * 20},
                         {"byteLength", indexCount * 4},
                         {"target", kElementArrayBuffer}});
  json buffer = {{"byteLength", bin.size()}};
  if (embedUri) buffer["uri"] = "data:application/octet-stream;base64," + base64(bin);
  json asset = {{"version", "2.0"}, {"generator", std::string("sandtable ") + SANDTABLE_VERSION}};
  if (!extras.is_null()) asset["extras"] = extras;
  json doc = {{"asset", asset},
              {"scene", 0},
              {"scenes", json::array({{{"nodes", {0}}}})},
              {"nodes", json::array({{{"name", "sandtable"}, {"mesh", 0}}})},
              {"meshes", json::array({{{"name", "sandtable"}, {"primitives", primitives}}})},
              {"materials", materialsJson},
              {"accessors", accessors},
              {"bufferViews", bufferViews},
              {"buffers", json::array({buffer})}};
  return {std::move(doc), std::move(bin)};
}

std::string toGltf(const Mesh& m, const nlohmann::json& extras) {
  return gltfDocument(m, extras, true).first.dump(1) + "\n";
}

std::vector<std::byte> toGlb(const Mesh& m, const nlohmann::json& extras) {
  auto [doc, bin] = gltfDocument(m, extras, false);
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
