// Scenario files (docs/SCRIPTS.md §5): a line reader that checks every
// word and names line and column, and the seeded placement of groups.
#include "sandtable/sim/scenario.h"

#include <algorithm>
#include <filesystem>
#include <limits>
#include <map>

#include "sandtable/base/hash.h"
#include "sandtable/edits/profile.h"
#include "sandtable/sim/entity.h"
#include "text.h"

namespace sandtable::sim {
namespace {

using namespace text;  // the line readers' shared helpers

constexpr std::size_t kMaxProblems = 20;
constexpr std::size_t kMaxName = 64;
constexpr int kMaxGroupCount = 100000;
// Entity lines and group members together: the simulator allocates for
// each before its first step, so the cap is checked as the file is read.
constexpr std::uint64_t kMaxScenarioEntities = 100000;
constexpr double kMaxSpeedKmh = 15000;  // about Mach 12: above any munition
constexpr double kMaxHeightM = 100000;  // the bound of paths and --height
constexpr double kMinAltitudeM = -500;  // below the Dead Sea shore (-430 m)
constexpr const char* kHeader = "sandtable-scenario 1";
constexpr const char* kEntityKeys =
    "icon, force, domain, mobility, at, heading, speed, altitude, agl, behaviour, script, script-entity, "
    "aircraft, fuel (and the word driven)";
constexpr const char* kGroupKeys =
    "name, icon, force, domain, mobility, area, heading, speed, altitude, agl, behaviour, aircraft, fuel";
// Terrain edit lines' bounds: a crater from a hand grenade's to a large
// bomb's, earthworks a few metres to a kilometre wide and up to 100 m high
// or deep; a flatten's height from below the Dead Sea to above Everest.
constexpr double kMinCraterRadiusM = edits::kFinestSpacing;
constexpr double kMaxCraterRadiusM = 500;
constexpr double kMaxEditDepthM = 100;
constexpr double kMaxEditWidthM = 1000;
constexpr double kMaxSlope = 100;  // rise over run: near a wall
constexpr double kMaxGroundM = 9000;

/// A terrain edit directive: its kind and keys.
struct EditDirective {
  std::string_view word;
  edit::Kind kind;
  std::vector<std::string_view> keys;
  const char* keyList;
};

/// The edit directive `word` names, or null.
const EditDirective* editDirective(std::string_view word) {
  static const EditDirective table[] = {
      {"crater", edit::Kind::crater, {"at", "size", "radius", "depth"}, "at, size, radius, depth"},
      {"berm", edit::Kind::berm, {"line", "width", "height", "slope"}, "line, width, height, slope"},
      {"ditch", edit::Kind::ditch, {"line", "width", "depth", "slope"}, "line, width, depth, slope"},
      {"flatten", edit::Kind::flatten, {"polygon", "height", "slope"}, "polygon, height, slope"},
  };
  for (const auto& d : table) {
    if (d.word == word) return &d;
  }
  return nullptr;
}

/// "A,B,..." as exactly n finite numbers.
std::optional<std::vector<double>> numberList(std::string_view s, std::size_t n) {
  std::vector<double> out;
  while (true) {
    const auto comma = s.find(',');
    const auto v = finiteNumber(s.substr(0, comma));
    if (!v) return std::nullopt;
    out.push_back(*v);
    if (comma == std::string_view::npos) break;
    s.remove_prefix(comma + 1);
  }
  if (out.size() != n) return std::nullopt;
  return out;
}

/// "A..B" or "A" (both ends A).
std::optional<std::pair<double, double>> range(std::string_view s) {
  const auto dots = s.find("..");
  if (dots == std::string_view::npos) {
    const auto v = finiteNumber(s);
    if (!v) return std::nullopt;
    return std::pair{*v, *v};
  }
  const auto lo = finiteNumber(s.substr(0, dots)), hi = finiteNumber(s.substr(dots + 2));
  if (!lo || !hi) return std::nullopt;
  return std::pair{*lo, *hi};
}

bool validName(std::string_view s) {
  if (s.empty() || s.size() > kMaxName) return false;
  for (char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

std::optional<ScenarioDomain> domainWord(std::string_view s) {
  if (s == "land") return ScenarioDomain::land;
  if (s == "sea") return ScenarioDomain::sea;
  if (s == "air") return ScenarioDomain::air;
  if (s == "munition") return ScenarioDomain::munition;
  return std::nullopt;
}

std::optional<ScenarioMobility> mobilityWord(std::string_view s) {
  if (s == "simple") return ScenarioMobility::simple;
  if (s == "tracked") return ScenarioMobility::tracked;
  if (s == "wheeled") return ScenarioMobility::wheeled;
  if (s == "ship") return ScenarioMobility::ship;
  if (s == "aircraft") return ScenarioMobility::aircraft;
  return std::nullopt;
}

ScenarioMobility defaultMobility(ScenarioDomain d) {
  switch (d) {
    case ScenarioDomain::land: return ScenarioMobility::tracked;
    case ScenarioDomain::sea: return ScenarioMobility::ship;
    case ScenarioDomain::air: return ScenarioMobility::aircraft;
    case ScenarioDomain::munition: return ScenarioMobility::simple;
  }
  return ScenarioMobility::simple;
}

/// The domain a mobility needs, or nullopt for `simple` (any).
std::optional<ScenarioDomain> mobilityDomain(ScenarioMobility m) {
  switch (m) {
    case ScenarioMobility::tracked:
    case ScenarioMobility::wheeled: return ScenarioDomain::land;
    case ScenarioMobility::ship: return ScenarioDomain::sea;
    case ScenarioMobility::aircraft: return ScenarioDomain::air;
    case ScenarioMobility::simple: return std::nullopt;
  }
  return std::nullopt;
}

/// FNV-1a: a group's name as a 64-bit key for its members' draws.
std::uint64_t nameKey(std::string_view s) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (char c : s) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ull;
  }
  return h;
}

/// Which kind of line a key=value list belongs to: its messages differ.
enum class Owner { entity, group, edit };

/// One key=value of a directive, and where it is.
struct Field {
  std::string_view value;
  std::size_t keyColumn = 0, valueColumn = 0;
};

/// What entity and group lines share, read from their key=value words.
struct Common {
  std::string icon;
  std::uint8_t force = kScenarioNeutral;
  ScenarioDomain domain = ScenarioDomain::land;
  ScenarioMobility mobility = ScenarioMobility::tracked;
  std::pair<double, double> heading{0, 0}, speedMs{0, 0};
  std::optional<std::pair<double, double>> altitude, agl;
  ScenarioBehaviour behaviour;
  std::string aircraft;
  double fuel = 1.0;
};

class Reader {
 public:
  explicit Reader(std::string name) : name_(std::move(name)) {
    dir_ = std::filesystem::path(name_).parent_path();
  }

  Result<Scenario> run(std::string_view text) {
    out_.source = name_;
    std::size_t pos = 0;
    while (pos < text.size()) {
      lineOffset_ = pos;
      const std::string_view line = nextLine(text, pos);
      ++line_;
      if (!parseLine(line) || problems_.size() >= kMaxProblems) break;
    }
    if (problems_.empty() && !header_) {
      line_ = 1;
      lineOffset_ = 0;
      fail(0, std::string("the file is empty; a scenario starts with the line \"") + kHeader + "\"");
    }
    // A line's keys are checked in a fixed order: report in file order.
    std::stable_sort(problems_.begin(), problems_.end(),
                     [](const Problem& a, const Problem& b) { return a.offset < b.offset; });
    if (!problems_.empty()) return problems_;
    return std::move(out_);
  }

 private:
  void fail(std::size_t column, const std::string& what) {
    if (problems_.size() >= kMaxProblems) return;
    problems_.push_back({name_, lineOffset_ + column, lineColumnMessage(line_, column, what)});
  }

  /// False stops the reading (a file without the header is not a scenario).
  bool parseLine(std::string_view line) {
    const auto tok = tokenize(line);
    if (tok.empty()) return true;
    if (!header_) return headerLine(tok);
    const std::string_view d = tok[0].text;
    if (d == "frame") {
      frameLine(tok);
    } else if (d == "seed") {
      seedLine(tok);
    } else if (d == "entity") {
      entityLine(tok);
    } else if (d == "group") {
      groupLine(tok);
    } else if (const EditDirective* directive = editDirective(d)) {
      editLine(tok, *directive);
    } else if (d == "sandtable-scenario") {
      fail(tok[0].column, "the header \"sandtable-scenario\" may come only once, on the first line");
    } else {
      fail(tok[0].column, "unknown directive " + text::quoted(d) +
                              "; the directives are frame, seed, entity, group, crater, berm, ditch and flatten");
    }
    return true;
  }

  bool headerLine(const std::vector<Token>& tok) {
    if (tok[0].text != "sandtable-scenario") {
      fail(tok[0].column, std::string("this is not a scenario file: its first line must be \"") + kHeader + "\"");
      return false;
    }
    if (tok.size() != 2 || tok[1].text != "1") {
      const std::size_t col = tok.size() > 1 ? tok[1].column : tok[0].column;
      fail(col, std::string("this reader knows scenario version 1 only; write \"") + kHeader + "\"");
      return false;
    }
    header_ = true;
    return true;
  }

  void frameLine(const std::vector<Token>& tok) {
    if (frameSet_ || !out_.entities.empty() || !out_.groups.empty() || !out_.terrainEdits.empty()) {
      return fail(tok[0].column, "\"frame\" may come once, before the first entity, group or terrain edit");
    }
    if (tok.size() != 2 || (tok[1].text != "lonlat" && tok[1].text != "projected")) {
      const std::size_t col = tok.size() > 1 ? tok[1].column : tok[0].column;
      return fail(col, "expected \"frame lonlat\" (at= is longitude,latitude in degrees, WGS 84) or \"frame "
                       "projected\" (at= is easting,northing in metres of the database CRS)");
    }
    out_.frame = tok[1].text == "lonlat" ? ScenarioFrame::lonLat : ScenarioFrame::projected;
    frameSet_ = true;
  }

  void seedLine(const std::vector<Token>& tok) {
    if (out_.seed) return fail(tok[0].column, "\"seed\" may come only once");
    if (tok.size() != 2) {
      const std::size_t col = tok.size() > 2 ? tok[2].column : tok[0].column;
      return fail(col, "expected \"seed N\" with one whole number N from 0 to 18446744073709551615");
    }
    const auto v = unsignedNumber(tok[1].text, std::numeric_limits<std::uint64_t>::max());
    if (!v) {
      return fail(tok[1].column, "seed " + text::quoted(tok[1].text) +
                                     " must be a whole number from 0 to 18446744073709551615");
    }
    out_.seed = *v;
  }

  /// Reads key=value words from tok[first]; `allowed` lists the keys.
  /// Sets `driven` for the bare word on an entity line. False on a problem.
  bool fields(const std::vector<Token>& tok, std::size_t first, const std::vector<std::string_view>& allowed,
              const char* keyList, Owner owner, std::map<std::string_view, Field>& out,
              std::optional<std::size_t>& drivenColumn) {
    const bool allowDriven = owner == Owner::entity;
    bool ok = true;
    for (std::size_t k = first; k < tok.size(); ++k) {
      const Token& t = tok[k];
      const auto eq = t.text.find('=');
      if (eq == std::string_view::npos) {
        if (t.text == "driven" && allowDriven) {
          if (drivenColumn) {
            fail(t.column, "driven is given twice");
            ok = false;
          }
          drivenColumn = t.column;
          continue;
        }
        if (t.text == "driven" && owner == Owner::group) {
          fail(t.column, "a group cannot be driven; make the driven entity an entity line");
        } else {
          fail(t.column, "unexpected word " + text::quoted(t.text) + "; write key=value, the keys are " + keyList);
        }
        ok = false;
        continue;
      }
      const std::string_view key = t.text.substr(0, eq);
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        std::string m = "unknown key " + text::quoted(key) + "; the keys are ";
        m += keyList;
        if (owner == Owner::group && (key == "at" || key == "script" || key == "script-entity")) {
          m = text::quoted(key) + " is not for a group: its members are scattered over area= (keys: ";
          m += keyList;
          m += ")";
        }
        fail(t.column, m);
        ok = false;
        continue;
      }
      if (eq + 1 == t.text.size()) {
        fail(t.column + eq + 1, text::quoted(key) + " has no value; write " + std::string(key) + "=VALUE");
        ok = false;
        continue;
      }
      if (out.count(key)) {
        fail(t.column, std::string(key) + "= is given twice");
        ok = false;
        continue;
      }
      out[key] = {t.text.substr(eq + 1), t.column, t.column + eq + 1};
    }
    return ok;
  }

  /// A new name: valid and not used before.
  bool claimName(std::string_view name, std::size_t column, const char* what) {
    if (!validName(name)) {
      fail(column, std::string(what) + " name " + text::quoted(name) + " must be 1 to 64 letters, digits, '_' or '-'");
      return false;
    }
    const auto it = names_.find(std::string(name));
    if (it != names_.end()) {
      fail(column, "the name " + text::quoted(name) + " is already used at line " + std::to_string(it->second) +
                       "; give each entity and group its own name");
      return false;
    }
    names_[std::string(name)] = line_;
    return true;
  }

  /// A value in a range of numbers, e.g. speed=10..30 or speed=20.
  bool numbers(const std::map<std::string_view, Field>& f, std::string_view key, bool allowRange, double lo,
               double hi, const char* unit, std::optional<std::pair<double, double>>& out) {
    const auto it = f.find(key);
    if (it == f.end()) return true;
    const Field& v = it->second;
    const auto r = allowRange ? range(v.value) : [&]() -> std::optional<std::pair<double, double>> {
      const auto n = finiteNumber(v.value);
      if (!n) return std::nullopt;
      return std::pair{*n, *n};
    }();
    std::string bounds = "from " + shortNumber(lo) + " to " + shortNumber(hi) + " " + unit;
    if (!r) {
      fail(v.valueColumn, std::string(key) + "=" + std::string(v.value) + " is not " +
                              (allowRange ? "a number or a range LOW..HIGH " : "a number ") + bounds);
      return false;
    }
    if (r->first > r->second) {
      fail(v.valueColumn, std::string(key) + "=" + std::string(v.value) + ": the low end " + shortNumber(r->first) +
                              " is above the high end " + shortNumber(r->second) + "; write LOW..HIGH");
      return false;
    }
    if (r->first < lo || r->second > hi) {
      fail(v.valueColumn, std::string(key) + "=" + std::string(v.value) + " is out of bounds; give a value " + bounds);
      return false;
    }
    out = r;
    return true;
  }

  std::string resolvedPath(std::string_view file) const {
    const std::filesystem::path p{std::string(file)};
    if (p.is_absolute() || dir_.empty()) return p.string();
    return (dir_ / p).lexically_normal().string();
  }

  /// icon, force, domain, mobility, heading, speed, altitude, agl,
  /// behaviour, aircraft, fuel. `directiveColumn` is where a missing key's
  /// problem points.
  bool common(const std::map<std::string_view, Field>& f, std::size_t directiveColumn, const std::string& who,
              bool allowRanges, Common& c) {
    bool ok = true;
    if (const auto it = f.find("icon"); it != f.end()) {
      c.icon = std::string(it->second.value);
    } else {
      fail(directiveColumn, who + " has no icon=; add icon=NAME (an icon of the database's icons.pack)");
      ok = false;
    }
    if (const auto it = f.find("force"); it != f.end()) {
      const std::string_view v = it->second.value;
      if (v == "neutral") c.force = kScenarioNeutral;
      else if (v == "blue") c.force = kScenarioBlue;
      else if (v == "red") c.force = kScenarioRed;
      else if (v == "green") c.force = kScenarioGreen;
      else if (const auto n = unsignedNumber(v, 255)) c.force = static_cast<std::uint8_t>(*n);
      else {
        fail(it->second.valueColumn, "force=" + std::string(v) + " must be blue, red, green, neutral or 0..255");
        ok = false;
      }
    }
    if (const auto it = f.find("domain"); it != f.end()) {
      if (const auto d = domainWord(it->second.value)) {
        c.domain = *d;
      } else {
        fail(it->second.valueColumn, "domain=" + std::string(it->second.value) + " must be land, sea, air or munition");
        ok = false;
      }
    }
    c.mobility = defaultMobility(c.domain);
    if (const auto it = f.find("mobility"); it != f.end()) {
      const auto m = mobilityWord(it->second.value);
      if (!m) {
        fail(it->second.valueColumn, "mobility=" + std::string(it->second.value) +
                                         " must be simple, tracked, wheeled, ship or aircraft");
        ok = false;
      } else if (const auto need = mobilityDomain(*m); need && *need != c.domain) {
        fail(it->second.valueColumn, "mobility=" + std::string(it->second.value) + " needs domain=" +
                                         std::string(scenarioWord(*need)) + ", not domain=" +
                                         std::string(scenarioWord(c.domain)) + "; change one (simple suits any domain)");
        ok = false;
      } else {
        c.mobility = *m;
      }
    }
    std::optional<std::pair<double, double>> r;
    if (allowRanges) {
      c.heading = {0, 360};
      if (!numbers(f, "heading", true, -360, 360, "degrees", r)) ok = false;
      if (r) {
        if (r->second - r->first > 360) {
          fail(f.at("heading").valueColumn, "heading=" + std::string(f.at("heading").value) +
                                                " spans more than 360 degrees; 0..360 covers every heading");
          ok = false;
        }
        c.heading = *r;
      }
    } else {
      if (!numbers(f, "heading", false, -360, 360, "degrees clockwise from north", r)) ok = false;
      if (r) c.heading = {wrapDeg(r->first), wrapDeg(r->first)};
    }
    r.reset();
    if (!numbers(f, "speed", allowRanges, 0, kMaxSpeedKmh, "km/h", r)) ok = false;
    if (r) c.speedMs = {r->first / 3.6, r->second / 3.6};
    if (!numbers(f, "altitude", allowRanges, kMinAltitudeM, kMaxHeightM, "metres above the datum", c.altitude)) {
      ok = false;
    }
    if (!numbers(f, "agl", allowRanges, 0, kMaxHeightM, "metres above the ground", c.agl)) ok = false;
    if (f.count("altitude") && f.count("agl")) {
      fail(f.at("agl").keyColumn, "give altitude= (above the datum) or agl= (above the ground), not both");
      ok = false;
    }
    for (const char* key : {"altitude", "agl"}) {
      if (f.count(key) && c.domain != ScenarioDomain::air && c.domain != ScenarioDomain::munition) {
        fail(f.at(key).keyColumn, std::string(key) + "= is for domain=air or domain=munition; a " +
                                      std::string(scenarioWord(c.domain)) + " entity follows the ground or sea");
        ok = false;
      }
    }
    if (const auto it = f.find("behaviour"); it != f.end() && !behaviourValue(it->second, c.behaviour)) ok = false;
    if (const auto it = f.find("aircraft"); it != f.end()) {
      if (c.mobility != ScenarioMobility::aircraft) {
        fail(it->second.keyColumn, "aircraft= (the flight model file) is for mobility=aircraft; add domain=air");
        ok = false;
      }
      c.aircraft = resolvedPath(it->second.value);
    }
    if (const auto it = f.find("fuel"); it != f.end()) {
      const auto v = finiteNumber(it->second.value);
      if (!v || *v < 0 || *v > 1) {
        fail(it->second.valueColumn, "fuel=" + std::string(it->second.value) +
                                         " must be the fraction of a full tank, from 0 to 1 (0.5: half full)");
        ok = false;
      } else {
        c.fuel = *v;
      }
    }
    return ok;
  }

  bool behaviourValue(const Field& f, ScenarioBehaviour& b) {
    std::string_view s = f.value;
    std::size_t col = f.valueColumn;
    bool none = false, other = false;
    while (true) {
      const auto comma = s.find(',');
      const std::string_view w = s.substr(0, comma);
      if (w == "none") none = true;
      else if (w == "noise") b.zigzag = b.environment = b.edge = b.fight = other = true;
      else if (w == "zigzag") b.zigzag = other = true;
      else if (w == "environment") b.environment = other = true;
      else if (w == "edge") b.edge = other = true;
      else if (w == "fight") b.fight = other = true;
      else if (w == "engage") b.engage = other = true;
      else {
        fail(col, "behaviour " + text::quoted(w) + " is not known; write none, noise (all four), or a comma list of "
                                             "zigzag, environment, edge, fight, engage");
        return false;
      }
      if (comma == std::string_view::npos) break;
      s.remove_prefix(comma + 1);
      col += comma + 1;
    }
    if (none && other) {
      fail(f.valueColumn, "behaviour=none cannot be combined with other behaviours");
      return false;
    }
    return true;
  }

  /// at=A,B in the file's frame.
  bool position(const Field& f, std::size_t n, std::vector<double>& v) {
    const auto list = numberList(f.value, n);
    const bool lonLat = out_.frame == ScenarioFrame::lonLat;
    const char* form = n == 2 ? (lonLat ? "LON,LAT" : "EASTING,NORTHING")
                              : (lonLat ? "MINLON,MINLAT,MAXLON,MAXLAT" : "MINE,MINN,MAXE,MAXN");
    if (!list) {
      fail(f.valueColumn, text::quoted(f.value) + " must be " + std::to_string(n) + " numbers " + form +
                              ", separated by commas without spaces");
      return false;
    }
    v = *list;
    if (lonLat) {
      for (std::size_t k = 0; k < n; k += 2) {
        if (v[k] < -180 || v[k] > 180 || v[k + 1] < -90 || v[k + 1] > 90) {
          fail(f.valueColumn, "lon " + shortNumber(v[k]) + " lat " + shortNumber(v[k + 1]) +
                                  " is not a position in degrees; for easting,northing put \"frame projected\" "
                                  "before the first entity");
          return false;
        }
      }
    }
    return true;
  }

  void entityLine(const std::vector<Token>& tok) {
    if (tok.size() < 2) {
      return fail(tok[0].column, "expected \"entity NAME icon=ICON at=A,B ...\"; the entity has no name");
    }
    const bool named = claimName(tok[1].text, tok[1].column, "entity");
    std::map<std::string_view, Field> f;
    std::optional<std::size_t> drivenColumn;
    static const std::vector<std::string_view> keys = {
        "icon", "force", "domain", "mobility", "at", "heading", "speed", "altitude", "agl", "behaviour",
        "script", "script-entity", "aircraft", "fuel"};
    if (!fields(tok, 2, keys, kEntityKeys, Owner::entity, f, drivenColumn) || !named) return;
    EntitySpec e;
    e.name = std::string(tok[1].text);
    e.line = line_;
    e.lonLat = out_.frame == ScenarioFrame::lonLat;
    Common c;
    bool ok = common(f, tok[0].column, "entity " + text::quoted(e.name), false, c);
    if (const auto it = f.find("at"); it != f.end()) {
      std::vector<double> v;
      if (position(it->second, 2, v)) {
        e.a = v[0];
        e.b = v[1];
      } else {
        ok = false;
      }
    }
    ok = scriptKeys(f, drivenColumn, e) && ok;
    if (!f.count("at") && !f.count("script")) {
      fail(tok[0].column, "entity " + text::quoted(e.name) + " has no at=; add at=" +
                              (e.lonLat ? "LON,LAT" : "EASTING,NORTHING") + " (or script=FILE to let a script place it)");
      ok = false;
    }
    if (drivenColumn && out_.driven) {
      fail(*drivenColumn, "only one entity can be driven; entity " + text::quoted(out_.entities[*out_.driven].name) +
                              " at line " + std::to_string(out_.entities[*out_.driven].line) + " already is");
      ok = false;
    }
    if (!ok) return;
    e.icon = c.icon;
    e.force = c.force;
    e.domain = c.domain;
    e.mobility = c.mobility;
    e.headingDeg = c.heading.first;
    e.speedMs = c.speedMs.first;
    if (c.altitude) e.altitude = c.altitude->first;
    if (c.agl) e.agl = c.agl->first;
    e.behaviour = c.behaviour;
    e.aircraft = c.aircraft;
    e.fuel = c.fuel;
    if (!claimEntities(1, tok[0].column)) return;
    e.driven = drivenColumn.has_value();
    if (e.driven) out_.driven = out_.entities.size();
    out_.entities.push_back(std::move(e));
  }

  /// script= and script-entity=, and what a scripted entity cannot have.
  bool scriptKeys(const std::map<std::string_view, Field>& f, std::optional<std::size_t> drivenColumn,
                  EntitySpec& e) {
    const auto s = f.find("script"), n = f.find("script-entity");
    if (s == f.end()) {
      if (n == f.end()) return true;
      fail(n->second.keyColumn, "script-entity= needs script=FILE, the script that holds that Entity_Number");
      return false;
    }
    if (n == f.end()) {
      fail(s->second.keyColumn, "script= needs script-entity=N, the Entity_Number this entity plays in the script");
      return false;
    }
    bool ok = true;
    if (const auto v = unsignedNumber(n->second.value, std::numeric_limits<std::uint32_t>::max())) {
      e.scriptEntity = static_cast<std::uint32_t>(*v);
    } else {
      fail(n->second.valueColumn, "script-entity=" + std::string(n->second.value) +
                                      " must be an Entity_Number, a whole number from 0 to 4294967295");
      ok = false;
    }
    e.script = resolvedPath(s->second.value);
    if (drivenColumn) {
      fail(*drivenColumn, "a scripted entity cannot be driven; drop driven or script=");
      ok = false;
    }
    for (const char* key : {"heading", "speed", "behaviour"}) {
      if (f.count(key)) {
        fail(f.at(key).keyColumn, std::string(key) + "= does nothing on a scripted entity (its script moves it); "
                                                     "drop it or script=");
        ok = false;
      }
    }
    return ok;
  }

  void groupLine(const std::vector<Token>& tok) {
    if (tok.size() < 2) return fail(tok[0].column, "expected \"group COUNT icon=ICON area=... \"; the count is missing");
    const auto count = unsignedNumber(tok[1].text, kMaxGroupCount);
    if (!count || *count == 0) {
      return fail(tok[1].column, "group count " + text::quoted(tok[1].text) + " must be a whole number from 1 to " +
                                     std::to_string(kMaxGroupCount));
    }
    ++groupNumber_;
    std::map<std::string_view, Field> f;
    std::optional<std::size_t> drivenColumn;
    static const std::vector<std::string_view> keys = {"name", "icon", "force", "domain", "mobility", "area", "heading",
                                                       "speed", "altitude", "agl", "behaviour", "aircraft", "fuel"};
    if (!fields(tok, 2, keys, kGroupKeys, Owner::group, f, drivenColumn)) return;
    GroupSpec g;
    g.count = static_cast<int>(*count);
    g.line = line_;
    g.lonLat = out_.frame == ScenarioFrame::lonLat;
    bool ok = true;
    if (const auto it = f.find("name"); it != f.end()) {
      g.name = std::string(it->second.value);
      ok = claimName(g.name, it->second.valueColumn, "group");
    } else {
      g.name = "group" + std::to_string(groupNumber_);
      ok = claimName(g.name, tok[0].column, "group");
    }
    Common c;
    ok = common(f, tok[0].column, "group " + text::quoted(g.name), true, c) && ok;
    if (const auto it = f.find("area"); it != f.end()) {
      std::vector<double> v;
      if (!position(it->second, 4, v)) {
        ok = false;
      } else if (v[0] > v[2] || v[1] > v[3]) {
        fail(it->second.valueColumn, "area=" + std::string(it->second.value) +
                                         " has a minimum above its maximum; write MIN,MIN,MAX,MAX (west,south,east,north)");
        ok = false;
      } else {
        g.minA = v[0];
        g.minB = v[1];
        g.maxA = v[2];
        g.maxB = v[3];
      }
    } else {
      fail(tok[0].column, "group " + text::quoted(g.name) + " has no area=; add area=" +
                              (g.lonLat ? "MINLON,MINLAT,MAXLON,MAXLAT" : "MINE,MINN,MAXE,MAXN"));
      ok = false;
    }
    if (!ok) return;
    g.icon = c.icon;
    g.force = c.force;
    g.domain = c.domain;
    g.mobility = c.mobility;
    g.headingMinDeg = c.heading.first;
    g.headingMaxDeg = c.heading.second;
    g.speedMinMs = c.speedMs.first;
    g.speedMaxMs = c.speedMs.second;
    if (c.altitude) {
      g.altitudeMin = c.altitude->first;
      g.altitudeMax = c.altitude->second;
    }
    if (c.agl) {
      g.aglMin = c.agl->first;
      g.aglMax = c.agl->second;
    }
    g.behaviour = c.behaviour;
    g.aircraft = c.aircraft;
    g.fuel = c.fuel;
    if (!claimEntities(*count, tok[1].column)) return;
    out_.groups.push_back(std::move(g));
  }

  /// key=V with lo < V <= hi (lo <= V when `zeroAllowed`); nothing when
  /// the key is absent. False on a problem.
  bool bounded(const std::map<std::string_view, Field>& f, std::string_view key, double lo, bool zeroAllowed, double hi,
               const char* unit, std::optional<double>& out) {
    const auto it = f.find(key);
    if (it == f.end()) return true;
    const Field& v = it->second;
    const std::string bounds = std::string(zeroAllowed ? "from " : "above ") + shortNumber(lo) +
                               (zeroAllowed ? " to " : " and at most ") + shortNumber(hi) + " " + unit;
    const auto n = finiteNumber(v.value);
    if (!n) {
      fail(v.valueColumn, std::string(key) + "=" + std::string(v.value) + " is not a number " + bounds);
      return false;
    }
    if (*n < lo || (*n == lo && !zeroAllowed) || *n > hi) {
      fail(v.valueColumn, std::string(key) + "=" + std::string(v.value) + " is out of bounds; give a value " + bounds);
      return false;
    }
    out = *n;
    return true;
  }

  /// A required key's value, or a problem at the directive naming it.
  bool required(const std::map<std::string_view, Field>& f, std::string_view key, std::size_t directiveColumn,
                const std::string& who, const std::string& form) {
    if (f.count(key)) return true;
    fail(directiveColumn, who + " has no " + std::string(key) + "=; add " + std::string(key) + "=" + form);
    return false;
  }

  /// "A,B;C,D;..." (line= or polygon=) in the file's frame: at least
  /// `least` points, at most kMaxScenarioEditPoints, counted before any is
  /// stored.
  bool pointList(const Field& f, std::string_view key, std::size_t least, const std::string& who,
                 std::vector<std::array<double, 2>>& out) {
    const bool lonLat = out_.frame == ScenarioFrame::lonLat;
    const char* pair = lonLat ? "LON,LAT" : "EASTING,NORTHING";
    const std::size_t count = 1 + static_cast<std::size_t>(std::count(f.value.begin(), f.value.end(), ';'));
    if (count > kMaxScenarioEditPoints) {
      fail(f.valueColumn, std::string(key) + "= has " + std::to_string(count) + " points, more than the " +
                              std::to_string(kMaxScenarioEditPoints) + " a line may hold; split it into several lines");
      return false;
    }
    if (count < least) {
      fail(f.valueColumn, std::string(key) + "= has " + std::to_string(count) + " point" + (count == 1 ? "" : "s") +
                              "; " + who + " needs at least " + std::to_string(least) + ": " + pair + ";" + pair +
                              (least > 2 ? std::string(";") + pair : std::string()) + " ...");
      return false;
    }
    out.reserve(count);
    std::string_view rest = f.value;
    std::size_t column = f.valueColumn;
    for (std::size_t k = 1; k <= count; ++k) {
      const std::size_t semi = rest.find(';');
      const std::string_view piece = rest.substr(0, semi);
      const auto v = numberList(piece, 2);
      if (!v) {
        fail(column, "point " + std::to_string(k) + " " + text::quoted(piece) + " of " + std::string(key) +
                         "= must be two numbers " + pair + "; write the points as " + pair + ";" + pair +
                         " ... with no spaces");
        return false;
      }
      if (lonLat && ((*v)[0] < -180 || (*v)[0] > 180 || (*v)[1] < -90 || (*v)[1] > 90)) {
        fail(column, "point " + std::to_string(k) + ": lon " + shortNumber((*v)[0]) + " lat " + shortNumber((*v)[1]) +
                         " is not a position in degrees; for easting,northing put \"frame projected\" before the "
                         "first entity");
        return false;
      }
      out.push_back({(*v)[0], (*v)[1]});
      column += piece.size() + 1;
      if (semi != std::string_view::npos) rest.remove_prefix(semi + 1);
    }
    return true;
  }

  /// A crater's size: size=small|medium|large (edits/profile.h), or
  /// radius= and depth= both.
  bool craterSize(const std::map<std::string_view, Field>& f, std::size_t directiveColumn, TerrainEditSpec& e) {
    const auto size = f.find("size"), radius = f.find("radius"), depth = f.find("depth");
    if (size != f.end()) {
      if (radius != f.end() || depth != f.end()) {
        const Field& extra = radius != f.end() ? radius->second : depth->second;
        fail(extra.keyColumn, "give size= or radius= and depth=, not both");
        return false;
      }
      const std::string_view w = size->second.value;
      const edits::CraterSize* c = w == "small"    ? &edits::kCraterSmall
                                   : w == "medium" ? &edits::kCraterMedium
                                   : w == "large"  ? &edits::kCraterLarge
                                                   : nullptr;
      if (!c) {
        auto both = [](const edits::CraterSize& z) {
          return shortNumber(z.radius) + " m, " + shortNumber(z.depth) + " m";
        };
        fail(size->second.valueColumn, "size=" + std::string(w) + " must be small (radius, depth: " +
                                           both(edits::kCraterSmall) + "), medium (" + both(edits::kCraterMedium) +
                                           ") or large (" + both(edits::kCraterLarge) + "); or give radius=M depth=M");
        return false;
      }
      e.radius = c->radius;
      e.depth = c->depth;
      return true;
    }
    if (radius == f.end() && depth == f.end()) {
      fail(directiveColumn, "crater has no size=; add size=small|medium|large, or radius=M depth=M");
      return false;
    }
    if (radius == f.end() || depth == f.end()) {
      const Field& given = radius != f.end() ? radius->second : depth->second;
      fail(given.keyColumn, radius != f.end() ? "radius= needs depth= (the centre's depth below the ground, metres)"
                                              : "depth= needs radius= (the rim crest's radius, metres)");
      return false;
    }
    std::optional<double> r, d;
    bool ok = bounded(f, "radius", kMinCraterRadiusM, true, kMaxCraterRadiusM, "metres", r);
    ok = bounded(f, "depth", 0, false, kMaxEditDepthM, "metres", d) && ok;
    if (!ok) return false;
    e.radius = *r;
    e.depth = *d;
    return true;
  }

  /// Twice the signed area of a polygon (the shoelace formula), in the
  /// file's units: zero when every corner lies on one line.
  static double twiceArea(const std::vector<std::array<double, 2>>& p) {
    double a = 0;
    for (std::size_t k = 0; k < p.size(); ++k) {
      const auto& u = p[k];
      const auto& v = p[(k + 1) % p.size()];
      a += u[0] * v[1] - v[0] * u[1];
    }
    return a;
  }

  /// line= or polygon=: the points, a line with some length, a polygon
  /// with some area.
  bool shape(const Field& f, std::string_view key, const std::string& who, TerrainEditSpec& e) {
    const bool flatten = e.kind == edit::Kind::flatten;
    if (!pointList(f, key, flatten ? 3 : 2, who, e.points)) return false;
    if (flatten && twiceArea(e.points) == 0) {
      fail(f.valueColumn, "polygon= encloses no area: its corners lie on one line; give three or more corners around "
                          "the ground to flatten");
      return false;
    }
    const auto& first = e.points.front();
    if (!flatten && std::all_of(e.points.begin(), e.points.end(), [&](const auto& p) { return p == first; })) {
      fail(f.valueColumn, "line= has no length: every point is the same; give the line's two ends");
      return false;
    }
    return true;
  }

  /// berm and ditch: line=, width=, height= or depth=; flatten: polygon=,
  /// height=; all three: slope=.
  bool earthwork(const std::map<std::string_view, Field>& f, std::size_t col, const std::string& who,
                 TerrainEditSpec& e) {
    const bool flatten = e.kind == edit::Kind::flatten, berm = e.kind == edit::Kind::berm;
    const std::string pair = e.lonLat ? "LON,LAT" : "EASTING,NORTHING";
    const std::string_view where = flatten ? "polygon" : "line";
    const std::string form = pair + ";" + pair + (flatten ? ";" + pair : std::string()) + "...";
    bool ok = required(f, where, col, who, form) && shape(f.at(where), where, who, e);
    std::optional<double> width, rise, slope;
    if (flatten) {
      ok = required(f, "height", col, who, "M (metres above the datum)") &&
           bounded(f, "height", -500, true, kMaxGroundM, "metres above the datum", rise) && ok;
    } else {
      const char* riseKey = berm ? "height" : "depth";
      const char* widthForm =
          berm ? "M (the crest's width, metres; 0 for a ridge)" : "M (the floor's width, metres; 0 for a V)";
      ok = required(f, "width", col, who, widthForm) &&
           bounded(f, "width", 0, true, kMaxEditWidthM, "metres", width) && ok;
      ok = required(f, riseKey, col, who, "M (metres)") &&
           bounded(f, riseKey, 0, false, kMaxEditDepthM, "metres", rise) && ok;
    }
    ok = bounded(f, "slope", 0, false, kMaxSlope, "(rise over run; 0.5 is 1 up in 2 across)", slope) && ok;
    if (!ok) return false;
    e.width = width.value_or(0);
    e.height = *rise;
    e.sideSlope = slope.value_or(kScenarioDefaultSlope);
    return true;
  }

  /// `crater`, `berm`, `ditch` or `flatten`: one terrain edit.
  void editLine(const std::vector<Token>& tok, const EditDirective& d) {
    const std::size_t col = tok[0].column;
    // Before anything of the line is read or stored.
    if (out_.terrainEdits.size() >= kMaxScenarioEdits) {
      return fail(col, "this line is terrain edit " + std::to_string(out_.terrainEdits.size() + 1) +
                           ", more than the " + std::to_string(kMaxScenarioEdits) +
                           " a scenario may hold (crater, berm, ditch and flatten lines together)");
    }
    std::map<std::string_view, Field> f;
    std::optional<std::size_t> noDriven;
    if (!fields(tok, 1, d.keys, d.keyList, Owner::edit, f, noDriven)) return;
    TerrainEditSpec e;
    e.kind = d.kind;
    e.lonLat = out_.frame == ScenarioFrame::lonLat;
    e.line = line_;
    const std::string who(d.word);
    bool ok = true;
    if (e.kind == edit::Kind::crater) {
      std::vector<double> v;
      ok = required(f, "at", col, who, e.lonLat ? "LON,LAT" : "EASTING,NORTHING") && position(f.at("at"), 2, v);
      if (ok) e.points = {{v[0], v[1]}};
      ok = craterSize(f, col, e) && ok;
    } else {
      ok = earthwork(f, col, who, e);
    }
    if (ok) out_.terrainEdits.push_back(std::move(e));
  }

  /// Counts `n` more entities against kMaxScenarioEntities; false (with
  /// the problem at `column`) when the scenario would hold more.
  bool claimEntities(std::uint64_t n, std::size_t column) {
    if (entityTotal_ + n > kMaxScenarioEntities) {
      fail(column, "this line brings the scenario to " + std::to_string(entityTotal_ + n) +
                       " entities, more than the " + std::to_string(kMaxScenarioEntities) +
                       " a scenario may hold (entity lines and group members together); lower the group counts");
      return false;
    }
    entityTotal_ += n;
    return true;
  }

  std::string name_;
  std::filesystem::path dir_;
  std::vector<Problem> problems_;
  Scenario out_;
  std::map<std::string, int> names_;  ///< entity and group names -> line
  std::size_t lineOffset_ = 0;
  int line_ = 0;
  int groupNumber_ = 0;
  std::uint64_t entityTotal_ = 0;
  bool header_ = false;
  bool frameSet_ = false;
};

}  // namespace

Result<Scenario> parseScenario(std::string_view text, const std::string& name) { return Reader(name).run(text); }

Result<Scenario> readScenarioFile(const std::string& path) {
  auto body = text::readText(path, 1u << 20, "the scenario file");
  if (!body) return body.problems();
  return parseScenario(body.value(), path);
}

EntitySpec groupMember(const GroupSpec& g, int k, std::uint64_t seed) {
  const std::uint64_t key = hash::mix(seed ^ hash::mix(nameKey(g.name)));
  auto draw = [&](std::uint64_t j) { return hash::unit(hash::mix(key + static_cast<std::uint64_t>(k) * 16 + j)); };
  auto between = [](double lo, double hi, double u) { return lo + u * (hi - lo); };
  EntitySpec e;
  e.name = g.name + "." + std::to_string(k);
  e.icon = g.icon;
  e.force = g.force;
  e.domain = g.domain;
  e.mobility = g.mobility;
  e.lonLat = g.lonLat;
  e.a = between(g.minA, g.maxA, draw(0));
  e.b = between(g.minB, g.maxB, draw(1));
  e.headingDeg = wrapDeg(between(g.headingMinDeg, g.headingMaxDeg, draw(2)));
  e.speedMs = between(g.speedMinMs, g.speedMaxMs, draw(3));
  if (g.altitudeMin && g.altitudeMax) e.altitude = between(*g.altitudeMin, *g.altitudeMax, draw(4));
  if (g.aglMin && g.aglMax) e.agl = between(*g.aglMin, *g.aglMax, draw(5));
  e.behaviour = g.behaviour;
  e.aircraft = g.aircraft;
  e.fuel = g.fuel;
  e.line = g.line;
  return e;
}

std::vector<EntitySpec> expandGroup(const GroupSpec& g, std::uint64_t seed) {
  std::vector<EntitySpec> out;
  out.reserve(static_cast<std::size_t>(std::max(g.count, 0)));
  for (int k = 1; k <= g.count; ++k) out.push_back(groupMember(g, k, seed));
  return out;
}

std::string_view scenarioWord(ScenarioDomain d) {
  switch (d) {
    case ScenarioDomain::land: return "land";
    case ScenarioDomain::sea: return "sea";
    case ScenarioDomain::air: return "air";
    case ScenarioDomain::munition: return "munition";
  }
  return "land";
}

std::string_view scenarioWord(ScenarioMobility m) {
  switch (m) {
    case ScenarioMobility::simple: return "simple";
    case ScenarioMobility::tracked: return "tracked";
    case ScenarioMobility::wheeled: return "wheeled";
    case ScenarioMobility::ship: return "ship";
    case ScenarioMobility::aircraft: return "aircraft";
  }
  return "simple";
}

std::string_view scenarioWord(ScenarioFrame f) { return f == ScenarioFrame::lonLat ? "lonlat" : "projected"; }

}  // namespace sandtable::sim
