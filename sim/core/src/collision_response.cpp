// Collision response (seed VII.C): the "sandtable-collisions 1" table
// parser and lookup (Table 6), Figure 64's moving/moving rule with the
// glancing bounce, and the contact ray of Figures 62-63.
#include "sandtable/sim/collision_response.h"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "sandtable/formats/bytes.h"
#include "sandtable/sim/entity.h"
#include "text.h"

namespace sandtable::sim {
namespace {

using namespace text;  // the line readers' shared helpers

constexpr std::string_view kHeader = "sandtable-collisions";
constexpr std::uint64_t kMaxFileBytes = 1u << 20;
constexpr std::size_t kMaxProblems = 20;
/// Beyond any vehicle or munition (seed Table 1 tops out at 3000 km/h).
constexpr double kMaxEdgeKmh = 100000;

/// Seed Table 6; samples/collisions.txt holds the same text (a test
/// checks that both parse to the same table).
constexpr std::string_view kDefaultText =
    R"TABLE(# Sandtable collision response table: the built-in default, seed Table 6
# (Pratt 1993, VII.C.1) as editable text. Grammar in docs/COLLISIONS.md.
#
# When a moving entity hits a static object, the simulator looks up the
# row for (entity class, object class) and picks the column for the
# entity's speed bin. Each cell is ENTITY/OBJECT: what happens to the
# entity (none, stop, destroyed) and to the object (none, knocked-over,
# stump, ruins, destroyed).
sandtable-collisions 1

# Speed bins, km/h, per entity class: slow below the first edge, medium
# from the first edge up to (not including) the second, fast from the
# second edge up. Equal edges leave no medium bin; "0 0" makes every
# speed fast (a missile always hits with its full explosive effect).
# The seed gives no numbers; these are Sandtable's.
#      class    medium-from fast-from
speeds tank     10          40
speeds airplane 150         400
speeds missile  0           0

# Seed Table 6: the faster the entity the more damage; the more mass in
# the object the more damage to the entity; weapons always do maximum
# damage.
#      entity   object slow              medium                  fast
result tank     tree   stop/none         destroyed/knocked-over  destroyed/stump
result tank     house  stop/none         destroyed/none          destroyed/ruins
result tank     rock   stop/none         destroyed/none          destroyed/none
result airplane tree   destroyed/none    destroyed/knocked-over  destroyed/stump
result airplane house  destroyed/none    destroyed/none          destroyed/ruins
result airplane rock   stop/none         destroyed/none          destroyed/none
result missile  tree   destroyed/destroyed destroyed/destroyed   destroyed/destroyed
result missile  house  destroyed/destroyed destroyed/destroyed   destroyed/destroyed
result missile  rock   destroyed/none    destroyed/none          destroyed/none

# Any pair with no result row (an unknown entity or object class).
default stop/none
)TABLE";

// ------------------------------------------------------------ table text

bool validName(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' ||
           c == '.';
  });
}

std::optional<EntityResult> entityWord(std::string_view s) {
  if (s == "none") return EntityResult::none;
  if (s == "stop") return EntityResult::stop;
  if (s == "destroyed") return EntityResult::destroyed;
  return std::nullopt;
}

std::optional<ObjectResult> objectWord(std::string_view s) {
  if (s == "none") return ObjectResult::none;
  if (s == "knocked-over") return ObjectResult::knockedOver;
  if (s == "stump") return ObjectResult::stump;
  if (s == "ruins") return ObjectResult::ruins;
  if (s == "destroyed") return ObjectResult::destroyed;
  return std::nullopt;
}

/// Where a row was first given, for "already given on line N" and for
/// the end-of-file check that every entity class has speeds.
struct Where {
  std::size_t line = 0;
  std::uint64_t offset = 0;
  std::size_t column = 0;
};

class Parser {
 public:
  Parser(std::string_view text, std::string file) : text_(text), file_(std::move(file)) {}

  Result<CollisionTable> run() {
    bool header = false;
    std::size_t pos = 0;
    while (pos < text_.size() && problems_.size() < kMaxProblems) {
      lineOffset_ = pos;
      const std::string_view line = nextLine(text_, pos);
      ++line_;
      if (!plainText(line)) continue;
      const auto tok = tokenize(line);
      if (tok.empty()) continue;
      lineLength_ = line.size();
      if (!header) {
        if (!headerLine(tok)) return problems_;
        header = true;
        continue;
      }
      directive(tok);
    }
    if (!header) {
      lineOffset_ = text_.size();
      ++line_;
      failAt(0, "the table is empty; its first line that is not a comment must be \"sandtable-collisions 1\"");
      return problems_;
    }
    checkSpeedsGiven();
    if (!problems_.empty()) return problems_;
    return table_;
  }

 private:
  /// A problem at 0-based `column` of the current line.
  void failAt(std::size_t column, const std::string& what) {
    if (problems_.size() >= kMaxProblems) return;
    problems_.push_back({file_, lineOffset_ + column, lineColumnMessage(line_, column, what)});
  }
  void fail(const Token& t, const std::string& what) { failAt(t.column, what); }

  bool plainText(std::string_view line) {
    const std::size_t k = findControl(line);
    if (k == std::string_view::npos) return true;
    failAt(k, controlCharacter(line[k]) + "; the table is plain text");
    return false;
  }

  /// The field count is wrong: point at the first extra word, or at the
  /// end of the line when words are missing.
  void wrongCount(const std::vector<Token>& tok, std::size_t want, const std::string& form) {
    std::string m = std::string(tok[0].text);
    m += " takes ";
    m += std::to_string(want - 1);
    m += want == 2 ? " field" : " fields";
    m += ", not ";
    m += std::to_string(tok.size() - 1);
    m += ": ";
    m += form;
    if (tok.size() > want) return fail(tok[want], m);
    failAt(lineLength_, m);
  }

  bool headerLine(const std::vector<Token>& tok) {
    if (tok[0].text == kHeader && tok.size() == 2) {
      if (tok[1].text == "1") return true;
      std::uint64_t v = 0;
      const auto [p, ec] = std::from_chars(tok[1].text.data(), tok[1].text.data() + tok[1].text.size(), v);
      if (ec == std::errc() && p == tok[1].text.data() + tok[1].text.size() && v > 1) {
        std::string m = "version ";
        m += std::to_string(v);
        m += " is newer than this reader knows (1); use a newer sandtable";
        fail(tok[1], m);
        return false;
      }
      fail(tok[1], "the header's version must be 1: \"sandtable-collisions 1\"");
      return false;
    }
    fail(tok[0], "missing header; the first line that is not a comment must be \"sandtable-collisions 1\"");
    return false;
  }

  void directive(const std::vector<Token>& tok) {
    if (tok[0].text == "speeds") return speedsLine(tok);
    if (tok[0].text == "result") return resultLine(tok);
    if (tok[0].text == "default") return defaultLine(tok);
    if (tok[0].text == kHeader) return fail(tok[0], "the header \"sandtable-collisions 1\" may appear only once");
    std::string m = "unknown directive ";
    m += text::quoted(tok[0].text);
    m += " (known: speeds, result, default)";
    fail(tok[0], m);
  }

  bool className(const Token& t, const char* what) {
    if (validName(t.text)) return true;
    std::string m = what;
    m += " class name ";
    m += text::quoted(t.text);
    m += " may hold only letters, digits, '_', '-' and '.'";
    fail(t, m);
    return false;
  }

  std::optional<double> edge(const Token& t) {
    double v = 0;
    if (finiteNumber(t.text, v) && v >= 0 && v <= kMaxEdgeKmh) return v;
    std::string m = "speed edge ";
    m += text::quoted(t.text);
    m += " must be a number of km/h from 0 to ";
    m += shortNumber(kMaxEdgeKmh);
    fail(t, m);
    return std::nullopt;
  }

  void speedsLine(const std::vector<Token>& tok) {
    if (tok.size() != 4) return wrongCount(tok, 4, "speeds CLASS MEDIUM_FROM_KMH FAST_FROM_KMH");
    if (!className(tok[1], "entity")) return;
    const std::string cls(tok[1].text);
    if (const auto it = speedsWhere_.find(cls); it != speedsWhere_.end()) {
      std::string m = "speeds for ";
      m += text::quoted(cls);
      m += " were already given on line ";
      m += std::to_string(it->second.line);
      m += "; keep one speeds line per entity class";
      return fail(tok[1], m);
    }
    const auto medium = edge(tok[2]);
    const auto fast = edge(tok[3]);
    if (!medium || !fast) return;
    if (*fast < *medium) {
      std::string m = "speed edges must not decrease: the fast edge ";
      m += shortNumber(*fast);
      m += " km/h is below the medium edge ";
      m += shortNumber(*medium);
      m += " km/h; swap them";
      return fail(tok[3], m);
    }
    table_.speeds[cls] = {*medium, *fast};
    speedsWhere_[cls] = {line_, lineOffset_ + tok[1].column, tok[1].column};
  }

  /// "ENTITY/OBJECT" as one cell, or nullopt (a problem reported).
  std::optional<StaticOutcome> cell(const Token& t) {
    const std::size_t slash = t.text.find('/');
    if (slash == std::string_view::npos || t.text.find('/', slash + 1) != std::string_view::npos) {
      std::string m = "cell ";
      m += text::quoted(t.text);
      m += " must be ENTITY/OBJECT, for example stop/none";
      fail(t, m);
      return std::nullopt;
    }
    const auto e = entityWord(t.text.substr(0, slash));
    if (!e) {
      std::string m = "unknown entity result ";
      m += text::quoted(t.text.substr(0, slash));
      m += " (known: none, stop, destroyed)";
      fail(t, m);
      return std::nullopt;
    }
    const auto o = objectWord(t.text.substr(slash + 1));
    if (!o) {
      std::string m = "unknown object result ";
      m += text::quoted(t.text.substr(slash + 1));
      m += " (known: none, knocked-over, stump, ruins, destroyed)";
      fail({t.text.substr(slash + 1), t.column + slash + 1}, m);
      return std::nullopt;
    }
    return StaticOutcome{*e, *o};
  }

  void resultLine(const std::vector<Token>& tok) {
    if (tok.size() != 6) return wrongCount(tok, 6, "result ENTITY OBJECT SLOW MEDIUM FAST, each cell ENTITY/OBJECT");
    if (!className(tok[1], "entity") || !className(tok[2], "object")) return;
    const std::string entity(tok[1].text), object(tok[2].text);
    if (const auto it = resultWhere_.find({entity, object}); it != resultWhere_.end()) {
      std::string m = "a result for ";
      m += entity;
      m += " hitting ";
      m += object;
      m += " was already given on line ";
      m += std::to_string(it->second.line);
      m += "; keep one row per pair";
      return fail(tok[1], m);
    }
    BinOutcomes row;
    bool ok = true;
    for (std::size_t k = 0; k < 3; ++k) {
      const auto c = cell(tok[3 + k]);
      if (c) row[k] = *c;
      else ok = false;
    }
    const Where here{line_, lineOffset_ + tok[1].column, tok[1].column};
    resultWhere_[{entity, object}] = here;
    firstResultWhere_.try_emplace(entity, here);
    if (ok) table_.results[entity][object] = row;
  }

  void defaultLine(const std::vector<Token>& tok) {
    if (tok.size() != 2) return wrongCount(tok, 2, "default ENTITY/OBJECT");
    if (defaultWhere_.line != 0) {
      std::string m = "default was already given on line ";
      m += std::to_string(defaultWhere_.line);
      m += "; keep one";
      return fail(tok[0], m);
    }
    defaultWhere_ = {line_, lineOffset_, 0};
    if (const auto c = cell(tok[1])) table_.unknown = *c;
  }

  /// Every entity class with a result row needs speed bins: without them
  /// its medium and fast columns could never be reached.
  void checkSpeedsGiven() {
    for (const auto& [entity, where] : firstResultWhere_) {
      if (table_.speeds.count(entity)) continue;
      line_ = where.line;
      lineOffset_ = where.offset - where.column;
      std::string m = "entity class ";
      m += text::quoted(entity);
      m += " has results but no speeds line; add \"speeds ";
      m += entity;
      m += " MEDIUM_FROM_KMH FAST_FROM_KMH\"";
      failAt(where.column, m);
    }
  }

  std::string_view text_;
  std::string file_;
  std::uint64_t lineOffset_ = 0;
  std::size_t line_ = 0;
  std::size_t lineLength_ = 0;
  CollisionTable table_;
  std::map<std::string, Where> speedsWhere_;
  std::map<std::pair<std::string, std::string>, Where> resultWhere_;
  std::map<std::string, Where> firstResultWhere_;
  Where defaultWhere_;
  std::vector<Problem> problems_;
};

// ------------------------------------------------------------ geometry

/// Compass bearing of a ground-plane vector (x east, z south): clockwise
/// from north, which is -z; [0, 360).
double bearingDeg(const Eigen::Vector2d& v) { return headingOf(v.x(), v.y()); }

/// The unit ground-plane vector of a heading. Not entity.h's headingVector:
/// this divides by kRadToDeg where that multiplies by kDegToRad, and the
/// two differ in the last bit for about one angle in nine (200 of the 1441
/// whole degrees from -720 to 720).
Eigen::Vector2d groundVector(double headingDeg) {
  const double r = headingDeg / kRadToDeg;
  return {std::sin(r), -std::cos(r)};
}

/// Figure 64's bounds are whole degrees; a bearing computed from
/// positions built at an edge angle misses it by rounding only.
double snapDeg(double d) {
  const double whole = std::round(d);
  return std::abs(d - whole) <= 1e-9 ? wrapDeg(whole) : d;
}

/// Glancing bounce of one velocity: the component along `away` (the unit
/// normal pointing from the other entity to this one) made to point
/// away, the tangential one kept, the whole scaled by keep.
Eigen::Vector2d bounce(const Eigen::Vector2d& v, const Eigen::Vector2d& away, double keep) {
  const double along = v.dot(away);
  const Eigen::Vector2d tangential = v - along * away;
  return keep * (tangential + std::abs(along) * away);
}

/// The heading of a velocity after a bounce; a stopped one keeps its old.
double headingAfter(const Eigen::Vector2d& v, double oldHeadingDeg) {
  return v.squaredNorm() > 0 ? bearingDeg(v) : wrapDeg(oldHeadingDeg);
}

/// Möller-Trumbore on a triangle already in the ray's frame.
std::optional<double> rayTriangleD(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Eigen::Vector3d& a,
                                   const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Barycentric slack so that a ray through a shared edge (a cube face's
  // diagonal, a box's corner) meets at least one of the two triangles.
  constexpr double kEdgeSlack = 1e-9;
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d p = dir.cross(e2);
  const double det = e1.dot(p);
  // Parallel or degenerate, relative to the sizes involved.
  if (!(std::abs(det) > 1e-12 * e1.norm() * e2.norm() * dir.norm())) return std::nullopt;
  const double inv = 1.0 / det;
  const Eigen::Vector3d s = origin - a;
  const double u = s.dot(p) * inv;
  if (u < -kEdgeSlack || u > 1 + kEdgeSlack) return std::nullopt;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = dir.dot(q) * inv;
  if (v < -kEdgeSlack || u + v > 1 + kEdgeSlack) return std::nullopt;
  const double t = e2.dot(q) * inv;
  if (!(t >= 0)) return std::nullopt;
  return t;
}

Eigen::Vector3d toWorld(const Eigen::Affine3d& m, const Eigen::Vector3f& p) { return m * p.cast<double>(); }

/// The largest t >= 0 at which the ray meets any triangle after mapping
/// them to the world; 0 when it meets none.
double farthestHit(const std::vector<Triangle>& tris, const Eigen::Affine3d& bodyToWorld,
                   const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) {
  double best = 0;
  for (const Triangle& t : tris) {
    // In double throughout: a world position in float loses centimetres.
    const Eigen::Vector3d a = toWorld(bodyToWorld, t.a), b = toWorld(bodyToWorld, t.b),
                          c = toWorld(bodyToWorld, t.c);
    if (const auto hit = rayTriangleD(origin, dir, a, b, c)) best = std::max(best, *hit);
  }
  return best;
}

}  // namespace

std::string_view resultName(EntityResult r) {
  switch (r) {
    case EntityResult::none: return "none";
    case EntityResult::stop: return "stop";
    case EntityResult::destroyed: return "destroyed";
  }
  return "?";
}

std::string_view resultName(ObjectResult r) {
  switch (r) {
    case ObjectResult::none: return "none";
    case ObjectResult::knockedOver: return "knocked-over";
    case ObjectResult::stump: return "stump";
    case ObjectResult::ruins: return "ruins";
    case ObjectResult::destroyed: return "destroyed";
  }
  return "?";
}

Result<CollisionTable> parseCollisionTable(std::string_view text, const std::string& name) {
  return Parser(text, name).run();
}

Result<CollisionTable> readCollisionTable(const std::string& path) {
  auto body = text::readText(path, kMaxFileBytes, "the collision table", "collision table: ");
  if (!body) return body.problems();
  return parseCollisionTable(body.value(), path);
}

std::string_view defaultCollisionTableText() { return kDefaultText; }

const CollisionTable& defaultCollisionTable() {
  // The text is a constant the tests parse, so this cannot fail; should
  // it ever, the empty table answers stop/none for every pair.
  static const CollisionTable table = [] {
    auto r = parseCollisionTable(kDefaultText, "built-in collision table");
    return r ? r.value() : CollisionTable{};
  }();
  return table;
}

SpeedBin speedBin(const CollisionTable& table, std::string_view entityClass, double speedMs) {
  const auto it = table.speeds.find(entityClass);
  const double s = std::abs(speedMs);
  if (it == table.speeds.end() || std::isnan(s)) return SpeedBin::slow;
  // The edges divided, not the speed multiplied: edge / 3.6 from a caller
  // then compares equal to the edge.
  if (s >= it->second.fastKmh / 3.6) return SpeedBin::fast;
  if (s >= it->second.mediumKmh / 3.6) return SpeedBin::medium;
  return SpeedBin::slow;
}

StaticOutcome lookup(const CollisionTable& table, std::string_view entityClass, std::string_view objectClass,
                     double speedMs) {
  const auto rows = table.results.find(entityClass);
  if (rows == table.results.end()) return table.unknown;
  const auto row = rows->second.find(objectClass);
  if (row == rows->second.end()) return table.unknown;
  return row->second[static_cast<std::size_t>(speedBin(table, entityClass, speedMs))];
}

ImpactKind classifyImpact(double relativeBearingDeg) {
  if (std::isnan(relativeBearingDeg)) return ImpactKind::glancing;
  const double a = wrapDeg(relativeBearingDeg);
  if (a <= 5 || a >= 355) return ImpactKind::front;
  if (a >= 85 && a <= 95) return ImpactKind::right;
  if (a >= 175 && a <= 185) return ImpactKind::rear;
  if (a >= 265 && a <= 275) return ImpactKind::left;
  return ImpactKind::glancing;
}

MovingOutcome resolveMoving(const MovingState& a, const MovingState& b, double killSpeedMs, double bounceKeep) {
  MovingOutcome out;
  const Eigen::Vector2d d = b.position - a.position;
  const double dist = d.norm();
  // The line of centres, A to B; coincident entities use A's heading.
  const Eigen::Vector2d n = dist > 0 ? Eigen::Vector2d(d / dist) : groundVector(a.headingDeg);
  const double bearingAB = dist > 0 ? bearingDeg(d) : wrapDeg(a.headingDeg);
  out.kindA = classifyImpact(snapDeg(wrapDeg(bearingAB - a.headingDeg)));
  out.kindB = classifyImpact(snapDeg(wrapDeg(bearingAB + 180.0 - b.headingDeg)));
  out.newHeadingA = wrapDeg(a.headingDeg);
  out.newHeadingB = wrapDeg(b.headingDeg);
  if (out.kindA != ImpactKind::glancing) {
    // Kill or stop: either way both stand still where they are.
    const bool kill = (a.velocity - b.velocity).norm() > killSpeedMs;
    out.killA = out.killB = kill;
    out.stopA = out.stopB = !kill;
    return out;
  }
  const double keep = std::isnan(bounceKeep) ? kDefaultBounceKeep : std::clamp(bounceKeep, 0.0, 1.0);
  out.newVelocityA = bounce(a.velocity, -n, keep);
  out.newVelocityB = bounce(b.velocity, n, keep);
  out.newHeadingA = headingAfter(out.newVelocityA, a.headingDeg);
  out.newHeadingB = headingAfter(out.newVelocityB, b.headingDeg);
  return out;
}

std::optional<double> rayTriangle(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, const Triangle& tri) {
  return rayTriangleD(origin, dir, tri.a.cast<double>(), tri.b.cast<double>(), tri.c.cast<double>());
}

Contact contactPoint(const std::vector<Triangle>& trisA, const Eigen::Affine3d& bodyToWorldA,
                     const std::vector<Triangle>& trisB, const Eigen::Affine3d& bodyToWorldB) {
  Contact c;
  const Eigen::Vector3d oA = bodyToWorldA.translation(), oB = bodyToWorldB.translation();
  const Eigen::Vector3d d = oB - oA;
  const double dist = d.norm();
  double along = 0;  // where the contact point lies on the ray from A
  if (dist > 0) {
    const Eigen::Vector3d u = d / dist;
    c.distA = farthestHit(trisA, bodyToWorldA, oA, u);
    c.distB = farthestHit(trisB, bodyToWorldB, oB, -u);
    // Figure 63: the two icons' extents along the ray do not reach each other.
    if (c.distA + c.distB < dist) return c;
    // The overlap runs from B's surface (dist - distB) to A's (distA).
    along = 0.5 * (c.distA + dist - c.distB);
    c.worldPoint = oA + along * u;
  } else {
    c.worldPoint = oA;
  }
  c.hit = true;
  c.bodyPointA = bodyToWorldA.inverse(Eigen::Affine) * c.worldPoint;
  c.bodyPointB = bodyToWorldB.inverse(Eigen::Affine) * c.worldPoint;
  return c;
}

}  // namespace sandtable::sim
