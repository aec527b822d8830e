// Scripts (seed VIII.B; docs/SCRIPTS.md): the Figure 71 line reader and
// writer, Figure 73 playback, the dead-reckoning recorder, the merge of a
// played and a recorded script, and Table 7 paths as scripts.
#include "sandtable/sim/script.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <unordered_set>

#include "sandtable/sim/units.h"
#include "sandtable/sim/update_rule.h"
#include "sandtable/world/path.h"
#include "text.h"

namespace sandtable::sim {
namespace {

using namespace text;  // the line readers' shared helpers

constexpr std::size_t kMaxProblems = 20;
/// The most digits a whole-number field may have: this reader has always
/// refused longer words, leading zeros or not.
constexpr std::size_t kMaxDigits = 19;

constexpr const char* kFieldNames[kScriptFields] = {
    "Hours",     "Minutes",    "Seconds",        "Entity_Number",  "Entity_Type",
    "X_Position", "Y_Position", "Z_Position",     "Direction",      "View_Direction",
    "Gun_Elevation", "Above_Ground_Level", "Speed", "Fire_Flag", "Alive_Flag"};

class Reader {
 public:
  explicit Reader(std::string name) : name_(std::move(name)) {}

  Result<std::vector<ScriptLine>> run(std::string_view text) {
    std::size_t pos = 0;
    int lineNo = 0;
    while (pos < text.size()) {
      lineOffset_ = pos;
      const std::string_view line = nextLine(text, pos);
      line_ = ++lineNo;
      parseLine(line);
      if (problems_.size() >= kMaxProblems) break;
    }
    if (!problems_.empty()) return problems_;
    return std::move(lines_);
  }

 private:
  void fail(std::size_t column, const std::string& what) {
    if (problems_.size() >= kMaxProblems) return;
    problems_.push_back({name_, lineOffset_ + column, lineColumnMessage(line_, column, what)});
  }

  void parseLine(std::string_view line) {
    std::size_t end = 0;
    const auto tok = tokenize(line, end);
    if (tok.empty()) return;
    if (tok.size() < kScriptFields) {
      std::string m = "expected 15 fields (Hours Minutes Seconds Entity_Number Entity_Type X_Position "
                      "Y_Position Z_Position Direction View_Direction Gun_Elevation Above_Ground_Level "
                      "Speed Fire_Flag Alive_Flag), found ";
      m += std::to_string(tok.size());
      m += "; ";
      m += kFieldNames[tok.size()];
      m += " and the fields after it are missing";
      return fail(end, m);  // just past the last field, where the next should be
    }
    if (tok.size() > kScriptFields) {
      std::string m = "unexpected 16th field ";
      m += text::quoted(tok[kScriptFields].text);
      m += ": a script line has exactly 15 fields (a comment starts with #)";
      return fail(tok[kScriptFields].column, m);
    }
    ScriptLine s;
    s.line = line_;
    if (!clock(tok, s) || !ids(tok, s) || !floats(tok, s) || !flags(tok, s)) return;
    if (!lines_.empty() && s.timeS < lines_.back().timeS) {
      std::string m = "time ";
      m += shortNumber(s.timeS);
      m += " s is before the ";
      m += shortNumber(lines_.back().timeS);
      m += " s of line ";
      m += std::to_string(lines_.back().line);
      m += "; script lines must not go back in time: sort them by time";
      return fail(tok[0].column, m);
    }
    lines_.push_back(s);
  }

  bool clock(const std::vector<Token>& tok, ScriptLine& s) {
    std::uint64_t h = 0, m = 0;
    if (!unsignedNumber(tok[0].text, 999999, h, kMaxDigits)) {
      fail(tok[0].column, "Hours " + text::quoted(tok[0].text) + " must be a whole number >= 0 (\"00\")");
      return false;
    }
    if (!unsignedNumber(tok[1].text, 59, m, kMaxDigits)) {
      fail(tok[1].column, "Minutes " + text::quoted(tok[1].text) + " must be a whole number from 0 to 59 (\"00\")");
      return false;
    }
    double sec = 0;
    if (!finiteNumber(tok[2].text, sec) || sec < 0 || !(sec < 60)) {
      fail(tok[2].column, "Seconds " + text::quoted(tok[2].text) +
                              " must be a number >= 0 and below 60 (\"11\", or with a fraction \"11.016667\")");
      return false;
    }
    s.hours = static_cast<int>(h);
    s.minutes = static_cast<int>(m);
    s.seconds = sec;
    s.timeS = double(h) * 3600.0 + double(m) * 60.0 + sec;
    return true;
  }

  bool ids(const std::vector<Token>& tok, ScriptLine& s) {
    std::uint64_t v[2] = {0, 0};
    for (std::size_t k = 0; k < 2; ++k) {
      const Token& t = tok[3 + k];
      if (!unsignedNumber(t.text, std::numeric_limits<std::uint32_t>::max(), v[k], kMaxDigits)) {
        fail(t.column, std::string(kFieldNames[3 + k]) + " " + text::quoted(t.text) +
                           " must be a whole number from 0 to 4294967295");
        return false;
      }
    }
    s.entity = static_cast<std::uint32_t>(v[0]);
    s.type = static_cast<std::uint32_t>(v[1]);
    return true;
  }

  bool floats(const std::vector<Token>& tok, ScriptLine& s) {
    double* out[8] = {&s.x, &s.y, &s.z, &s.directionDeg, &s.viewDirectionDeg, &s.gunElevation,
                      &s.aboveGroundLevel, &s.speed};
    for (std::size_t k = 0; k < 8; ++k) {
      const Token& t = tok[5 + k];
      if (!finiteNumber(t.text, *out[k])) {
        fail(t.column, std::string(kFieldNames[5 + k]) + " " + text::quoted(t.text) +
                           " is not a finite number (write it like 8161.926270)");
        return false;
      }
    }
    return true;
  }

  bool flags(const std::vector<Token>& tok, ScriptLine& s) {
    bool* out[2] = {&s.fire, &s.alive};
    for (std::size_t k = 0; k < 2; ++k) {
      const Token& t = tok[13 + k];
      if (t.text != "0" && t.text != "1") {
        fail(t.column, std::string(kFieldNames[13 + k]) + " " + text::quoted(t.text) + " must be 0 or 1");
        return false;
      }
      *out[k] = t.text == "1";
    }
    return true;
  }

  std::string name_;
  std::vector<Problem> problems_;
  std::vector<ScriptLine> lines_;
  std::size_t lineOffset_ = 0;
  int line_ = 0;
};

/// t (seconds >= 0) in whole microseconds.
long long microseconds(double t) {
  if (!std::isfinite(t) || !(t > 0)) return 0;
  return std::llround(t * 1e6);
}

void appendF(std::string& out, const char* format, double v) {
  char buf[400];  // "%f" of the largest double is 316 characters
  const int n = std::snprintf(buf, sizeof buf, format, v);
  if (n > 0) out.append(buf, std::min<std::size_t>(static_cast<std::size_t>(n), sizeof buf - 1));
}

/// Degrees b - a wrapped to (-180, 180]. Not turnBetween (entity.h): that
/// goes through [0, 360), which rounds a small negative difference to the
/// last bit of 360, so the recorder's tolerance test could flip.
double angleDelta(double a, double b) {
  double d = std::fmod(b - a, 360.0);
  if (d > 180) d -= 360;
  if (d <= -180) d += 360;
  return d;
}

bool allFinite(const ScriptLine& s) {
  for (double v : {s.timeS, s.x, s.y, s.z, s.directionDeg, s.viewDirectionDeg, s.gunElevation,
                   s.aboveGroundLevel, s.speed}) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

bool byTime(const ScriptLine& a, const ScriptLine& b) { return a.timeS < b.timeS; }

std::vector<ScriptLine> sortedByTime(std::vector<ScriptLine> lines) {
  if (!std::is_sorted(lines.begin(), lines.end(), byTime)) std::stable_sort(lines.begin(), lines.end(), byTime);
  return lines;
}

}  // namespace

void ScriptLine::setTime(double t) {
  const long long us = microseconds(t);
  timeS = us == 0 ? 0.0 : t;
  const long long whole = us / 1000000;
  hours = static_cast<int>(whole / 3600);
  minutes = static_cast<int>((whole / 60) % 60);
  seconds = double(whole % 60) + double(us % 1000000) * 1e-6;
}

Result<std::vector<ScriptLine>> parseScript(std::string_view text, const std::string& name) {
  return Reader(name).run(text);
}

Result<std::vector<ScriptLine>> readScriptFile(const std::string& path) {
  // Recordings of long exercises with many entities are big: 256 MiB.
  auto body = text::readText(path, 256ull << 20, "the script file");
  if (!body) return body.problems();
  return parseScript(body.value(), path);
}

std::string formatScriptLine(const ScriptLine& s) {
  const long long us = microseconds(s.timeS);
  const long long whole = us / 1000000, fraction = us % 1000000;
  char buf[96];
  if (fraction == 0) {
    std::snprintf(buf, sizeof buf, "%02lld %02lld %02lld", whole / 3600, (whole / 60) % 60, whole % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%02lld %02lld %02lld.%06lld", whole / 3600, (whole / 60) % 60, whole % 60,
                  fraction);
  }
  std::string out = buf;
  std::snprintf(buf, sizeof buf, " %u %u", static_cast<unsigned>(s.entity), static_cast<unsigned>(s.type));
  out += buf;
  appendF(out, " %f", s.x);
  if (s.y == 0.0) {
    out += " 0.0";  // the seed's "follows the ground" marker, as Figure 71 writes it
  } else {
    appendF(out, " %f", s.y);
  }
  for (double v : {s.z, s.directionDeg, s.viewDirectionDeg, s.gunElevation, s.aboveGroundLevel, s.speed}) {
    appendF(out, " %f", v);
  }
  out += s.fire ? " 1" : " 0";
  out += s.alive ? " 1" : " 0";
  return out;
}

std::string formatScript(const std::vector<ScriptLine>& lines) {
  std::string out;
  for (const auto& l : lines) {
    out += formatScriptLine(l);
    out += '\n';
  }
  return out;
}

std::vector<ScriptEntity> scriptEntities(const std::vector<ScriptLine>& lines) {
  std::vector<ScriptEntity> out;
  std::unordered_set<std::uint32_t> seen;
  for (const auto& l : lines) {
    if (seen.insert(l.entity).second) out.push_back({l.entity, l.type, l.timeS});
  }
  return out;
}

Eigen::Vector2d deadReckon(const ScriptLine& line, double timeS) {
  const double dt = std::max(0.0, timeS - line.timeS);
  const double a = line.directionDeg * kDegToRad;
  return {line.x + std::sin(a) * line.speed * dt, line.z - std::cos(a) * line.speed * dt};
}

ScriptPlayer::ScriptPlayer(std::vector<ScriptLine> lines) : lines_(sortedByTime(std::move(lines))) {}

std::size_t ScriptPlayer::advance(double nowS, const std::function<bool(std::uint32_t)>& isAlive,
                                  const std::function<void(const ScriptLine&)>& apply) {
  std::size_t applied = 0;
  // The writer rounds times to the microsecond (up, half the time): a line
  // recorded at a step's time is still due at that step when read back.
  const double due = nowS + kScriptTimeResolutionS / 2;
  while (cursor_ < lines_.size() && lines_[cursor_].timeS <= due) {
    const ScriptLine& l = lines_[cursor_++];
    if (isAlive && !isAlive(l.entity)) continue;  // no reincarnation (seed VIII.B.3)
    if (apply) apply(l);
    ++applied;
  }
  return applied;
}

double ScriptPlayer::nextTimeS() const {
  if (lines_.empty()) return 0;
  return cursor_ < lines_.size() ? lines_[cursor_].timeS : lines_.back().timeS;
}

bool ScriptRecorder::changed(const ScriptLine& last, const ScriptLine& now) const {
  if (now.entity != last.entity || now.type != last.type || now.fire != last.fire || now.alive != last.alive) {
    return true;
  }
  if (std::abs(now.speed - last.speed) > options_.speedToleranceMs) return true;
  if (std::abs(now.y - last.y) > options_.heightToleranceM ||
      std::abs(now.aboveGroundLevel - last.aboveGroundLevel) > options_.heightToleranceM) {
    return true;
  }
  const double angleError = std::max({std::abs(angleDelta(last.directionDeg, now.directionDeg)),
                                      std::abs(angleDelta(last.viewDirectionDeg, now.viewDirectionDeg)),
                                      std::abs(now.gunElevation - last.gunElevation)});
  const Eigen::Vector2d predicted = deadReckon(last, now.timeS);
  const double positionError = (predicted - Eigen::Vector2d(now.x, now.z)).norm();
  const UpdateThresholds rule{options_.toleranceM, options_.angleToleranceDeg, options_.maxIntervalS};
  return updateDue(rule, positionError, angleError, now.timeS - last.timeS);
}

bool ScriptRecorder::record(const ScriptLine& state) {
  if (!allFinite(state) || state.timeS < 0) return false;
  if (hasOffered_ && state.timeS < lastOfferedS_) return false;
  hasOffered_ = true;
  lastOfferedS_ = state.timeS;
  ScriptLine s = state;
  s.setTime(state.timeS);
  s.line = 0;
  if (lines_.empty() || changed(lines_.back(), s)) {
    lines_.push_back(s);
    hasPending_ = false;
    return true;
  }
  pending_ = s;
  hasPending_ = true;
  return false;
}

void ScriptRecorder::finish() {
  if (!hasPending_) return;
  lines_.push_back(pending_);
  hasPending_ = false;
}

std::vector<ScriptLine> mergeScriptLines(const std::vector<ScriptLine>& played,
                                         const std::vector<ScriptLine>& recorded) {
  const auto a = sortedByTime(played), b = sortedByTime(recorded);
  std::vector<ScriptLine> out;
  out.reserve(a.size() + b.size());
  // std::merge puts the first range's element first among equals.
  std::merge(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out), byTime);
  return out;
}

std::string mergeScripts(const std::vector<ScriptLine>& played, const std::vector<ScriptLine>& recorded) {
  return formatScript(mergeScriptLines(played, recorded));
}

namespace {

bool moves(const world::PathWaypoint& a, const world::PathWaypoint& b) {
  return a.easting != b.easting || a.northing != b.northing;
}

/// Bearing of leg k (clockwise from north, [0, 360)), or of the nearest
/// moving leg before it, or after it; 0 when nothing moves.
double legBearing(const std::vector<world::PathWaypoint>& w, std::size_t k) {
  // Not headingOf (entity.h): it multiplies by kRadToDeg and wraps 360 to
  // 0, which differs from this in the last bit for about one angle in
  // nine; scripts made from paths keep their exact Direction values.
  auto bearing = [&](std::size_t m) {
    const double h = std::atan2(w[m + 1].easting - w[m].easting, w[m + 1].northing - w[m].northing) / kDegToRad;
    return h < 0 ? h + 360.0 : h;
  };
  for (std::size_t m = k + 1; m-- > 0;) {
    if (moves(w[m], w[m + 1])) return bearing(m);
  }
  for (std::size_t m = k + 1; m + 1 < w.size(); ++m) {
    if (moves(w[m], w[m + 1])) return bearing(m);
  }
  return 0;
}

std::string waypointRef(const world::PathWaypoint& w, std::size_t k) {
  if (w.line > 0) return "path line " + std::to_string(w.line);
  return "waypoint " + std::to_string(k + 1);
}

}  // namespace

Result<std::vector<ScriptLine>> scriptFromPath(const world::Path& path, std::uint32_t entity, std::uint32_t type,
                                               double originEasting, double originNorthing) {
  const auto& w = path.waypoints;
  if (w.size() < 2) {
    return Problem{kScriptProblem, 0,
                   "scriptFromPath: a path needs at least two waypoints, it has " + std::to_string(w.size())};
  }
  if (!std::isfinite(originEasting) || !std::isfinite(originNorthing)) {
    return Problem{kScriptProblem, 0, "scriptFromPath: the grid origin is not a finite easting/northing"};
  }
  std::vector<ScriptLine> out;
  auto lineAt = [&](std::size_t k, double speed) {
    ScriptLine s;
    s.setTime(w[k].timeS);
    s.entity = entity;
    s.type = type;
    s.x = w[k].easting - originEasting;
    s.z = originNorthing - w[k].northing;
    s.directionDeg = legBearing(w, std::min(k, w.size() - 2));
    s.speed = speed;
    s.line = w[k].line;
    out.push_back(s);
  };
  for (std::size_t k = 0; k + 1 < w.size(); ++k) {
    const double length = std::hypot(w[k + 1].easting - w[k].easting, w[k + 1].northing - w[k].northing);
    const double duration = w[k + 1].timeS - w[k].timeS;
    if (!std::isfinite(w[k].timeS) || !(duration >= 0) || (length > 0 && !(duration > 0))) {
      return Problem{kScriptProblem, 0,
                     "scriptFromPath: the leg from " + waypointRef(w[k], k) + " to " + waypointRef(w[k + 1], k + 1) +
                         " is " + shortNumber(length) + " m long in " + shortNumber(duration) +
                         " s; resolve the path (world::resolvePath) so times increase along moving legs"};
    }
    lineAt(k, length > 0 ? length / duration : 0.0);  // the mean speed: dead reckoning lands on w[k + 1]
  }
  lineAt(w.size() - 1, 0.0);
  return out;
}

}  // namespace sandtable::sim
