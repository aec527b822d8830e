// The material table's text format (docs/FORMAT.md §11): a line
// parser that reports every problem with the file and the byte offset of
// its line, the canonical writer, and the rule matcher.
#include "sandtable/formats/materials.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cmath>
#include <string_view>

#include "sandtable/formats/bytes.h"

namespace sandtable::materials {
namespace {

constexpr std::uint64_t kMaxId = 0xFFFE;  // kNoClass is reserved
constexpr double kMaxWidth = 1000.0;

bool isSpace(char c) { return c == ' ' || c == '\t'; }

char lower(char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c; }

bool equalsNoCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (lower(a[k]) != lower(b[k])) return false;
  }
  return true;
}

/// Whitespace-separated tokens up to a token that starts with '#'.
std::vector<std::string_view> tokenize(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t k = 0;
  while (k < line.size()) {
    while (k < line.size() && isSpace(line[k])) ++k;
    if (k == line.size() || line[k] == '#') break;
    const std::size_t start = k;
    while (k < line.size() && !isSpace(line[k])) ++k;
    out.push_back(line.substr(start, k - start));
  }
  return out;
}

bool parseUnsigned(std::string_view s, std::uint64_t max, std::uint64_t& out) {
  if (s.empty() || s.size() > 10) return false;
  std::uint64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  if (v > max) return false;
  out = v;
  return true;
}

bool parseRgb(std::string_view s, std::uint32_t& out) {
  if (s.size() != 6) return false;
  std::uint32_t v = 0;
  for (char c : s) {
    int d = -1;
    if (c >= '0' && c <= '9') d = c - '0';
    else if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    if (d < 0) return false;
    v = v * 16 + static_cast<std::uint32_t>(d);
  }
  out = v;
  return true;
}

bool parseWidth(std::string_view s, double& out) {
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v) || !(v > 0) || v > kMaxWidth) {
    return false;
  }
  out = v;
  return true;
}

/// A finite number, the whole token.
bool parseReal(std::string_view s, double& out) {
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v)) return false;
  out = v;
  return true;
}

bool validName(std::string_view s) {
  if (s.empty() || s == kIgnoreClass || s == "none") return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-' || c == '.';
  });
}

std::string quoted(std::string_view s) {
  std::string q;
  q.reserve(s.size() + 2);
  q.push_back('"');
  q.append(s);
  q.push_back('"');
  return q;
}

std::string hex6(std::uint32_t v) {
  static const char* digits = "0123456789ABCDEF";
  std::string s(6, '0');
  for (int k = 5; k >= 0; --k, v >>= 4) s[static_cast<std::size_t>(k)] = digits[v & 15];
  return s;
}

std::string number(double v) {
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return ec == std::errc() ? std::string(buf, end) : std::to_string(v);
}

/// A directive whose class name is resolved once every class is known.
struct Pending {
  std::uint64_t offset = 0;
  std::size_t line = 0;
  std::string name;
};

class Parser {
 public:
  Parser(std::string_view text, std::string file) : text_(text), file_(std::move(file)) {}

  Result<Table> run() {
    std::size_t lineNo = 0;
    bool header = false;
    std::size_t pos = 0;
    while (pos < text_.size()) {
      std::size_t end = text_.find('\n', pos);
      if (end == std::string_view::npos) end = text_.size();
      std::string_view line = text_.substr(pos, end - pos);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      offset_ = pos;
      line_ = ++lineNo;
      pos = end + 1;
      if (!plainText(line)) continue;
      const auto tok = tokenize(line);
      if (tok.empty()) continue;
      if (!header) {
        if (!headerLine(tok)) return problems_;
        header = true;
        continue;
      }
      directive(tok);
    }
    offset_ = text_.size();
    line_ = lineNo + 1;
    if (!header) {
      fail("the table is empty; its first line that is not a comment must be \"" + std::string(kHeaderLine) + "\"",
           false);
      return problems_;
    }
    finish();
    if (!problems_.empty()) return problems_;
    return table_;
  }

 private:
  void fail(const std::string& what, bool withLine = true) {
    problems_.push_back(
        {file_, offset_, "materials: " + (withLine ? "line " + std::to_string(line_) + ": " : std::string()) + what});
  }

  bool plainText(std::string_view line) {
    for (std::size_t k = 0; k < line.size(); ++k) {
      const auto c = static_cast<unsigned char>(line[k]);
      if ((c < 0x20 && c != '\t') || c == 0x7F) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "0x%02X", c);
        fail("control character " + std::string(buf) + " at column " + std::to_string(k + 1) +
             "; the table is plain text");
        return false;
      }
    }
    return true;
  }

  bool headerLine(const std::vector<std::string_view>& tok) {
    if (tok[0] == "sandtable-materials" && tok.size() == 2) {
      std::uint64_t v = 0;
      if (parseUnsigned(tok[1], 1000000, v) && v == 1) return true;
      if (parseUnsigned(tok[1], 1000000, v) && v > 1) {
        fail("version " + std::to_string(v) + " is newer than this reader knows (1); use a newer sandtable");
        return false;
      }
    }
    fail("missing header; the first line that is not a comment must be \"" + std::string(kHeaderLine) + "\"");
    return false;
  }

  void directive(const std::vector<std::string_view>& tok) {
    if (tok[0] == "class") return classLine(tok);
    if (tok[0] == "rule") return ruleLine(tok);
    if (tok[0] == "default-area" || tok[0] == "default-line") return defaultLine(tok);
    if (tok[0] == "scatter") return scatterLine(tok);
    if (tok[0] == "place") return placeLine(tok);
    if (tok[0] == "sandtable-materials") {
      return fail("the header \"" + std::string(kHeaderLine) + "\" may appear only once");
    }
    fail("unknown directive " + quoted(tok[0]) + " (known: class, rule, default-area, default-line, scatter, place)");
  }

  void classLine(const std::vector<std::string_view>& tok) {
    if (tok.size() < 3) {
      return fail("class needs an id and a name: class ID NAME kind=area|line priority=P [rank=R] "
                  "upper=RRGGBB lower=RRGGBB material=M texture=T [width=W]");
    }
    Class c;
    std::uint64_t v = 0;
    if (!parseUnsigned(tok[1], kMaxId, v)) {
      return fail("class id " + quoted(tok[1]) + " is not a whole number 0..65534");
    }
    c.id = static_cast<std::uint16_t>(v);
    if (!validName(tok[2])) {
      return fail("class name " + quoted(tok[2]) +
                  " may hold only letters, digits, '_', '-' and '.' (and may not be \"-\" or \"none\")");
    }
    c.name = std::string(tok[2]);
    for (std::size_t k = 0; k < table_.classes.size(); ++k) {
      if (table_.classes[k].id == c.id) {
        return fail("class id " + std::to_string(c.id) + " is already used by " + quoted(table_.classes[k].name) +
                    " (line " + std::to_string(classLines_[k]) + "); give every class its own id");
      }
      if (table_.classes[k].name == c.name) {
        return fail("class name " + quoted(c.name) + " is already used (line " + std::to_string(classLines_[k]) +
                    "); give every class its own name");
      }
    }
    enum Field { kind, priority, rank, upper, lower, material, texture, width, extrude, storey, stick, resist, water,
                 count };
    static const char* names[count] = {"kind",  "priority", "rank",   "upper", "lower",  "material", "texture",
                                       "width", "extrude",  "storey", "stick", "resist", "water"};
    std::string_view given[count];
    bool seen[count] = {};
    for (std::size_t k = 3; k < tok.size(); ++k) {
      const std::size_t eq = tok[k].find('=');
      if (eq == std::string_view::npos || eq == 0) {
        return fail(quoted(tok[k]) + " is not KEY=VALUE");
      }
      const std::string_view key = tok[k].substr(0, eq);
      int f = -1;
      for (int n = 0; n < count; ++n) {
        if (key == names[n]) f = n;
      }
      if (f < 0) {
        return fail("unknown class field " + quoted(key) +
                     " (known: kind, priority, rank, upper, lower, material, texture, width, extrude, storey, stick, resist, "
                    "water)");
      }
      if (seen[f]) return fail("class field " + quoted(key) + " is given twice");
      seen[f] = true;
      given[f] = tok[k].substr(eq + 1);
    }
    for (int f : {kind, priority, upper, lower, material, texture}) {
      if (!seen[f]) return fail("class " + quoted(c.name) + " is missing " + names[f] + "=");
    }
    if (given[kind] == "area") c.kind = Kind::area;
    else if (given[kind] == "line") c.kind = Kind::line;
    else return fail("kind must be area or line, not " + quoted(given[kind]));
    if (!parseUnsigned(given[priority], 99, v) || v < 1) {
      return fail("priority must be 1..99 (1 skin, 2-10 decals, roads 10, 99 objects), not " +
                  quoted(given[priority]));
    }
    c.priority = static_cast<std::uint8_t>(v);
    if (c.kind == Kind::area && c.priority != 1) {
      return fail("area class " + quoted(c.name) + " must have priority=1: area classes are the skin; "
                  "decals are line classes");
    }
    if (c.kind == Kind::line && (c.priority < 2 || c.priority > 98)) {
      return fail("line class " + quoted(c.name) + " is a decal: its priority must be 2..98, not " +
                  std::to_string(c.priority));
    }
    if (seen[rank]) {
      if (c.kind != Kind::area) return fail("rank= applies only to area classes");
      if (!parseUnsigned(given[rank], 65535, v)) return fail("rank must be 0..65535, not " + quoted(given[rank]));
      c.rank = static_cast<std::uint16_t>(v);
    }
    if (!parseRgb(given[upper], c.upperRgb)) {
      return fail("upper must be a colour of 6 hex digits RRGGBB, not " + quoted(given[upper]));
    }
    if (!parseRgb(given[lower], c.lowerRgb)) {
      return fail("lower must be a colour of 6 hex digits RRGGBB, not " + quoted(given[lower]));
    }
    if (!parseUnsigned(given[material], 65535, v)) {
      return fail("material must be 0..65535, not " + quoted(given[material]));
    }
    c.material = static_cast<std::uint16_t>(v);
    if (!parseUnsigned(given[texture], 65535, v)) {
      return fail("texture must be 0..65535, not " + quoted(given[texture]));
    }
    c.texture = static_cast<std::uint16_t>(v);
    if (c.kind == Kind::line) {
      if (!seen[width]) return fail("line class " + quoted(c.name) + " needs width=W (metres)");
      if (!parseWidth(given[width], c.width)) {
        return fail("width must be metres in (0, 1000], not " + quoted(given[width]));
      }
    } else if (seen[width]) {
      return fail("width= applies only to line classes");
    }
    if ((seen[extrude] || seen[storey]) && c.kind != Kind::area) {
      return fail("extrude= and storey= apply only to area classes (building footprints)");
    }
    if (seen[extrude] && !parseWidth(given[extrude], c.extrude)) {
      return fail("extrude must be a default building height in metres in (0, 1000], not " +
                  quoted(given[extrude]));
    }
    if (seen[storey] && !parseWidth(given[storey], c.storey)) {
      return fail("storey must be metres per building level in (0, 1000], not " + quoted(given[storey]));
    }
    if (seen[stick] && (!parseReal(given[stick], c.stickDeg) || c.stickDeg < 0 || c.stickDeg > 90)) {
      return fail("stick must be the slope in degrees, 0..90, at which a vehicle at rest starts to slide, not " +
                  quoted(given[stick]));
    }
    if (seen[resist] && (!parseReal(given[resist], c.resist) || c.resist < 0 || c.resist > 10)) {
      return fail("resist must be the resistive force as a fraction of the vehicle's weight, 0..10, not " +
                  quoted(given[resist]));
    }
    if (seen[water]) {
      if (given[water] == "yes") c.water = true;
      else if (given[water] == "no") c.water = false;
      else return fail("water must be yes or no, not " + quoted(given[water]));
    }
    table_.classes.push_back(std::move(c));
    classLines_.push_back(line_);
  }

  /// tok[1] split at its first '=' into a non-empty key and value (rule
  /// and place lines); false (a problem reported) when it is not KEY=VALUE.
  bool keyValue(const std::vector<std::string_view>& tok, std::string& key, std::string& value) {
    const std::size_t eq = tok[1].find('=');
    if (eq == std::string_view::npos || eq == 0 || eq + 1 == tok[1].size()) {
      fail(quoted(tok[1]) + " is not KEY=VALUE (VALUE * matches any non-empty value)");
      return false;
    }
    key = std::string(tok[1].substr(0, eq));
    value = std::string(tok[1].substr(eq + 1));
    return true;
  }

  void ruleLine(const std::vector<std::string_view>& tok) {
    if (tok.size() < 3 || tok.size() > 4) {
      return fail("rule needs KEY=VALUE and a class name: rule KEY=VALUE CLASS [width-field=FIELD]");
    }
    Rule r;
    if (!keyValue(tok, r.key, r.value)) return;
    r.className = std::string(tok[2]);
    if (tok.size() == 4) {
      constexpr std::string_view opt = "width-field=";
      if (tok[3].substr(0, opt.size()) != opt || tok[3].size() == opt.size()) {
        return fail("unknown rule option " + quoted(tok[3]) + " (known: width-field=FIELD)");
      }
      r.widthField = std::string(tok[3].substr(opt.size()));
    }
    table_.rules.push_back(std::move(r));
    ruleRefs_.push_back({offset_, line_, table_.rules.back().className});
  }

  /// icon=, density=, scale=, seed= of a scatter or place line, from tok[from].
  bool objectOptions(const std::vector<std::string_view>& tok, std::size_t from, bool scatter, std::string& icon,
                     double* density, Variation& var, std::uint64_t* seed) {
    for (std::size_t k = from; k < tok.size(); ++k) {
      const std::size_t eq = tok[k].find('=');
      const std::string_view key = eq == std::string_view::npos ? tok[k] : tok[k].substr(0, eq);
      const std::string_view val = eq == std::string_view::npos ? std::string_view() : tok[k].substr(eq + 1);
      if (key == "icon" && !val.empty()) {
        icon = std::string(val);
      } else if (key == "density" && scatter) {
        if (!parseWidth(val, *density) || *density > 10000) {
          fail("density must be objects per hectare in (0, 10000], not " + quoted(val));
          return false;
        }
      } else if (key == "scale") {
        const std::size_t dots = val.find("..");
        const std::string_view lo = val.substr(0, dots), hi = dots == std::string_view::npos ? lo : val.substr(dots + 2);
        if (!parseWidth(lo, var.scaleMin) || !parseWidth(hi, var.scaleMax) || var.scaleMax < var.scaleMin ||
            var.scaleMax > 100) {
          fail("scale must be S or A..B with 0 < A <= B <= 100, not " + quoted(val));
          return false;
        }
      } else if (key == "seed" && scatter) {
        if (!parseUnsigned(val, ~std::uint64_t(0) >> 1, *seed)) {
          fail("seed must be a whole number, not " + quoted(val));
          return false;
        }
      } else {
        fail("unknown " + std::string(scatter ? "scatter" : "place") + " option " + quoted(tok[k]) + " (known: icon=NAME" +
             (scatter ? ", density=N, scale=A..B, seed=S)" : ", scale=A..B)"));
        return false;
      }
    }
    if (icon.empty()) {
      fail(std::string(scatter ? "scatter" : "place") + " needs icon=NAME, an icon of the --icons definition file");
      return false;
    }
    if (scatter && !(*density > 0)) {
      fail("scatter needs density=N, objects per hectare");
      return false;
    }
    return true;
  }

  void scatterLine(const std::vector<std::string_view>& tok) {
    if (tok.size() < 3) return fail("scatter needs a class and options: scatter CLASS icon=NAME density=N [scale=A..B] [seed=S]");
    Scatter sc;
    sc.className = std::string(tok[1]);
    if (!objectOptions(tok, 2, true, sc.icon, &sc.perHectare, sc.variation, &sc.seed)) return;
    table_.scatters.push_back(std::move(sc));
    scatterRefs_.push_back({offset_, line_, table_.scatters.back().className});
  }

  void placeLine(const std::vector<std::string_view>& tok) {
    if (tok.size() < 3) return fail("place needs KEY=VALUE and options: place KEY=VALUE icon=NAME [scale=A..B]");
    Place pl;
    if (!keyValue(tok, pl.key, pl.value)) return;
    if (!objectOptions(tok, 2, false, pl.icon, nullptr, pl.variation, nullptr)) return;
    table_.places.push_back(std::move(pl));
  }

  void defaultLine(const std::vector<std::string_view>& tok) {
    const bool area = tok[0] == "default-area";
    if (tok.size() != 2) {
      return fail(std::string(tok[0]) + " needs exactly one class name" + (area ? "" : " (or none)"));
    }
    Pending& p = area ? defaultArea_ : defaultLine_;
    if (p.line != 0) {
      return fail(std::string(tok[0]) + " is given twice (first on line " + std::to_string(p.line) + ")");
    }
    p = {offset_, line_, std::string(tok[1])};
  }

  /// Resolves class names now that every class line has been read.
  void finish() {
    const std::uint64_t endOffset = offset_;
    const std::size_t endLine = line_;
    for (std::size_t k = 0; k < ruleRefs_.size(); ++k) {
      offset_ = ruleRefs_[k].offset;
      line_ = ruleRefs_[k].line;
      const Rule& r = table_.rules[k];
      if (r.className == kIgnoreClass) {
        if (!r.widthField.empty()) fail("width-field= makes no sense on an ignore rule (class \"-\")");
        continue;
      }
      const Class* c = table_.findByName(r.className);
      if (!c) {
        fail("rule names class " + quoted(r.className) + ", which no class line defines");
      } else if (!r.widthField.empty() && c->kind != Kind::line) {
        fail("width-field= applies only to line classes; " + quoted(c->name) + " is an area class");
      }
    }
    for (const Pending& r : scatterRefs_) {
      offset_ = r.offset;
      line_ = r.line;
      const Class* c = table_.findByName(r.name);
      if (!c) fail("scatter names class " + quoted(r.name) + ", which no class line defines");
      else if (c->kind != Kind::area) fail("scatter needs an area class; " + quoted(c->name) + " is a line class");
    }
    if (defaultArea_.line == 0) {
      offset_ = endOffset;
      line_ = endLine;
      fail("default-area is missing; add \"default-area NAME\" naming an area class", false);
    } else {
      offset_ = defaultArea_.offset;
      line_ = defaultArea_.line;
      const Class* c = table_.findByName(defaultArea_.name);
      if (!c) fail("default-area names class " + quoted(defaultArea_.name) + ", which no class line defines");
      else if (c->kind != Kind::area) fail("default-area must name an area class; " + quoted(c->name) + " is a line class");
      else table_.defaultArea = c->id;
    }
    if (defaultLine_.line == 0) {
      offset_ = endOffset;
      line_ = endLine;
      fail("default-line is missing; add \"default-line NAME\" naming a line class, or \"default-line none\"",
           false);
    } else {
      offset_ = defaultLine_.offset;
      line_ = defaultLine_.line;
      if (defaultLine_.name == "none") {
        table_.defaultLine = kNoClass;
      } else {
        const Class* c = table_.findByName(defaultLine_.name);
        if (!c) fail("default-line names class " + quoted(defaultLine_.name) + ", which no class line defines");
        else if (c->kind != Kind::line) fail("default-line must name a line class (or none); " + quoted(c->name) + " is an area class");
        else table_.defaultLine = c->id;
      }
    }
  }

  std::string_view text_;
  std::string file_;
  std::uint64_t offset_ = 0;
  std::size_t line_ = 0;
  Table table_;
  std::vector<std::size_t> classLines_;
  std::vector<Pending> ruleRefs_, scatterRefs_;
  Pending defaultArea_, defaultLine_;
  std::vector<Problem> problems_;
};

}  // namespace

const Class* Table::find(std::uint16_t id) const {
  for (const Class& c : classes) {
    if (c.id == id) return &c;
  }
  return nullptr;
}

const Class* Table::findByName(const std::string& name) const {
  for (const Class& c : classes) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

Result<Table> parse(std::span<const std::byte> text, const std::string& file) {
  return Parser(std::string_view(reinterpret_cast<const char*>(text.data()), text.size()), file).run();
}

Result<Table> readFile(const std::string& path) {
  auto bytes = readSmallFile(path, kMaxFileBytes);
  if (!bytes) return Problem{path, 0, "materials: " + bytes.message()};
  return parse(bytes.value(), path);
}

std::string format(const Table& t) {
  std::string s = "# sandtable material table (docs/FORMAT.md §11)\n";
  s += kHeaderLine;
  s += "\n";
  for (const Class& c : t.classes) {
    s += "class " + std::to_string(c.id) + " " + c.name + " kind=" + (c.kind == Kind::area ? "area" : "line") +
         " priority=" + std::to_string(c.priority);
    if (c.kind == Kind::area) s += " rank=" + std::to_string(c.rank);
    s += " upper=" + hex6(c.upperRgb) + " lower=" + hex6(c.lowerRgb) + " material=" + std::to_string(c.material) +
         " texture=" + std::to_string(c.texture);
    if (c.kind == Kind::line) s += " width=" + number(c.width);
    if (c.extrude > 0) s += " extrude=" + number(c.extrude);
    if (c.storey != kDefaultStorey) s += " storey=" + number(c.storey);
    if (c.stickDeg != kDefaultStickDeg) s += " stick=" + number(c.stickDeg);
    if (c.resist != kDefaultResist) s += " resist=" + number(c.resist);
    if (c.water) s += " water=yes";
    s += "\n";
  }
  for (const Rule& r : t.rules) {
    s += "rule " + r.key + "=" + r.value + " " + r.className;
    if (!r.widthField.empty()) s += " width-field=" + r.widthField;
    s += "\n";
  }
  auto nameOf = [&](std::uint16_t id) {
    const Class* c = t.find(id);
    return c ? c->name : std::to_string(id);
  };
  auto variation = [](const Variation& v) {
    if (v.scaleMin == 1 && v.scaleMax == 1) return std::string();
    return " scale=" + number(v.scaleMin) + (v.scaleMax == v.scaleMin ? "" : ".." + number(v.scaleMax));
  };
  for (const Scatter& sc : t.scatters) {
    s += "scatter " + sc.className + " icon=" + sc.icon + " density=" + number(sc.perHectare) + variation(sc.variation) +
         (sc.seed == 1 ? "" : " seed=" + std::to_string(sc.seed)) + "\n";
  }
  for (const Place& pl : t.places) s += "place " + pl.key + "=" + pl.value + " icon=" + pl.icon + variation(pl.variation) + "\n";
  s += "default-area " + nameOf(t.defaultArea) + "\n";
  s += "default-line " + (t.defaultLine == kNoClass ? std::string("none") : nameOf(t.defaultLine)) + "\n";
  return s;
}

const Place* placeFor(const Table& t, const std::string& layer, const void* feature, AttributeFn attr) {
  for (const Place& pl : t.places) {
    const auto v = pl.key == "layer" ? std::optional<std::string>(layer) : (attr ? attr(feature, pl.key) : std::nullopt);
    if (!v || v->empty()) continue;
    if (pl.value == "*" || equalsNoCase(*v, pl.value)) return &pl;
  }
  return nullptr;
}

Match classify(const Table& t, const std::string& layer, const void* feature, AttributeFn attr, bool isLine) {
  // Attributes looked up once per key: rules often share a key.
  std::vector<std::pair<const std::string*, std::optional<std::string>>> seen;
  auto value = [&](const std::string& key) -> const std::optional<std::string>& {
    for (const auto& [k, v] : seen) {
      if (*k == key) return v;
    }
    seen.emplace_back(&key, key == "layer" ? std::optional<std::string>(layer)
                                           : (attr ? attr(feature, key) : std::nullopt));
    return seen.back().second;
  };
  for (const Rule& r : t.rules) {
    const bool ignore = r.className == kIgnoreClass;
    const Class* c = ignore ? nullptr : t.findByName(r.className);
    if (!ignore && (!c || (c->kind == Kind::line) != isLine)) continue;
    const std::optional<std::string>& v = value(r.key);
    if (!v || v->empty()) continue;
    if (r.value != "*" && !equalsNoCase(*v, r.value)) continue;
    if (ignore) return {kNoClass, 0, true};
    Match m{c->id, c->width, true};
    if (!r.widthField.empty()) {
      if (const auto w = attr ? attr(feature, r.widthField) : std::nullopt) {
        // Leading number of the value: "7", "7.5", "7 m".
        std::string_view s(*w);
        while (!s.empty() && isSpace(s.front())) s.remove_prefix(1);
        double width = 0;
        const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), width);
        (void)end;
        if (ec == std::errc() && std::isfinite(width) && width > 0 && width <= kMaxWidth) m.width = width;
      }
    }
    return m;
  }
  const std::uint16_t id = isLine ? t.defaultLine : t.defaultArea;
  const Class* c = id == kNoClass ? nullptr : t.find(id);
  return {id, c ? c->width : 0.0, false};
}

}  // namespace sandtable::materials
