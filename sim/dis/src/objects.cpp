#include "sandtable/sim_dis/objects.h"

#include <array>
#include <cmath>
#include <sstream>

#include "sandtable/edits/profile.h"
#include "sandtable/sim/units.h"

namespace sandtable::sim_dis {
namespace {

constexpr double kUnitsPerSecond = 2147483648.0 / 3600.0;  ///< timestamp units (bits 31..1)
constexpr std::uint16_t kAll = 0xFFFF;                     ///< "all" in a simulation address
/// A received segment whose axis has less horizontal part than this
/// (pitched past 89.4 degrees) has no heading.
constexpr double kSteepestLevel = 0.01;

/// The crater size classes, in subcategory order (1 small, 2 medium, 3 large).
constexpr std::array<edits::CraterSize, 3> kCraterClasses = {edits::kCraterSmall, edits::kCraterMedium,
                                                             edits::kCraterLarge};
constexpr std::array<dis::ObjectType, 3> kCraterTypes = {kCraterSmallType, kCraterMediumType, kCraterLargeType};

Problem problem(const std::string& stage, const std::string& message) { return {"", 0, stage + ": " + message}; }

double onGrid(double v) { return std::round(v / kObjectGridM) * kObjectGridM; }

bool sameClass(const dis::ObjectType& a, const dis::ObjectType& b) {
  return a.domain == b.domain && a.kind == b.kind && a.category == b.category;
}
bool finite(const dis::Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool finite(const dis::Euler& e) { return std::isfinite(e.psi) && std::isfinite(e.theta) && std::isfinite(e.phi); }

std::size_t craterClass(double radius) {
  std::size_t best = 0;
  for (std::size_t k = 1; k < kCraterClasses.size(); ++k) {
    if (std::abs(radius - kCraterClasses[k].radius) < std::abs(radius - kCraterClasses[best].radius)) best = k;
  }
  return best;
}

double groundAt(const ObjectSender& s, double x, double z) { return s.ground ? s.ground(x, z) : 0.0; }

dis::Header objectHeader(const ObjectSender& s, const edit::Edit& e, dis::PduType type, std::size_t bytes) {
  dis::Header h;
  h.exercise = s.exercise;
  h.type = std::uint8_t(type);
  h.family = std::uint8_t(dis::Family::syntheticEnvironment);
  h.timestamp = editTimestamp(e.time);
  h.length = std::uint16_t(bytes);
  return h;
}

Result<dis::Pdu> craterPdu(edit::Edit e, const DisFrame& frame, const ObjectSender& s, const dis::ObjectId& id,
                           std::uint16_t update, const dis::ObjectId& previous) {
  snapCrater(e);
  const double x = e.points[0][0], z = e.points[0][1];
  auto anchor = frame.anchorAtFrame({x, groundAt(s, x, z), z});
  if (!anchor) return problem("toPdu", "crater at (" + std::to_string(x) + ", " + std::to_string(z) + "): " + anchor.message());
  dis::PointObjectState p;
  p.id = id;
  p.referenced = previous;
  p.updateNumber = update;
  p.type = kCraterTypes[craterClass(e.radius)];
  p.location = anchor->ecef;
  p.orientation = disOrientation(anchor.value(), 0, 0, 0);  // level, facing grid north: a crater has no heading
  p.requester = {s.site, s.application};
  p.receiver = {kAll, kAll};
  dis::Pdu pdu;
  pdu.header = objectHeader(s, e, dis::PduType::pointObjectState, dis::kPointObjectBytes);
  pdu.pointObject = p;
  return pdu;
}

Result<dis::Pdu> linearPdu(const edit::Edit& e, const DisFrame& frame, const ObjectSender& s, const dis::ObjectId& id,
                           std::uint16_t update, const dis::ObjectId& previous) {
  const std::string stage = "toPdu: " + std::string(edit::kindName(e.kind));
  const std::size_t n = e.points.size() - 1;
  if (n > dis::kMaxSegments) {
    return problem(stage, std::to_string(n) + " segments; a Linear Object State PDU carries at most " +
                              std::to_string(dis::kMaxSegments));
  }
  dis::LinearObjectState l;
  l.id = id;
  l.referenced = previous;
  l.updateNumber = update;
  l.requester = {s.site, s.application};
  l.receiver = {kAll, kAll};
  l.type = e.kind == edit::Kind::ditch ? kTankDitchType : kOtherLinearType;
  for (std::size_t k = 0; k < n; ++k) {
    const auto& a = e.points[k];
    const auto& b = e.points[k + 1];
    const double dx = b[0] - a[0], dz = b[1] - a[1];
    const double length = std::hypot(dx, dz);
    if (!(length >= kObjectGridM)) {
      return problem(stage, "segment " + std::to_string(k + 1) + " is " + std::to_string(length) +
                                " m long, under the " + std::to_string(kObjectGridM) + " m grid");
    }
    const double mx = 0.5 * (a[0] + b[0]), mz = 0.5 * (a[1] + b[1]);
    auto anchor = frame.anchorAtFrame({mx, groundAt(s, mx, mz), mz});
    if (!anchor) return problem(stage, "segment " + std::to_string(k + 1) + ": " + anchor.message());
    dis::LinearSegment g;
    g.number = std::uint8_t(k + 1);
    g.specificAppearance = slopeAppearance(e.sideSlope);
    g.location = anchor->ecef;
    // Heading clockwise from grid north (-z), level: the segment's direction.
    g.orientation = disOrientation(anchor.value(), std::atan2(dx, -dz) * sim::kRadToDeg, 0, 0);
    g.length = float(length);
    g.width = float(e.width);
    (e.kind == edit::Kind::ditch ? g.depth : g.height) = float(e.height);
    l.segments.push_back(g);
  }
  dis::Pdu pdu;
  pdu.header = objectHeader(s, e, dis::PduType::linearObjectState, dis::kLinearObjectBytes + dis::kSegmentBytes * n);
  pdu.linearObject = std::move(l);
  return pdu;
}

/// The fields every object edit takes from the PDU.
edit::Edit editOf(const dis::ObjectId& id, std::uint16_t update, const dis::Header& h, double nowS) {
  edit::Edit e;
  e.id = std::uint64_t(update) << 16 | id.object;
  e.origin = edit::Origin(id.site) << 16 | id.application;
  e.time = unwrapTime(h.timestamp, nowS);
  return e;
}

Result<std::optional<edit::Edit>> fromPoint(const dis::Header& h, const dis::PointObjectState& p, const DisFrame& frame,
                                            double nowS) {
  std::size_t size = kCraterTypes.size();
  for (std::size_t k = 0; k < kCraterTypes.size(); ++k) {
    if (p.type == kCraterTypes[k]) size = k;
  }
  if (size == kCraterTypes.size()) return std::optional<edit::Edit>();
  if (!finite(p.location)) return problem("fromPdu", "crater: the location is not finite");
  auto at = frame.frame().fromEcef({p.location.x, p.location.y, p.location.z});
  if (!at) return problem("fromPdu", "crater: " + at.message());
  edit::Edit e = editOf(p.id, p.updateNumber, h, nowS);
  e.kind = edit::Kind::crater;
  e.points = {{onGrid(at->x), onGrid(at->z)}};
  e.radius = kCraterClasses[size].radius;
  e.depth = kCraterClasses[size].depth;
  return std::optional<edit::Edit>(std::move(e));
}

Result<std::optional<edit::Edit>> fromLinear(const dis::Header& h, const dis::LinearObjectState& l,
                                             const DisFrame& frame, double nowS) {
  const bool ditch = sameClass(l.type, kTankDitchType);
  if (!ditch && !sameClass(l.type, kOtherLinearType)) return std::optional<edit::Edit>();
  const std::string stage = ditch ? "fromPdu: tank ditch" : "fromPdu: linear obstacle";
  if (l.segments.empty()) return problem(stage, "no segments");
  const dis::LinearSegment& first = l.segments.front();
  for (float v : {first.width, first.height, first.depth}) {
    if (!std::isfinite(v)) return problem(stage, "segment 1: a size is not finite");
  }
  if (first.width < 0) return problem(stage, "segment 1: width " + std::to_string(first.width) + " is negative");
  if (ditch && !(first.depth > 0)) return problem(stage, "segment 1 has no depth");
  // An "other" obstacle is a berm only when it stands up and sinks nothing.
  if (!ditch && !(first.height > 0 && first.depth == 0)) return std::optional<edit::Edit>();

  edit::Edit e = editOf(l.id, l.updateNumber, h, nowS);
  e.kind = ditch ? edit::Kind::ditch : edit::Kind::berm;
  e.width = first.width;
  e.height = ditch ? first.depth : first.height;
  e.sideSlope = slopeOf(first.specificAppearance);
  for (std::size_t k = 0; k < l.segments.size(); ++k) {
    const dis::LinearSegment& g = l.segments[k];
    const std::string seg = "segment " + std::to_string(k + 1);
    if (!finite(g.location) || !finite(g.orientation) || !std::isfinite(g.length)) {
      return problem(stage, seg + ": its location, orientation or length is not finite");
    }
    if (!(g.length > 0)) return problem(stage, seg + " has no length");
    auto anchor = frame.anchorAtEcef(g.location);
    if (!anchor) return problem(stage, seg + ": " + anchor.message());
    // The segment's x axis (DIS body: forward) in the frame, level.
    const dis::Matrix3 r = dis::rotationMatrix(g.orientation.psi, g.orientation.theta, g.orientation.phi);
    const Eigen::Vector3d along = frameVector(anchor.value(), {r[0][0], r[1][0], r[2][0]});
    const double level = std::hypot(along.x(), along.z());
    if (!(level > kSteepestLevel)) return problem(stage, seg + " points up or down");
    const double half = 0.5 * double(g.length);
    const double ux = along.x() / level, uz = along.z() / level;
    const std::array<double, 2> start{onGrid(anchor->frame.x() - half * ux), onGrid(anchor->frame.z() - half * uz)};
    const std::array<double, 2> end{onGrid(anchor->frame.x() + half * ux), onGrid(anchor->frame.z() + half * uz)};
    if (e.points.empty()) {
      e.points.push_back(start);
    } else {
      const auto& last = e.points.back();
      const double gap = std::hypot(start[0] - last[0], start[1] - last[1]);
      if (gap > kJoinToleranceM) {
        std::ostringstream m;
        m << seg << " starts " << gap << " m from where segment " << k << " ends";
        return problem(stage, m.str());
      }
    }
    // A segment shorter than the grid adds no point (the polyline keeps no repeated point).
    if (end != e.points.back()) e.points.push_back(end);
  }
  if (e.points.size() < 2) return problem(stage, "every segment is shorter than the grid");
  return std::optional<edit::Edit>(std::move(e));
}

}  // namespace

std::string objectTypeName(const dis::ObjectType& t) {
  if (t == kCraterSmallType) return "crater, small";
  if (t == kCraterMediumType) return "crater, medium";
  if (t == kCraterLargeType) return "crater, large";
  if (sameClass(t, kTankDitchType)) return "tank ditch";
  if (sameClass(t, kOtherLinearType)) return "linear obstacle, other";
  if (sameClass(t, kBuildingRubbleType)) return "building rubble";
  if (sameClass(t, kVehicleDefiladeType)) return "vehicle defilade";
  return std::to_string(t.domain) + "." + std::to_string(t.kind) + "." + std::to_string(t.category) + "." +
         std::to_string(t.subcategory);
}

std::uint32_t slopeAppearance(double sideSlope) {
  const double units = std::round(sideSlope / kSlopeUnit);
  const std::uint32_t q = units >= 4095 ? 4095u : units <= 1 ? 1u : std::uint32_t(units);
  return kSlopeMarker << 28 | q << 16;
}

double slopeOf(std::uint32_t specificAppearance) {
  const std::uint32_t q = (specificAppearance >> 16) & 0xFFFu;
  if ((specificAppearance >> 28) != kSlopeMarker || q == 0) return kDefaultSideSlope;
  return double(q) * kSlopeUnit;
}

std::uint32_t editTimestamp(double timeS) {
  const double hour = std::floor(timeS / 3600.0);
  const double units = std::round((timeS - hour * 3600.0) * kUnitsPerSecond);
  // Rounding up to the next hour's start is that hour's 0; unwrapTime then picks that hour.
  const std::uint32_t u = units >= 2147483648.0 || !(units >= 0) ? 0u : std::uint32_t(units);
  return u << 1;
}

double unwrapTime(std::uint32_t timestamp, double nowS) {
  const double past = dis::timestampSeconds(timestamp);
  return std::floor((nowS + kClockSkewS - past) / 3600.0) * 3600.0 + past;
}

void snapCrater(edit::Edit& e) {
  if (e.kind != edit::Kind::crater) return;
  const edits::CraterSize& c = kCraterClasses[craterClass(e.radius)];
  e.radius = c.radius;
  e.depth = c.depth;
}

Result<dis::Pdu> toPdu(const edit::Edit& e, const DisFrame& frame, const ObjectSender& sender,
                       const dis::ObjectId& previous) {
  if (std::string m = edit::checkEdit(e); !m.empty()) return problem("toPdu", m);
  if (e.id >> 32 != 0) {
    return problem("toPdu", "edit id " + std::to_string(e.id) +
                                " is past 2^32 - 1, what an object number and an update number carry");
  }
  const dis::ObjectId id{sender.site, sender.application, std::uint16_t(e.id & 0xFFFF)};
  const auto update = std::uint16_t(e.id >> 16);
  switch (e.kind) {
    case edit::Kind::crater: return craterPdu(e, frame, sender, id, update, previous);
    case edit::Kind::berm:
    case edit::Kind::ditch: return linearPdu(e, frame, sender, id, update, previous);
    default: break;
  }
  return problem("toPdu", std::string(edit::kindName(e.kind)) + " edits do not travel as DIS objects");
}

std::vector<std::byte> encodeObject(const dis::Pdu& pdu) {
  if (pdu.pointObject) return dis::encode(pdu.header, *pdu.pointObject);
  if (pdu.linearObject) return dis::encode(pdu.header, *pdu.linearObject);
  return {};
}

Result<std::optional<edit::Edit>> fromPdu(const dis::Pdu& pdu, const DisFrame& frame, double nowS) {
  if (pdu.pointObject) return fromPoint(pdu.header, *pdu.pointObject, frame, nowS);
  if (pdu.linearObject) return fromLinear(pdu.header, *pdu.linearObject, frame, nowS);
  return problem("fromPdu", "PDU type " + std::to_string(pdu.header.type) + " is not a Point or Linear Object State");
}

Result<EncodedEdit> encodeEdit(const edit::Edit& e, const DisFrame& frame, const ObjectSender& sender,
                               const dis::ObjectId& previous) {
  auto pdu = toPdu(e, frame, sender, previous);
  if (!pdu) return pdu.problems();
  EncodedEdit out;
  out.bytes = encodeObject(pdu.value());
  // Through the bytes, as a receiver gets them (the floats as sent), with the sender's clock.
  auto decoded = dis::decode(out.bytes, "encodeEdit");
  if (!decoded) return decoded.problems();
  auto got = fromPdu(decoded.value(), frame, e.time);
  if (!got) return got.problems();
  if (!got.value()) return problem("encodeEdit", "the PDU made no edit");  // cannot happen: toPdu sends our types
  out.edit = std::move(*got.value());
  return out;
}

Result<edit::Edit> asReceived(const edit::Edit& e, const DisFrame& frame, const ObjectSender& sender) {
  auto encoded = encodeEdit(e, frame, sender);
  if (!encoded) return encoded.problems();
  return std::move(encoded->edit);
}

}  // namespace sandtable::sim_dis
