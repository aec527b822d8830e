// The icon definition file: a line-oriented text in the spirit of seed
// Figure 19, with one directive per line and an `icon` line opening each
// block (grammar: docs/ICONS.md).
#include "sandtable/icons/definitions.h"

#include <charconv>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <string_view>

#include "sandtable/formats/bytes.h"
#include "sandtable/formats/dis_icons.h"

namespace sandtable::icons {
namespace {

namespace fs = std::filesystem;

struct Line {
  std::uint64_t offset = 0;
  std::vector<std::string_view> tokens;
};

/// A parse in progress: the file's name and the problems found so far.
struct Parser {
  std::string file;
  std::vector<Problem> problems;
  /// Every `dis` pattern so far (packed type, wildcard mask) and its icon:
  /// one pattern for two icons would leave the choice to file order.
  std::map<std::pair<std::uint64_t, std::uint8_t>, std::string> disOwners;
  void fail(const Line& l, const std::string& what) {
    problems.push_back({file, l.offset, "icon definitions: " + what});
  }
};

/// 's' in quotes. Built by append: GCC 12 reports a false -Wrestrict on
/// "'" + std::string once inlined.
std::string quoted(std::string_view s) {
  std::string q;
  q.reserve(s.size() + 2);
  q.append(1, '\'').append(s).append(1, '\'');
  return q;
}

bool isNameChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' ||
         c == '.';
}

bool validName(std::string_view s) {
  if (s.empty() || s.size() > iconpack::kMaxNameBytes) return false;
  for (char c : s) {
    if (!isNameChar(c)) return false;
  }
  return true;
}

/// Splits into lines of tokens; `#` at a token's start begins a comment.
std::vector<Line> tokenize(std::string_view text, Parser& p) {
  std::vector<Line> lines;
  std::size_t at = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string_view::npos) end = text.size();
    std::string_view s = text.substr(at, end - at);
    if (!s.empty() && s.back() == '\r') s.remove_suffix(1);
    Line l{at, {}};
    std::size_t i = 0;
    while (i < s.size()) {
      const auto c = static_cast<unsigned char>(s[i]);
      if (c == ' ' || c == '\t') {
        ++i;
        continue;
      }
      if (c == '#') break;
      std::size_t j = i;
      while (j < s.size() && s[j] != ' ' && s[j] != '\t') {
        const auto d = static_cast<unsigned char>(s[j]);
        if (d < 0x20 || d == 0x7F) {
          p.fail({at + j, {}}, "control character 0x" + crcHex(d).substr(8) + "; the file must be plain text");
          return {};
        }
        ++j;
      }
      l.tokens.push_back(s.substr(i, j - i));
      i = j;
    }
    if (!l.tokens.empty()) lines.push_back(std::move(l));
    at = end + 1;
  }
  return lines;
}

std::optional<float> number(std::string_view s) {
  double v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return float(v);
}

template <typename T>
std::optional<T> integer(std::string_view s) {
  T v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

/// "x,y,z" -> three finite numbers.
std::optional<std::array<float, 3>> triple(std::string_view s) {
  std::array<float, 3> v{};
  for (std::size_t k = 0; k < 3; ++k) {
    const std::size_t comma = s.find(',');
    const auto f = number(k < 2 ? s.substr(0, comma) : s);
    if (!f || (k < 2 && comma == std::string_view::npos)) return std::nullopt;
    v[k] = *f;
    if (k < 2) s.remove_prefix(comma + 1);
  }
  return v;
}

bool wantArgs(Parser& p, const Line& l, std::size_t lo, std::size_t hi, const char* usage) {
  const std::size_t n = l.tokens.size() - 1;
  if (n >= lo && n <= hi) return true;
  p.fail(l, quoted(l.tokens[0]) + " takes " + usage);
  return false;
}

void parseComponent(Parser& p, const Line& l, IconDef& icon) {
  if (!wantArgs(p, l, 3, 5, "NAME FILE offset=X,Y,Z [parent=NAME] [state=alive|dead]")) return;
  ComponentDef c;
  c.name = std::string(l.tokens[1]);
  c.model = std::string(l.tokens[2]);
  if (!validName(c.name)) return p.fail(l, "component name '" + c.name + "' must be 1-255 of A-Z a-z 0-9 _ - .");
  bool haveOffset = false;
  for (std::size_t k = 3; k < l.tokens.size(); ++k) {
    const std::string_view t = l.tokens[k];
    const std::size_t eq = t.find('=');
    const std::string_view key = t.substr(0, eq), value = eq == t.npos ? std::string_view() : t.substr(eq + 1);
    if (key == "offset" && triple(value)) {
      c.offset = *triple(value);
      haveOffset = true;
    } else if (key == "parent" && validName(value)) {
      c.parent = std::string(value);
    } else if (key == "state" && (value == "alive" || value == "dead")) {
      c.state = value == "dead" ? iconpack::State::dead : iconpack::State::alive;
    } else {
      return p.fail(l, "component field '" + std::string(t) +
                           "' is not offset=X,Y,Z, parent=NAME or state=alive|dead");
    }
  }
  if (!haveOffset) return p.fail(l, "component '" + c.name + "' needs offset=X,Y,Z (its frame's origin)");
  for (const auto& other : icon.components) {
    if (other.name == c.name && other.state == c.state) return p.fail(l, "component '" + c.name + "' twice");
  }
  if (!c.parent.empty()) {
    bool found = false;
    for (const auto& other : icon.components) found = found || (other.name == c.parent && other.state == c.state);
    if (!found) return p.fail(l, "parent '" + c.parent + "' is not an earlier component of the same state");
  }
  icon.components.push_back(std::move(c));
}

void parseCapabilities(Parser& p, const Line& l, IconDef& icon) {
  if (!wantArgs(p, l, 1, 2, "'none', or 'armed' and/or 'resupply'")) return;
  for (std::size_t k = 1; k < l.tokens.size(); ++k) {
    const std::string_view t = l.tokens[k];
    if (t == "armed") {
      icon.armed = true;
    } else if (t == "resupply") {
      icon.resupply = true;
    } else if (t != "none" || l.tokens.size() != 2) {
      return p.fail(l, "capability '" + std::string(t) + "' is not armed, resupply or none");
    }
  }
}

void parseNumbers(Parser& p, const Line& l, std::size_t n, std::span<float> out) {
  if (!wantArgs(p, l, n, n, n == 6 ? "MINX MINY MINZ MAXX MAXY MAXZ" : "RADIUS HEIGHT")) return;
  for (std::size_t k = 0; k < n; ++k) {
    const auto v = number(l.tokens[k + 1]);
    if (!v) return p.fail(l, quoted(l.tokens[k + 1]) + " is not a finite number");
    out[k] = *v;
  }
}

void parseBounds(Parser& p, const Line& l, IconDef& icon) {
  std::array<float, 6> b{};
  const std::size_t before = p.problems.size();
  parseNumbers(p, l, 6, b);
  if (p.problems.size() != before) return;
  if (b[0] > b[3] || b[1] > b[4] || b[2] > b[5]) return p.fail(l, "bounds: each minimum must not exceed its maximum");
  icon.bounds = b;
}

void parseCylinder(Parser& p, const Line& l, IconDef& icon) {
  std::array<float, 2> c{};
  const std::size_t before = p.problems.size();
  parseNumbers(p, l, 2, c);
  if (p.problems.size() != before) return;
  if (c[0] <= 0 || c[1] <= 0) return p.fail(l, "cylinder: radius and height must be positive metres");
  icon.cylinder = c;
}

void parseLevel(Parser& p, const Line& l, IconDef& icon) {
  if (!wantArgs(p, l, 1, 2, "RATIO [RANGE]")) return;
  const auto ratio = number(l.tokens[1]);
  const auto range = l.tokens.size() == 3 ? number(l.tokens[2]) : std::optional<float>(0.0f);
  if (!ratio || *ratio <= 0 || *ratio > 1) return p.fail(l, "lod ratio must be in (0, 1]");
  if (!range || *range < 0) return p.fail(l, "lod range must be metres >= 0 (0: from the screen-space error)");
  if (icon.levels.empty() && *ratio != 1) return p.fail(l, "the first lod must have ratio 1 (the model itself)");
  if (!icon.levels.empty() && *ratio >= icon.levels.back().ratio) {
    return p.fail(l, "lod ratios must decrease from one level to the next");
  }
  if (*range > 0 && !icon.levels.empty() && icon.levels.back().range >= *range) {
    return p.fail(l, "lod ranges must increase from one level to the next");
  }
  if (icon.levels.size() == iconpack::kMaxLevels) {
    return p.fail(l, "at most " + std::to_string(iconpack::kMaxLevels) + " levels of detail");
  }
  icon.levels.push_back({*ratio, *range});
}

void parseImportOption(Parser& p, const Line& l, IconDef& icon) {
  if (!wantArgs(p, l, 1, 1, "one value")) return;
  const std::string_view key = l.tokens[0], v = l.tokens[1];
  if (key == "up") {
    if (v == "auto") {
      icon.import.up = UpAxis::kFromFile;
    } else if (v == "y") {
      icon.import.up = UpAxis::kY;
    } else if (v == "z") {
      icon.import.up = UpAxis::kZ;
    } else {
      p.fail(l, "up must be auto, y or z");
    }
  } else if (key == "base-below") {
    const auto f = number(v);
    if (!f || *f < 0 || *f > 1000) return p.fail(l, "base-below must be metres from 0 to 1000");
    icon.baseBelow = static_cast<float>(*f);
  } else if (key == "max-triangles") {
    const auto n = integer<std::uint64_t>(v);
    if (!n || *n == 0) return p.fail(l, "max-triangles must be a positive integer");
    icon.import.maxTriangles = *n;
  } else {
    const auto f = number(v);
    if (!f || *f <= 0) return p.fail(l, std::string(key) + " must be a positive number");
    (key == "unit" ? icon.import.unitMetres : icon.import.scale) = *f;
  }
}

void parseModel(Parser& p, const Line& l, IconDef& icon) {
  if (!wantArgs(p, l, 1, 1, "FILE (a path without spaces, relative to this file)")) return;
  std::string& slot = l.tokens[0] == "model" ? icon.alive : icon.dead;
  if (!slot.empty()) return p.fail(l, quoted(l.tokens[0]) + " twice in icon '" + icon.name + "'");
  slot = std::string(l.tokens[1]);
}

void parseDis(Parser& p, const Line& l, IconDef& icon) {
  if (!wantArgs(p, l, 1, 1,
                "one pattern KIND.DOMAIN.COUNTRY.CATEGORY.SUBCATEGORY.SPECIFIC.EXTRA (each a number or *; "
                "trailing fields may be left off); give several types on several dis lines")) {
    return;
  }
  std::string why;
  const auto d = iconpack::parseDisPattern(l.tokens[1], why);
  if (!d) {
    return p.fail(l, "dis " + quoted(l.tokens[1]) + ": " + why +
                         " (write e.g. 1.1.225.1.1.3.0, 1.1.225.1 or 1.2.*.1: country 0-65535, the others 0-255)");
  }
  if (icon.dis.size() == iconpack::kMaxDisPatterns) {
    return p.fail(l, "at most " + std::to_string(iconpack::kMaxDisPatterns) + " dis lines per icon");
  }
  const auto [it, fresh] = p.disOwners.emplace(std::pair(iconpack::packedDisType(d->type), d->wild), icon.name);
  if (!fresh) {
    return p.fail(l, "dis " + iconpack::disText(*d) + " is already given for icon " + quoted(std::string_view(it->second)) +
                         "; a pattern names one icon");
  }
  icon.dis.push_back(*d);
}

using Directive = std::function<void(Parser&, const Line&, IconDef&)>;

const std::map<std::string_view, Directive>& directives() {
  static const std::map<std::string_view, Directive> d{
      {"model", parseModel},          {"dead", parseModel},
      {"component", parseComponent},  {"capabilities", parseCapabilities},
      {"bounds", parseBounds},        {"cylinder", parseCylinder},
      {"lod", parseLevel},            {"dis", parseDis},
      {"up", parseImportOption},      {"unit", parseImportOption},
      {"scale", parseImportOption},   {"max-triangles", parseImportOption},
      {"base-below", parseImportOption},
  };
  return d;
}

void openIcon(Parser& p, const Line& l, Definitions& out, std::set<std::string>& names) {
  if (!wantArgs(p, l, 1, 1, "NAME")) return;
  const std::string name(l.tokens[1]);
  if (!validName(name)) return p.fail(l, "icon name '" + name + "' must be 1-255 of A-Z a-z 0-9 _ - .");
  if (!names.insert(name).second) return p.fail(l, "icon '" + name + "' is defined twice");
  IconDef icon;
  icon.name = name;
  icon.line = l.offset;
  out.icons.push_back(std::move(icon));
}

void parseLines(Parser& p, const std::vector<Line>& lines, Definitions& out) {
  std::set<std::string> names;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const Line& l = lines[i];
    if (l.tokens[0] == "icon") {
      openIcon(p, l, out, names);
      continue;
    }
    const auto it = directives().find(l.tokens[0]);
    if (it == directives().end()) {
      p.fail(l, "unknown directive '" + std::string(l.tokens[0]) + "' (docs/ICONS.md lists them)");
    } else if (out.icons.empty()) {
      p.fail(l, quoted(l.tokens[0]) + " before the first 'icon NAME' line");
    } else {
      it->second(p, l, out.icons.back());
    }
  }
}

}  // namespace

Result<Definitions> parseDefinitions(std::span<const std::byte> text, const std::string& file,
                                     const std::string& baseDir) {
  Parser p{file, {}, {}};
  const std::string_view s(reinterpret_cast<const char*>(text.data()), text.size());
  const std::vector<Line> lines = tokenize(s, p);
  if (!p.problems.empty()) return p.problems;
  if (lines.empty() || lines[0].tokens.size() != 2 || lines[0].tokens[0] != "sandtable-icons" ||
      lines[0].tokens[1] != "1") {
    return Problem{file, lines.empty() ? 0 : lines[0].offset,
                   std::string("icon definitions: the first line must be '") + kDefinitionsHeader + "'"};
  }
  Definitions out;
  out.file = file;
  out.baseDir = baseDir;
  parseLines(p, lines, out);
  for (const auto& icon : out.icons) {
    if (icon.alive.empty()) {
      p.problems.push_back({file, icon.line, "icon definitions: icon '" + icon.name + "' has no 'model FILE' line"});
    }
  }
  if (!p.problems.empty()) return p.problems;
  return out;
}

Result<Definitions> readDefinitions(const std::string& path) {
  auto bytes = readSmallFile(path, kMaxDefinitionBytes);
  if (!bytes) return bytes.problems();
  const fs::path dir = fs::path(path).parent_path();
  return parseDefinitions(bytes.value(), path, dir.empty() ? std::string(".") : dir.string());
}

}  // namespace sandtable::icons
