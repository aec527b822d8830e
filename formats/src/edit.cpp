#include "sandtable/formats/edit.h"

#include <cmath>
#include <sstream>

namespace sandtable::edit {

std::string_view kindName(Kind k) {
  switch (k) {
    case Kind::crater: return "crater";
    case Kind::berm: return "berm";
    case Kind::ditch: return "ditch";
    case Kind::flatten: return "flatten";
    case Kind::addObject: return "add-object";
    case Kind::removeObject: return "remove-object";
    case Kind::switchObject: return "switch-object";
    case Kind::scaleObject: return "scale-object";
  }
  return "unknown";
}

namespace {

std::string bad(Kind k, const char* field, const char* rule, double got) {
  std::ostringstream s;
  s << "edit: " << kindName(k) << ": Edit::" << field << " must be " << rule << " (got " << got << ")";
  return s.str();
}

std::string needPoints(Kind k, std::size_t least, std::size_t got) {
  std::ostringstream s;
  s << "edit: " << kindName(k) << ": Edit::points needs at least " << least << " (got " << got << ")";
  return s.str();
}

}  // namespace

std::string checkEdit(const Edit& e) {
  if (std::uint8_t(e.kind) < 1 || std::uint8_t(e.kind) > kMaxKind) return "edit: kind " + std::to_string(int(e.kind)) + " is unknown";
  if (!std::isfinite(e.time)) return bad(e.kind, "time", "finite", e.time);
  for (const auto& p : e.points) {
    if (!std::isfinite(p[0]) || !std::isfinite(p[1])) return "edit: " + std::string(kindName(e.kind)) + ": Edit::points must be finite";
  }
  const auto positive = [&](const char* field, double v) { return v > 0 && std::isfinite(v) ? std::string() : bad(e.kind, field, "> 0", v); };
  switch (e.kind) {
    case Kind::crater:
      if (e.points.size() != 1) return needPoints(e.kind, 1, e.points.size());
      if (auto m = positive("radius", e.radius); !m.empty()) return m;
      return positive("depth", e.depth);
    case Kind::berm:
    case Kind::ditch:
      if (e.points.size() < 2) return needPoints(e.kind, 2, e.points.size());
      if (!(e.width >= 0) || !std::isfinite(e.width)) return bad(e.kind, "width", ">= 0", e.width);
      if (auto m = positive("height", e.height); !m.empty()) return m;
      return positive("sideSlope", e.sideSlope);
    case Kind::flatten:
      if (e.points.size() < 3) return needPoints(e.kind, 3, e.points.size());
      if (!std::isfinite(e.height)) return bad(e.kind, "height", "finite", e.height);
      return positive("sideSlope", e.sideSlope);
    case Kind::addObject:
      if (e.points.size() != 1) return needPoints(e.kind, 1, e.points.size());
      if (!std::isfinite(e.heading)) return bad(e.kind, "heading", "finite", e.heading);
      return positive("scale", e.scale);
    case Kind::scaleObject: return positive("scale", e.scale);
    case Kind::removeObject:
    case Kind::switchObject: return {};
  }
  return {};
}

}  // namespace sandtable::edit
