#pragma once
// The icon definition file (text, "sandtable-icons 1"): the seed's Figure 19
// dynamic entity definition file, extended. Per icon: its model for each
// state (alive, dead), articulated components with the offset of their
// frames, capabilities, optional bounds and bounding cylinder, scale, units
// and up axis of the source, levels of detail with switch ranges, and the
// DIS entity types (patterns with wildcards) it stands for. Grammar: docs/ICONS.md, "The definition file".
//
// Thread safety: parse and readFile are reentrant; Definitions is a value.
#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/icons/model.h"

namespace sandtable::icons {

inline constexpr const char* kDefinitionsHeader = "sandtable-icons 1";
/// Largest definition file readDefinitions accepts.
inline constexpr std::uint64_t kMaxDefinitionBytes = 4u << 20;

/// An articulated component: its own model, whose frame origin (the
/// articulation point) sits at `offset` in the parent's frame.
struct ComponentDef {
  std::string name;
  std::string model;         ///< as written, relative to the definition file
  std::string parent;        ///< "" = the hull; else an earlier component of the same state
  iconpack::State state = iconpack::State::alive;
  std::array<float, 3> offset{0, 0, 0};
};

/// One level of detail: the fraction of the triangles kept, and the far
/// range up to which it is drawn (0: from the screen-space error).
struct LevelDef {
  float ratio = 1;
  float range = 0;
};

/// IconDef::baseBelow of the built-in tree by default: metres its trunk
/// reaches below the ground (seed Figure 24: "several meters"; half a metre
/// keeps a trunk down on a 20 % slope of a 2.5 m crown radius).
inline constexpr float kDefaultBaseBelow = 0.5f;

struct IconDef {
  std::string name;
  std::uint64_t line = 0;    ///< byte offset of its `icon` line, for messages
  std::string alive;         ///< model of the alive state (required)
  std::string dead;          ///< model of the dead state ("" = the alive model)
  std::vector<ComponentDef> components;
  ImportOptions import;      ///< up, unit, scale, max-triangles
  bool armed = false, resupply = false;
  std::optional<std::array<float, 6>> bounds;       ///< min x y z, max x y z
  std::optional<std::array<float, 2>> cylinder;     ///< radius, height
  std::vector<LevelDef> levels;                     ///< empty: the default ratios
  /// `base-below M`: the vertices of each state's hull within 1 cm of its
  /// lowest point are lowered this many metres (after scaling), so that an
  /// object standing level on a slope shows no gap under its downhill side
  /// (seed Figure 24). Unset: kDefaultBaseBelow for the grounded built-ins
  /// (BuiltinModel::grounded: tree, stump, house, ruins, rock), 0 for the
  /// vehicle built-ins and model files, whose lowest points may be wheels or
  /// hooves that would stretch into spikes.
  std::optional<float> baseBelow;
  /// `dis` lines: the DIS entity types this icon stands for, with
  /// wildcards (docs/ICONS.md §3.1); at most iconpack::kMaxDisPatterns.
  std::vector<iconpack::DisPattern> dis;
};

struct Definitions {
  std::string file;          ///< the file read, "" when parsed from memory
  std::string baseDir;       ///< model paths are relative to this folder
  std::vector<IconDef> icons;
};

/// Parses the text; `file` names it in problems, `baseDir` resolves models.
/// Problems carry the byte offset of the line at fault.
Result<Definitions> parseDefinitions(std::span<const std::byte> text, const std::string& file,
                                     const std::string& baseDir);

/// Reads and parses `path`; models are relative to its folder.
Result<Definitions> readDefinitions(const std::string& path);

}  // namespace sandtable::icons
