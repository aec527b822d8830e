#pragma once
// What `sandtable icons DEFS` and `sandtable info` say about an icon
// database: per icon its parts, triangles per level, switch ranges,
// bounds, bounding cylinder, capabilities and DIS type.
#include <nlohmann/json.hpp>

#include "sandtable/formats/icon_pack.h"

namespace sandtable::cli {

/// [{"name", "levels": [{"range_m", "triangles"}], "triangles_dead", "parts",
///   "bounds", "cylinder", "armed", "resupply", "dis", "textures"}]
nlohmann::json iconsJson(const iconpack::Pack& p);

/// One block of lines per icon, to stdout.
void printIcons(const iconpack::Pack& p);

}  // namespace sandtable::cli
