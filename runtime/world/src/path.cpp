#include "sandtable/world/path.h"

#include "sandtable/formats/bytes.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>

namespace sandtable::world {
namespace {

constexpr double kKmhToMs = 1.0 / 3.6;
constexpr std::size_t kMaxProblems = 20;
/// validateFlightOptions' bound on --height; checked here so that the error
/// names the file and line rather than --height.
constexpr double kMaxHeightAgl = 1e5;
constexpr const char* kLineForm =
    "expected \"lon lat height_m [speed=KMH] [time=S]\" (or \"easting northing height_m ...\" "
    "after \"frame projected\")";

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string lineRef(int line) { return line > 0 ? "line " + std::to_string(line) : "waypoint"; }

/// The whole token as a finite double, or nullopt ("12abc", "nan" fail).
std::optional<double> number(std::string_view s) {
  double v = 0;
  const char* end = s.data() + s.size();
  auto [p, ec] = std::from_chars(s.data(), end, v);
  if (ec != std::errc() || p != end || !std::isfinite(v)) return std::nullopt;
  return v;
}

/// Seconds, "M:SS(.s)" or "H:MM:SS(.s)" (Table 7 writes 0:00:10.2).
std::optional<double> timeValue(std::string_view s) {
  double total = 0;
  int parts = 0;
  while (true) {
    const auto colon = s.find(':');
    const auto v = number(s.substr(0, colon));
    if (!v || *v < 0) return std::nullopt;
    if (parts > 0 && *v >= 60) return std::nullopt;  // minutes and seconds fields
    total = total * 60 + *v;
    if (++parts > 3) return std::nullopt;
    if (colon == std::string_view::npos) break;
    if (std::floor(*v) != *v) return std::nullopt;  // only the seconds may have a fraction
    s.remove_prefix(colon + 1);
  }
  return total;
}

struct Parser {
  std::string name;
  const PathOptions& options;
  std::vector<Problem> problems;
  PathFrame frame = PathFrame::lonLat;
  bool frameSet = false;
  std::vector<PathPoint> points;

  void fail(int line, const std::string& message) {
    if (problems.size() < kMaxProblems) problems.push_back({name, 0, lineRef(line) + ": " + message});
  }

  void parseLine(int lineNo, std::string line) {
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream in(line);
    std::vector<std::string> tokens;
    for (std::string t; in >> t;) tokens.push_back(t);
    if (tokens.empty()) return;
    if (tokens[0] == "frame") return parseFrame(lineNo, tokens);
    parseWaypoint(lineNo, tokens);
  }

  void parseFrame(int lineNo, const std::vector<std::string>& tokens) {
    if (!points.empty() || frameSet) {
      return fail(lineNo, "\"frame\" must come once, before the first waypoint");
    }
    if (tokens.size() != 2 || (tokens[1] != "lonlat" && tokens[1] != "projected")) {
      return fail(lineNo, "expected \"frame lonlat\" (degrees, WGS 84) or \"frame projected\" "
                          "(easting northing in metres of the database CRS)");
    }
    frame = tokens[1] == "lonlat" ? PathFrame::lonLat : PathFrame::projected;
    frameSet = true;
  }

  void parseWaypoint(int lineNo, const std::vector<std::string>& tokens) {
    if (tokens.size() < 3) return fail(lineNo, kLineForm);
    const auto a = number(tokens[0]), b = number(tokens[1]), h = number(tokens[2]);
    if (!a || !b || !h) return fail(lineNo, std::string(kLineForm) + "; a coordinate or the height is not a number");
    if (*h < 0) return fail(lineNo, "height_m " + tokens[2] + " is metres above the ground and must be >= 0");
    if (!(*h < kMaxHeightAgl)) {
      return fail(lineNo, "height_m " + tokens[2] + " is metres above the ground and must be below " +
                              fmt(kMaxHeightAgl) + " (the limit of MotionOptions::heightAgl)");
    }
    PathPoint p;
    p.heightAgl = *h;
    p.line = lineNo;
    for (std::size_t k = 3; k < tokens.size(); ++k) {
      if (!parseField(lineNo, tokens[k], k == 3, p)) return;
    }
    if (!placePoint(lineNo, *a, *b, p)) return;
    points.push_back(p);
  }

  /// `speed=`, `time=`, or (old format) a bare speed in km/h as the 4th field.
  bool parseField(int lineNo, const std::string& tok, bool fourth, PathPoint& p) {
    const auto eq = tok.find('=');
    const std::string key = eq == std::string::npos ? "" : tok.substr(0, eq);
    const std::string_view value = eq == std::string::npos ? std::string_view(tok) : std::string_view(tok).substr(eq + 1);
    if (key == "time") {
      if (p.timeS) return fail(lineNo, "time= given twice"), false;
      p.timeS = timeValue(value);
      if (!p.timeS) return fail(lineNo, "time \"" + tok.substr(eq + 1) + "\" must be seconds >= 0 (45, 10.2) or H:MM:SS (0:00:45)"), false;
      return true;
    }
    if (key == "speed" || (key.empty() && eq == std::string::npos && fourth)) {
      if (p.speedKmh) return fail(lineNo, "speed given twice"), false;
      p.speedKmh = number(value);
      if (!p.speedKmh) return fail(lineNo, "speed \"" + std::string(value) + "\" is not a number (km/h)"), false;
      if (!(*p.speedKmh > 0)) {
        return fail(lineNo, "speed must be positive; to wait at a point, repeat the waypoint with a later time="), false;
      }
      return true;
    }
    if (eq == std::string::npos) {
      return fail(lineNo, "unexpected field \"" + tok + "\": after the height only speed=KMH and time=S "
                          "(or one bare speed in km/h, the old format) may follow"), false;
    }
    return fail(lineNo, "unknown key \"" + key + "\"; the keys are speed= (km/h) and time= (seconds)"), false;
  }

  bool placePoint(int lineNo, double a, double b, PathPoint& p) {
    if (frame == PathFrame::projected) {
      p.easting = a;
      p.northing = b;
      return true;
    }
    if (a < -180 || a > 180 || b < -90 || b > 90) {
      fail(lineNo, "lon " + fmt(a) + " lat " + fmt(b) + " is not a position in degrees; for easting "
                   "northing put \"frame projected\" on a line before the first waypoint");
      return false;
    }
    if (!options.toProjected) {
      fail(lineNo, "lon/lat waypoints need a converter to the database CRS (none was given)");
      return false;
    }
    if (std::string why = options.toProjected(a, b, p.easting, p.northing); !why.empty()) {
      fail(lineNo, why);
      return false;
    }
    return true;
  }
};

double legLength(const PathPoint& a, const PathPoint& b) {
  return std::hypot(b.easting - a.easting, b.northing - a.northing);
}

struct Resolver {
  const std::vector<PathPoint>& pts;
  const PathOptions& options;
  std::string file;
  std::vector<PathWaypoint> out;
  std::vector<Problem> problems;

  void fail(const std::string& message) { problems.push_back({file, 0, message}); }

  /// Legs i .. j-1 end at the given time of waypoint j.
  bool boundedRun(std::size_t i, std::size_t j) {
    const double span = *pts[j].timeS - out[i].timeS;
    if (span < 0) {
      fail(lineRef(pts[j].line) + ": time=" + fmt(*pts[j].timeS) + " is before the " + fmt(out[i].timeS) +
           " s already reached at " + lineRef(pts[i].line) + "; times must not decrease");
      return false;
    }
    double fixedS = 0, freeLength = 0;
    std::size_t freeLegs = 0;
    for (std::size_t k = i; k < j; ++k) {
      const double d = legLength(pts[k], pts[k + 1]);
      if (pts[k].speedKmh) {
        fixedS += d / (*pts[k].speedKmh * kKmhToMs);
      } else {
        freeLength += d;
        ++freeLegs;
      }
    }
    const double left = span - fixedS;
    const std::string between = lineRef(pts[i].line) + " to " + lineRef(pts[j].line);
    double stretch = 1, freeSpeed = 0, freeWait = 0;
    if (freeLegs == 0) {
      // Over-determined: speeds and the end time both given (not in
      // Table 7). Accept rounding; the given time wins.
      const double tol = std::max(0.05, options.overdeterminedTolerance * span);
      if (std::abs(left) > tol) {
        fail("legs " + between + ": the speeds given take " + fmt(fixedS) + " s but time= allows " + fmt(span) +
             " s; drop speed= from a leg or time= from " + lineRef(pts[j].line) + ", or make them agree");
        return false;
      }
      stretch = fixedS > 0 ? span / fixedS : 1;
    } else if (freeLength > 0) {
      if (left <= 0) {
        fail("legs " + between + ": the legs with speed= already take " + fmt(fixedS) + " s, but time= at " +
             lineRef(pts[j].line) + " leaves " + fmt(span) + " s; raise a speed or give a later time");
        return false;
      }
      freeSpeed = freeLength / left;
    } else {
      if (left < -std::max(0.05, options.overdeterminedTolerance * span)) {
        fail("legs " + between + ": the legs with speed= already take " + fmt(fixedS) + " s, but time= at " +
             lineRef(pts[j].line) + " leaves " + fmt(span) + " s; raise a speed or give a later time");
        return false;
      }
      freeWait = std::max(left, 0.0) / double(freeLegs);  // zero-length legs: the eye waits
    }
    for (std::size_t k = i; k < j; ++k) {
      const double d = legLength(pts[k], pts[k + 1]);
      double legS = 0;
      if (pts[k].speedKmh) {
        legS = d / (*pts[k].speedKmh * kKmhToMs) * stretch;
      } else {
        legS = freeLength > 0 ? d / freeSpeed : freeWait;
      }
      out[k].legSpeedMs = legS > 0 ? d / legS : (pts[k].speedKmh ? *pts[k].speedKmh * kKmhToMs : 0);
      out[k + 1].timeS = k + 1 == j ? *pts[j].timeS : out[k].timeS + legS;
    }
    return true;
  }

  /// Legs from i to the end, with no given time after i.
  bool openRun(std::size_t i) {
    for (std::size_t k = i; k + 1 < pts.size(); ++k) {
      double v = 0;
      if (pts[k].speedKmh) {
        v = *pts[k].speedKmh * kKmhToMs;
      } else if (options.defaultSpeedKmh) {
        v = *options.defaultSpeedKmh * kKmhToMs;
      } else {
        // The speed holds (seed VI.B.2): the last leg that moved, not a wait.
        for (std::size_t m = k; m-- > 0 && !(v > 0);) v = out[m].legSpeedMs;
      }
      if (!(v > 0)) {
        fail(lineRef(pts[k].line) + ": the leg starting here has no speed= and no later waypoint has a time=; "
             "add speed=KMH here or time=S on a later waypoint");
        return false;
      }
      out[k].legSpeedMs = v;
      out[k + 1].timeS = out[k].timeS + legLength(pts[k], pts[k + 1]) / v;
    }
    return true;
  }

  bool run() {
    if (pts.size() < 2) {
      fail("a path needs at least two waypoints, it has " + std::to_string(pts.size()));
      return false;
    }
    out.resize(pts.size());
    for (std::size_t k = 0; k < pts.size(); ++k) {
      out[k].easting = pts[k].easting;
      out[k].northing = pts[k].northing;
      out[k].heightAgl = pts[k].heightAgl;
      out[k].timeGiven = pts[k].timeS.has_value();
      out[k].speedGiven = pts[k].speedKmh.has_value() && k + 1 < pts.size();
      out[k].line = pts[k].line;
    }
    out[0].timeS = pts[0].timeS.value_or(0.0);
    std::size_t i = 0;
    while (i + 1 < pts.size()) {
      std::size_t j = i + 1;
      while (j < pts.size() && !pts[j].timeS) ++j;
      if (j == pts.size()) return openRun(i);
      if (!boundedRun(i, j)) return false;
      i = j;
    }
    return true;
  }
};

double headingOf(const PathWaypoint& a, const PathWaypoint& b) {
  double h = std::atan2(b.easting - a.easting, b.northing - a.northing) * 180.0 / std::numbers::pi;
  return h < 0 ? h + 360.0 : h;
}

bool moves(const PathWaypoint& a, const PathWaypoint& b) {
  return a.easting != b.easting || a.northing != b.northing;
}

/// Heading of leg k, or of the nearest moving leg before it, or after it.
double legHeading(const std::vector<PathWaypoint>& w, std::size_t k) {
  for (std::size_t m = k + 1; m-- > 0;) {
    if (moves(w[m], w[m + 1])) return headingOf(w[m], w[m + 1]);
  }
  for (std::size_t m = k + 1; m + 1 < w.size(); ++m) {
    if (moves(w[m], w[m + 1])) return headingOf(w[m], w[m + 1]);
  }
  return 0;
}

}  // namespace

Result<Path> resolvePath(const std::vector<PathPoint>& points, const PathOptions& options,
                         const std::string& file, PathFrame frame) {
  Resolver r{points, options, file, {}, {}};
  if (!r.run()) return r.problems;
  Path p;
  p.frame = frame;
  p.waypoints = std::move(r.out);
  return p;
}

Result<Path> parsePath(std::string_view text, const std::string& name, const PathOptions& options) {
  Parser parser{name, options, {}, PathFrame::lonLat, false, {}};
  std::istringstream in{std::string(text)};
  std::string line;
  for (int lineNo = 1; std::getline(in, line); ++lineNo) parser.parseLine(lineNo, line);
  if (!parser.problems.empty()) return parser.problems;
  return resolvePath(parser.points, options, name, parser.frame);
}

std::string pathProblemText(const Problem& p) {
  // "line N: rest" is how Parser::fail and the resolver name a line.
  const std::string_view m = p.message;
  constexpr std::string_view kLine = "line ";
  if (m.substr(0, kLine.size()) == kLine) {
    const std::size_t digits = m.find_first_not_of("0123456789", kLine.size());
    if (digits != std::string_view::npos && digits > kLine.size() && m.substr(digits, 2) == ": ") {
      return p.file + ":" + std::string(m.substr(kLine.size(), digits - kLine.size())) + ": " +
             std::string(m.substr(digits + 2));
    }
  }
  return p.file + ": " + p.message;
}

Result<Path> readPathFile(const std::string& file, const PathOptions& options) {
  // A bound, so that /dev/zero or a huge file is refused rather than read
  // into memory; a path of a million waypoints fits (docs/PATH.md).
  constexpr std::uint64_t kMaxPathFileBytes = 64ull << 20;
  auto bytes = readSmallFile(file, kMaxPathFileBytes);
  if (!bytes) return Problem{file, 0, "cannot open the path file: " + bytes.message()};
  const auto& b = bytes.value();
  return parsePath(std::string_view(reinterpret_cast<const char*>(b.data()), b.size()), file, options);
}

namespace {

/// Heading difference b - a, wrapped to (-180, 180].
double headingDelta(double a, double b) {
  double d = std::fmod(b - a, 360.0);
  if (d > 180) d -= 360;
  if (d <= -180) d += 360;
  return d;
}

/// The heading while turning round waypoint j (between legs j - 1 and j),
/// or nullopt when t is outside that turn.
std::optional<double> turning(const Path& path, std::size_t j, double t) {
  const auto& w = path.waypoints;
  if (j == 0 || j + 1 >= w.size() || !(path.turnRateDegS > 0)) return std::nullopt;
  const double in = legHeading(w, j - 1), out = legHeading(w, j);
  const double delta = headingDelta(in, out);
  const double half = std::min({std::abs(delta) / path.turnRateDegS / 2,
                                (w[j].timeS - w[j - 1].timeS) / 2, (w[j + 1].timeS - w[j].timeS) / 2});
  if (!(half > 0) || std::abs(t - w[j].timeS) >= half) return std::nullopt;
  const double f = (t - (w[j].timeS - half)) / (2 * half);
  double h = std::fmod(in + f * delta, 360.0);
  return h < 0 ? h + 360 : h;
}

}  // namespace

Pose samplePath(const Path& path, double t) {
  const auto& w = path.waypoints;
  Pose p;
  if (w.empty()) return p;
  auto at = [&](const PathWaypoint& x, double heading) {
    p.easting = x.easting;
    p.northing = x.northing;
    p.heightAgl = x.heightAgl;
    p.headingDeg = heading;
    p.speedKmh = 0;
    return p;
  };
  if (w.size() == 1) return at(w[0], 0);
  if (!(t > w.front().timeS)) {
    // On the first waypoint the eye is already moving at the first leg's
    // speed (frame 0's panel read 0); before it, it waits there.
    at(w.front(), legHeading(w, 0));
    if (t == w.front().timeS) p.speedKmh = w.front().legSpeedMs * 3.6;
    return p;
  }
  if (t >= w.back().timeS) return at(w.back(), legHeading(w, w.size() - 2));
  // First waypoint later than t; the leg before it holds t.
  const auto next = std::upper_bound(w.begin(), w.end(), t,
                                     [](double v, const PathWaypoint& x) { return v < x.timeS; });
  const std::size_t k = std::size_t(next - w.begin()) - 1;
  const PathWaypoint &a = w[k], &b = w[k + 1];
  const double span = b.timeS - a.timeS;
  const double f = span > 0 ? (t - a.timeS) / span : 1.0;
  p.easting = a.easting + f * (b.easting - a.easting);
  p.northing = a.northing + f * (b.northing - a.northing);
  p.heightAgl = a.heightAgl + f * (b.heightAgl - a.heightAgl);
  p.headingDeg = turning(path, k, t).value_or(turning(path, k + 1, t).value_or(legHeading(w, k)));
  p.speedKmh = a.legSpeedMs * 3.6;
  return p;
}

}  // namespace sandtable::world
