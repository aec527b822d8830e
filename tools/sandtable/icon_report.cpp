#include "icon_report.h"

#include <cstdio>
#include <set>
#include <string>

#include "sandtable/formats/dis_icons.h"

namespace sandtable::cli {
namespace {

/// The icon's DIS patterns, "1.1.225.1, 1.1.*.1".
std::string disText(const iconpack::Icon& i) {
  std::string s;
  for (const auto& p : i.dis) s += (s.empty() ? "" : ", ") + iconpack::disText(p);
  return s;
}

/// The textures an icon's materials use, by pack index.
std::set<std::uint32_t> texturesOf(const iconpack::Icon& i) {
  std::set<std::uint32_t> t;
  for (const auto& m : i.materials) {
    if (m.texture != iconpack::kNoTexture) t.insert(m.texture);
  }
  return t;
}

bool hasDead(const iconpack::Icon& i) {
  for (const auto& p : i.parts) {
    if (p.state == iconpack::State::dead) return true;
  }
  return false;
}

}  // namespace

nlohmann::json iconsJson(const iconpack::Pack& p) {
  nlohmann::json out = nlohmann::json::array();
  for (const iconpack::Icon& i : p.icons) {
    nlohmann::json levels = nlohmann::json::array(), parts = nlohmann::json::array(), tex = nlohmann::json::array();
    for (std::size_t l = 0; l < i.ranges.size(); ++l) {
      levels.push_back({{"range_m", i.ranges[l]}, {"triangles", iconpack::triangleCount(i, l)}});
    }
    for (const auto& part : i.parts) {
      parts.push_back({{"name", part.name},
                       {"state", part.state == iconpack::State::dead ? "dead" : "alive"},
                       {"parent", part.parent},
                       {"offset", part.offset},
                       {"meshes", part.meshes.size()}});
    }
    for (const std::uint32_t t : texturesOf(i)) tex.push_back({{"name", p.textures[t].name}, {"bytes", p.textures[t].bytes.size()}});
    nlohmann::json j{{"name", i.name},
                     {"levels", levels},
                     {"parts", parts},
                     {"bounds", {{"min", {i.bounds[0], i.bounds[1], i.bounds[2]}}, {"max", {i.bounds[3], i.bounds[4], i.bounds[5]}}}},
                     {"cylinder", {{"radius_m", i.cylinderRadius}, {"height_m", i.cylinderHeight}}},
                     {"armed", i.armed},
                     {"resupply", i.resupply},
                     {"materials", i.materials.size()},
                     {"textures", tex}};
    nlohmann::json dis = nlohmann::json::array();
    for (const auto& pattern : i.dis) dis.push_back(iconpack::disText(pattern));
    j["dis"] = dis;
    j["triangles_dead"] = hasDead(i) ? nlohmann::json(iconpack::triangleCount(i, 0, iconpack::State::dead))
                                     : nlohmann::json(nullptr);
    out.push_back(std::move(j));
  }
  return out;
}

void printIcons(const iconpack::Pack& p) {
  for (const iconpack::Icon& i : p.icons) {
    std::printf("icon %s\n", i.name.c_str());
    std::printf("  levels   ");
    for (std::size_t l = 0; l < i.ranges.size(); ++l) {
      std::printf("%s%llu tri to %.0f m", l ? ", " : "", static_cast<unsigned long long>(iconpack::triangleCount(i, l)),
                  double(i.ranges[l]));
    }
    std::printf("\n");
    const auto& b = i.bounds;
    std::printf("  bounds   x %.2f..%.2f, y %.2f..%.2f, z %.2f..%.2f m; cylinder r %.2f m, h %.2f m\n", double(b[0]),
                double(b[3]), double(b[1]), double(b[4]), double(b[2]), double(b[5]), double(i.cylinderRadius),
                double(i.cylinderHeight));
    std::printf("  parts    %zu", i.parts.size());
    for (const auto& part : i.parts) {
      if (!part.name.empty()) {
        std::printf(", %s (%s) at %.2f %.2f %.2f", part.name.c_str(), part.state == iconpack::State::dead ? "dead" : "alive",
                    double(part.offset[0]), double(part.offset[1]), double(part.offset[2]));
      }
    }
    std::printf("%s\n", hasDead(i) ? "; has a dead state" : "");
    std::printf("  caps     %s%s%s", i.armed ? "armed " : "", i.resupply ? "resupply " : "",
                !i.armed && !i.resupply ? "none " : "");
    if (!i.dis.empty()) std::printf("; DIS %s", disText(i).c_str());
    std::printf("; %zu materials", i.materials.size());
    for (const std::uint32_t t : texturesOf(i)) {
      std::printf(", texture %s (%zu bytes)", p.textures[t].name.c_str(), p.textures[t].bytes.size());
    }
    std::printf("\n");
  }
}

}  // namespace sandtable::cli
