#pragma once
// The data logger's conversions between seed Figure 71 scripts and DIS
// captures (seed VIII.B and X; docs/DIS.md §9, "Scripts and captures").
//
// fromScript plays a script (sim::ScriptPlayer, sim::deadReckon) at a
// fixed rate and publishes each entity with the Publisher's
// threshold-and-heartbeat rule: the Entity State PDUs a `sim --dis` of the
// scripted run would send, one PDU per datagram, stamped with the script's
// times (relative timestamps). toScript reads Entity State PDUs back,
// dead reckons each entity between them (RemoteEntities, snapping: no
// smooth-back) at a fixed rate and offers every sample to a
// sim::ScriptRecorder, which keeps a line by the same rule. Positions go
// through the database frame's anchors (frame.h): exact at each PDU.
//
// Ids and types (the mapping each result lists):
//  - a script Entity_Number N is DIS entity site:application:N when every
//    number of the script is 1..65534, else the entities are numbered
//    1, 2, ... in order of first appearance; back, a DIS id becomes its
//    entity field when no two ids of the capture share one, else 1, 2, ...
//    in order of first appearance;
//  - a script Entity_Type is an index into the database's icon pack (what
//    `sim --record` writes): out, the icon's first `dis` pattern with its
//    wildcards sent as 0 (the gateway's rule), or a type the caller gives;
//    back, the icon the database draws that DIS type with (DisIconMap).
//
// Fields: Direction is the heading; Speed the horizontal speed (negative
// when moving against the heading); View_Direction the world bearing of
// the primary turret (articulated part 4096 + 11, radians from the hull's
// nose); Gun_Elevation the primary gun's (4416 + 13), radians, as the
// simulator reads it; Alive_Flag the appearance's damage bits; Fire_Flag a
// Fire PDU the entity sent; Y 0.0 (follows the ground) for land and sea
// entities, the frame height for the others.
//
// Thread safety: pure functions over their arguments.
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "sandtable/dis/datagram.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/sim/script.h"
#include "sandtable/sim_dis/frame.h"
#include "sandtable/sim_dis/publisher.h"

namespace sandtable::sim_dis {

/// The drawn ground's height at frame (x, z), nullopt off the database.
using GroundFn = std::function<std::optional<double>(double x, double z)>;

struct FromScriptOptions {
  std::uint8_t exercise = 1;
  std::uint16_t site = 1, application = 1;
  double rateHz = 60;       ///< how often the script's entities are offered to the publisher
  double startUnixS = 0;    ///< the capture time (seconds since 1970) of script time 0
  dis::Address sender{0x7F000001u, 3000};       ///< 127.0.0.1:3000
  dis::Address destination{0x7FFFFFFFu, 3000};  ///< 127.255.255.255:3000 (loopback broadcast)
  PublishOptions publishing;
  /// Entity_Type -> DIS type, before the icons' patterns.
  std::map<std::uint32_t, dis::EntityType> types;
  GroundFn groundAt;        ///< where Y is 0.0 (follows the ground); empty: height 0
};

/// How one script entity went onto the network, or came off it.
struct EntityMapping {
  std::uint32_t scriptEntity = 0;
  std::uint32_t scriptType = 0;
  dis::EntityId id;
  dis::EntityType type;
  std::string marking;
  std::string icon;        ///< the icon's name; "" when the pack has none there
  bool typeByIcon = true;  ///< false: from FromScriptOptions::types, or the default (then `fallback`)
  bool fallback = false;   ///< from: no type given and no icon pattern (1.1.0.0.0.0.0); to: no pattern matched
  std::uint64_t entityStates = 0;  ///< PDUs sent (from) or read (to)
  std::uint64_t lines = 0;         ///< script lines
};

struct FromScriptResult {
  std::vector<dis::Datagram> datagrams;  ///< in time order, one PDU each
  std::vector<EntityMapping> entities;   ///< in order of first appearance
  std::uint64_t entityStates = 0, fires = 0, removes = 0;
  std::uint64_t unplaceable = 0;  ///< states the frame could not convert (not sent)
  double endS = 0;                ///< script time of the last line (the entities are retired there)
};

/// The script as Entity State PDUs (and a Fire PDU per Fire_Flag, and a
/// deactivating Entity State PDU plus a Remove Entity PDU per entity at
/// the script's end). Problems: a rate that is not above 0, an empty
/// script.
Result<FromScriptResult> fromScript(const std::vector<sim::ScriptLine>& lines, const DisFrame& frame,
                                    std::span<const iconpack::Icon> icons, const FromScriptOptions& options = {});

struct ToScriptOptions {
  /// Only this exercise's PDUs; nullopt: the exercise of the first Entity
  /// State PDU.
  std::optional<std::uint8_t> exercise;
  double rateHz = 60;  ///< how often each entity's dead-reckoned state is offered to the recorder
  /// The capture time (seconds since 1970) of script time 0; nullopt: the
  /// first datagram's. Datagrams before it are skipped (counted).
  std::optional<double> originUnixS;
  sim::RecorderOptions recorder;
  double timeoutS = 12;  ///< an entity silent this long stops (a line with speed 0) and is dropped
  GroundFn groundAt;     ///< for Above_Ground_Level of entities off the ground; empty: 0
};

struct ToScriptResult {
  std::vector<sim::ScriptLine> lines;   ///< by time
  std::vector<EntityMapping> entities;  ///< in order of first appearance
  std::uint8_t exercise = 0;
  std::uint64_t datagrams = 0, pdus = 0, entityStates = 0, fires = 0, removes = 0;
  std::uint64_t otherExercise = 0, otherTypes = 0, malformed = 0, beforeOrigin = 0;
  std::uint64_t unplaceable = 0, timedOut = 0;
  std::string firstMalformed;  ///< the decoder's message (sender and offset)
  bool renumbered = false;     ///< entity numbers are 1, 2, ... (DIS entity fields clash)
};

/// A capture's Entity State (and Fire, Remove Entity) PDUs as a script.
/// Problems: a rate that is not above 0.
Result<ToScriptResult> toScript(std::span<const dis::Datagram> datagrams, const DisFrame& frame,
                                std::span<const iconpack::Icon> icons, const ToScriptOptions& options = {});

/// Where a script puts entity `entity` at `timeS` (tests and checks): the
/// last line at or before it dead reckoned (sim::deadReckon), held still
/// from a line with Alive_Flag 0 on, as the simulator plays it; nullopt
/// before the entity's first line.
std::optional<Eigen::Vector2d> scriptPosition(const std::vector<sim::ScriptLine>& lines, std::uint32_t entity,
                                              double timeS);

}  // namespace sandtable::sim_dis
