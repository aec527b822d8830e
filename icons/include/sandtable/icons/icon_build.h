#pragma once
// From definitions to the icon database: imports every model of every icon
// (states and components), makes its levels of detail, derives what the
// definition leaves out (bounds, the bounding cylinder, switch ranges from
// the screen-space error), embeds the textures, and adds the built-in
// procedural tree. A model named `builtin:NAME` is a built-in model
// (builtin_models.h), not a file. Rules: docs/ICONS.md.
//
// Thread safety: buildPack and the procedural models are reentrant.
#include <string>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/icons/definitions.h"
#include "sandtable/icons/model.h"

namespace sandtable::icons {

/// The name of the built-in tree icon (the default for forests and
/// natural=tree, so that a database needs no model files).
inline constexpr const char* kDefaultTreeName = "tree";

struct PackOptions {
  /// Switch ranges the definition leaves at 0 come from the screen-space
  /// error: a level is drawn until the next level's error in metres would
  /// exceed `pixelError` pixels on a `viewportHeight`-pixel screen with a
  /// vertical field of view of `fovDegrees`. The last level is drawn until
  /// the whole icon shrinks to `pixelError` pixels.
  float pixelError = 1.0f;
  float fovDegrees = 60.0f;
  float viewportHeight = 1080.0f;
  /// meshoptimizer's relative error bound for the simplified levels.
  float maxError = 0.05f;
  /// Adds the procedural tree (kDefaultTreeName) unless the definitions
  /// define an icon of that name.
  bool addDefaultTree = true;
  /// Largest texture file embedded; a larger one is a warning and the
  /// material keeps its base colour.
  std::uint64_t maxTextureBytes = 64u << 20;
};

/// Builds the pack. Errors name the definition file and the icon's line
/// (a model that cannot be imported, a parent that does not exist);
/// warnings carry the importer's (a texture not found).
Result<iconpack::Pack> buildPack(const Definitions& defs, const PackOptions& o = {});

/// A pack with the built-in icons only (the procedural tree).
iconpack::Pack defaultPack(const PackOptions& o = {});

/// The procedural tree, 8 m tall, in metres with Y up, its origin where the
/// trunk meets the ground: a trunk (an open 8-sided tube of 0.25 m radius,
/// brown, from 0.5 m below the origin to 3 m above) and a crown (two closed
/// 16-sided cones, green: 2.5 m radius from 2 m to 6 m, 1.8 m from 4.5 m to
/// 8 m). 80 triangles, with shared vertices so that it simplifies.
Model treeModel();

}  // namespace sandtable::icons
