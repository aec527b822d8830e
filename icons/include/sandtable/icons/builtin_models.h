#pragma once
// The built-in procedural models: small low-polygon meshes made of boxes,
// prisms, cylinders and cones with base colours (NPSNET's icons were of
// this kind, seed V.E), so that a database and the simulator's demo need
// no model files. A definition file names one as `builtin:NAME` wherever
// it names a model file: `model`, `dead` and `component` lines.
//
// Every built-in is in metres with Y up, faces north (-Z is forward, +X is
// right), and has its origin on the ground at the centre of its footprint:
// its lowest point is at y = 0, except the tank's gun, whose origin is its
// trunnion. Sizes, triangles and colours: docs/ICONS.md §4. The articulated
// tank is `builtin:tank-hull` with `builtin:tank-turret` as a component at
// (0, kTankTurretRingHeight, 0) and `builtin:tank-gun` as the turret's
// component at kTankGunTrunnion; `builtin:tank` is the three in one mesh.
//
// Thread safety: every function is reentrant; the table is immutable.
#include <array>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "sandtable/icons/model.h"

namespace sandtable::icons {

/// What a definition file writes before a built-in's name.
inline constexpr std::string_view kBuiltinPrefix = "builtin:";

/// Height of the tank hull's roof, where the turret's frame sits: the
/// offset of `component turret builtin:tank-turret offset=0,1.6,0`.
inline constexpr float kTankTurretRingHeight = 1.6f;

/// Where the tank's gun elevates, in the turret's frame: on the barrel's
/// axis (0.4 m up) at the turret's front face (1.9 m ahead of the ring).
/// The offset of `component gun builtin:tank-gun offset=0,0.4,-1.9
/// parent=turret`; the gun model's origin.
inline constexpr std::array<float, 3> kTankGunTrunnion{0.0f, 0.4f, -1.9f};

struct BuiltinModel {
  std::string_view name;  ///< as a definition file writes it: "builtin:tank"
  /// Standing still on a flat foot (tree, stump, house, ruins, rock): the
  /// icon build lowers its hull's foot by kDefaultBaseBelow unless the
  /// definition sets `base-below`. Vehicles keep their wheels and tracks.
  bool grounded = false;
  Model (*make)() = nullptr;
};

/// Every built-in, in the order of docs/ICONS.md §4 (the tree first).
std::span<const BuiltinModel> builtinModels();

/// True for any model name that starts with "builtin:", known or not: such
/// a name is never a file.
bool isBuiltinName(std::string_view file);

/// The built-in named `file` ("builtin:tank"), or nullptr.
const BuiltinModel* findBuiltin(std::string_view file);

/// The model of the built-in named `file`, or nullopt when there is none.
std::optional<Model> builtinModel(std::string_view file);

/// "builtin:tree, builtin:stump, ...": every name, for messages.
std::string builtinNames();

}  // namespace sandtable::icons
