#pragma once
// Terrain edits as DIS synthetic-environment objects (issue 37, "Who
// decides"; docs/DIS.md §14): a crater travels as a Point Object State PDU
// (type 43) of the standard's crater type, a berm or a ditch as a Linear
// Object State PDU (type 44), one segment per polyline segment. These are
// plain conversions between edit::Edit values and the PDUs; the tracker
// (object_tracker.h) sends, re-sends and dedupes them, and applying an
// edit is the caller's (runtime/edits).
//
// Bit-identical ground in two processes needs both to apply the same edit.
// A PDU cannot carry an Edit exactly (float32 sizes and angles, the
// geocentric round trip through PROJ, the size class of a crater), so the
// SENDER applies asReceived(e) = fromPdu(toPdu(e)), the edit every
// receiver reconstructs from the same bytes, never `e` itself. asReceived
// is idempotent: asReceived(asReceived(e)) == asReceived(e) bit for bit,
// because fromPdu puts every position on a 1/256 m grid of the database
// frame and every value on what its field carries exactly (tested for
// segments up to 10 km long).
//
// What travels (docs/DIS.md §14 has the bytes):
//  - object id = site : application : (edit id & 0xFFFF), update number =
//    edit id >> 16; a receiver's edit id = update << 16 | object number, so
//    ids below 2^32 travel exactly (the object number wraps every 65,536
//    edits; the update number then tells the objects apart);
//  - origin = site << 16 | application of the sender;
//  - time = the header timestamp: the edit's simulation seconds past the
//    hour (relative, bit 0 clear), rounded to the timestamp's unit
//    (3600 / 2^31 s); the receiver puts it in the latest hour that is not
//    more than kClockSkewS after its own clock (unwrapTime);
//  - referenced object id = the object the sender published before (the
//    tracker's order; fromPdu ignores it);
//  - crater: its size class only (snapCrater: radius and depth are one of
//    edits::kCraterSmall/Medium/Large), as the subcategory;
//  - berm / ditch: width, height (berm) or depth (ditch) as float32, side
//    slope in the specific segment appearance (kSlope* below).
//
// Thread safety: pure functions over values (DisFrame is thread-safe).
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "sandtable/base/result.h"
#include "sandtable/dis/pdu.h"
#include "sandtable/formats/edit.h"
#include "sandtable/sim_dis/frame.h"

namespace sandtable::sim_dis {

/// SISO-REF-010 object types (domain, kind, category, subcategory) that
/// terrain edits use or that receivers recognise. Domain 1 is land.
inline constexpr dis::ObjectType kCraterSmallType{1, 1, 3, 1};   ///< obstacle / crater / small
inline constexpr dis::ObjectType kCraterMediumType{1, 1, 3, 2};  ///< obstacle / crater / medium
inline constexpr dis::ObjectType kCraterLargeType{1, 1, 3, 3};   ///< obstacle / crater / large
inline constexpr dis::ObjectType kTankDitchType{1, 1, 1, 0};     ///< linear obstacle / tank ditch: a ditch
inline constexpr dis::ObjectType kOtherLinearType{1, 1, 0, 0};   ///< linear obstacle / other: a berm (no standard type)
inline constexpr dis::ObjectType kBuildingRubbleType{1, 3, 2, 0};  ///< cultural feature / building rubble: recognised, no edit
inline constexpr dis::ObjectType kVehicleDefiladeType{1, 2, 1, 0}; ///< prepared position / vehicle defilade (subcategory: the vehicle): recognised, no edit

/// The type as one number, domain << 24 | kind << 16 | category << 8 | subcategory.
inline constexpr std::uint32_t objectTypeKey(const dis::ObjectType& t) {
  return std::uint32_t(t.domain) << 24 | std::uint32_t(t.kind) << 16 | std::uint32_t(t.category) << 8 | t.subcategory;
}
/// "crater, small", "tank ditch", "building rubble", ... for the types
/// above (any subcategory of the ones without); "domain.kind.category.subcategory" otherwise.
std::string objectTypeName(const dis::ObjectType& t);

/// Positions after fromPdu lie on this grid of the database frame (x and
/// z), metres: far finer than any edit's feature, coarser than what the
/// float32 angles and lengths and PROJ's round trip lose (about 1e-7 of a
/// segment's length: under 1 mm up to 10 km, measured), so a second round
/// trip lands on the same points.
inline constexpr double kObjectGridM = 1.0 / 256;
/// Segment ends of a received linear object further apart than this are
/// not one polyline: the PDU is refused.
inline constexpr double kJoinToleranceM = 0.05;

/// The side slope's private convention (the standard gives a segment no
/// slope): in the 32-bit specific segment appearance, bits 28-31 =
/// kSlopeMarker say it is there, bits 16-27 hold the slope (rise over run)
/// in units of kSlopeUnit (1 .. 4095, so 1/128 .. 31.99); bits 0-15 stay
/// 0 for the standard's meanings. Without the marker a receiver takes
/// kDefaultSideSlope (1:2).
inline constexpr std::uint32_t kSlopeMarker = 0xA;
inline constexpr double kSlopeUnit = 1.0 / 128;
inline constexpr double kDefaultSideSlope = 0.5;
std::uint32_t slopeAppearance(double sideSlope);
double slopeOf(std::uint32_t specificAppearance);

/// How far the sender's clock may be ahead of the receiver's: an edit's
/// time is put in the latest hour not after the receiver's clock plus
/// this. So the time is right when the receiver's clock is between 60 s
/// behind and 59 minutes ahead of the sender's at the edit; otherwise it is
/// off by whole hours (heights do not depend on it).
inline constexpr double kClockSkewS = 60;
/// The timestamp of an edit made at `timeS` (relative: bit 0 clear), and
/// the time a receiver whose clock reads `nowS` gives it back.
std::uint32_t editTimestamp(double timeS);
double unwrapTime(std::uint32_t timestamp, double nowS);

/// Sets a crater's radius and depth to the size class whose radius is
/// nearest its own (edits::kCraterSmall, Medium, Large; ties to the
/// smaller). Other kinds are left as they are. toPdu snaps too.
void snapCrater(edit::Edit& e);

/// Who sends, and the ground under the objects.
struct ObjectSender {
  std::uint8_t exercise = 1;
  std::uint16_t site = 1, application = 1;
  /// The height (database frame y) at (x, z), for the PDU's geocentric
  /// location; receivers ignore the height. Empty: 0.
  std::function<double(double x, double z)> ground;
};

/// The PDU of a crater, berm or ditch edit (header and the point or linear
/// body, as dis::decode gives it). `previous` is the object the sender
/// published before this one (0:0:0 for none), written as the referenced
/// object id: receivers hand on one sender's edits in its order
/// (object_tracker.h). Refuses, saying why: an edit checkEdit refuses;
/// another kind; an id of 2^32 or more; more than dis::kMaxSegments
/// segments; a segment shorter than kObjectGridM; a point PROJ cannot convert.
Result<dis::Pdu> toPdu(const edit::Edit& e, const DisFrame& frame, const ObjectSender& sender,
                       const dis::ObjectId& previous = {});
/// The bytes of a PDU that toPdu made (or any with a point or linear body).
std::vector<std::byte> encodeObject(const dis::Pdu& pdu);

/// The edit a Point or Linear Object State PDU makes, read by a receiver
/// whose clock reads `nowS` (simulation seconds): a crater (crater types of
/// subcategory 1-3), a ditch (tank ditch, depth > 0), a berm (other linear
/// obstacle, height > 0, depth 0); nullopt for any other type (the caller
/// counts it by type). Refuses, naming the field: a non-finite or
/// unconvertible location or size, a negative width, a tank ditch without
/// depth, a segment of no length or pointing up, segments that do not join.
/// A linear object's width, height or depth and slope are its first segment's.
Result<std::optional<edit::Edit>> fromPdu(const dis::Pdu& pdu, const DisFrame& frame, double nowS);

/// An edit ready to send: the PDU's bytes, and the edit every receiver
/// makes of those bytes, fromPdu(decode(bytes), e.time).
struct EncodedEdit {
  std::vector<std::byte> bytes;
  edit::Edit edit;
};
Result<EncodedEdit> encodeEdit(const edit::Edit& e, const DisFrame& frame, const ObjectSender& sender,
                               const dis::ObjectId& previous = {});

/// encodeEdit(e).edit: the edit every receiver applies when `sender`
/// publishes `e`. The sender applies this one, not `e`.
Result<edit::Edit> asReceived(const edit::Edit& e, const DisFrame& frame, const ObjectSender& sender);

}  // namespace sandtable::sim_dis
