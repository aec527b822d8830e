// Culture::load: OGR sources read, classified by the material table,
// transformed into the database frame, repaired or dropped (counted),
// clipped to the database, line features widened (once, here), and a
// spatial index built (docs/CULTURE.md, "Loading").
#include <gdal.h>
#include <ogr_api.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <cpl_error.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <map>
#include <numbers>
#include <optional>
#include <unordered_map>

#include "culture_internal.h"
#include "sandtable/base/jobs.h"
#include "sandtable/converters/clip.h"
#include "sandtable/converters/crs.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/converters/elevation.h"  // cancelRequested

namespace sandtable::convert {

using namespace culture;

namespace {

constexpr std::size_t kMaxMessages = 20;

/// Every reason load drops, repairs, defaults or ignores a feature for
/// (CultureStats::reasons; docs/CULTURE.md, "What load reports").
struct Reason {
  const char* key;
  const char* action;
  const char* text;
  bool warning;
};
constexpr Reason kReasons[] = {
    {"unmatched_line", "dropped", "line whose attributes match no rule, and the table's default-line is none", true},
    {"no_rule_default", "defaulted", "matched no rule; took the table's default class", true},
    {"ignore_rule", "ignored", "matched an ignore rule (\"-\") of the material table", false},
    {"unknown_class", "dropped", "classified to a class the material table does not define", true},
    {"no_transform", "dropped", "cannot be transformed into the database CRS", true},
    {"not_finite", "dropped", "invalid geometry: coordinates that are not finite", true},
    {"zero_length", "dropped", "invalid geometry: line of zero length", true},
    {"no_area", "dropped", "invalid geometry: polygon of no area", true},
    {"invalid_polygon_repaired", "repaired", "invalid polygon (self-intersection), made valid", true},
    {"invalid_polygon_dropped", "dropped", "invalid polygon that cannot be made valid", true},
    {"self_intersecting_line", "repaired",
     "line that crosses or touches itself (a figure 8); widened as one outline, the crossing drawn once", true},
    {"repeated_points", "repaired", "repeated points, removed", true},
    {"unclosed_ring", "repaired", "polygon ring not closed, closed", true},
    {"simplified", "repaired", "line simplified beyond the base tolerance to bound the work", true},
    {"widen_failed", "dropped", "line whose widening failed (CGAL)", true},
    {"outside", "dropped", "wholly outside the database", false},
};

/// Counts one feature under `key` (one of kReasons); the first gives the sample.
void tally(CultureStats& st, const char* key, const std::string& id) {
  for (const Reason& r : kReasons) {
    if (std::strcmp(r.key, key) != 0) continue;
    ReasonStats& rs = st.reasons[key];
    if (rs.count++ == 0) rs = {1, r.action, r.text, id, r.warning};
    return;
  }
}

/// Whether any part crosses or touches itself (GEOS IsSimple; a closed part
/// that meets itself only at its ends is simple).
bool crossesItself(const std::vector<Polyline>& parts) {
  for (const Polyline& p : parts) {
    if (p.size() < 3) continue;
    OGRLineString ls;
    ls.setNumPoints(static_cast<int>(p.size()), FALSE);
    for (std::size_t k = 0; k < p.size(); ++k) ls.setPoint(static_cast<int>(k), p[k].x, p[k].z);
    if (!ls.IsSimple()) return true;
  }
  return false;
}
/// Size rule: vertices within about a width of each vertex, on average
/// (crowding); 3 x width / spacing for a line that runs on, so this allows
/// vertex spacings down to about width / 80.
constexpr std::uint64_t kMaxCrowding = 256;

bool endsWithNoCase(const std::string& s, const char* suffix) {
  const std::size_t n = std::strlen(suffix);
  if (s.size() < n) return false;
  for (std::size_t k = 0; k < n; ++k) {
    char a = s[s.size() - n + k], b = suffix[k];
    if (a >= 'A' && a <= 'Z') a = static_cast<char>(a - 'A' + 'a');
    if (a != b) return false;
  }
  return true;
}

/// GDAL path for a source: .gz through /vsigzip/, .zip through /vsizip/.
std::string gdalPath(const std::string& p) {
  if (p.rfind("/vsi", 0) == 0) return p;
  if (endsWithNoCase(p, ".gz")) return "/vsigzip/" + p;
  if (endsWithNoCase(p, ".zip")) return "/vsizip/" + p;
  return p;
}

/// Value of `key` in an OSM other_tags field: "k"=>"v","k2"=>"v2".
std::optional<std::string> hstoreValue(const char* s, const std::string& key) {
  auto quotedString = [&](const char*& c, std::string& out) {
    if (*c != '"') return false;
    ++c;
    out.clear();
    while (*c && *c != '"') {
      if (*c == '\\' && c[1]) ++c;
      out.push_back(*c++);
    }
    if (*c != '"') return false;
    ++c;
    return true;
  };
  std::string k, v;
  const char* c = s;
  while (*c) {
    while (*c == ',' || *c == ' ') ++c;
    if (!*c) break;
    if (!quotedString(c, k)) return std::nullopt;
    if (c[0] != '=' || c[1] != '>') return std::nullopt;
    c += 2;
    if (!quotedString(c, v)) return std::nullopt;
    if (k == key) return v;
  }
  return std::nullopt;
}

/// What the attribute callback of materials::classify sees.
struct FeatureView {
  OGRFeatureH f = nullptr;
  int otherTags = -1;
};

std::optional<std::string> attributeOf(const void* p, const std::string& key) {
  const auto& v = *static_cast<const FeatureView*>(p);
  const int i = OGR_F_GetFieldIndex(v.f, key.c_str());
  if (i >= 0) {
    if (!OGR_F_IsFieldSetAndNotNull(v.f, i)) return std::nullopt;
    return std::string(OGR_F_GetFieldAsString(v.f, i));
  }
  if (v.otherTags >= 0 && OGR_F_IsFieldSetAndNotNull(v.f, v.otherTags)) {
    return hstoreValue(OGR_F_GetFieldAsString(v.f, v.otherTags), key);
  }
  return std::nullopt;
}

/// Leading number of an attribute ("12", "12.5 m", "12m"); nullopt when
/// there is none, or it is not positive and finite.
std::optional<double> leadingNumber(const std::optional<std::string>& v) {
  if (!v) return std::nullopt;
  char* end = nullptr;
  const double d = std::strtod(v->c_str(), &end);
  if (end == v->c_str() || !(d > 0) || !std::isfinite(d)) return std::nullopt;
  return d;
}

/// A building's height: `height`, else `building:levels` storeys, else the
/// class's default (materials::Class::extrude); at most 1000 m.
double buildingHeight(const FeatureView& view, const materials::Class& cls) {
  if (auto h = leadingNumber(attributeOf(&view, "height")); h && *h <= 1000) return *h;
  if (auto n = leadingNumber(attributeOf(&view, "building:levels")); n && *n <= 300) return *n * cls.storey;
  return cls.extrude;
}

/// Per-layer state: name, transform into the frame, OSM extras.
struct LayerState {
  std::string name;
  OGRCoordinateTransformation* ct = nullptr;
  bool skip = false;
  bool failed = false;
  int otherTags = -1;
  std::uint64_t defaulted = 0;
  std::uint64_t unmatchedLines = 0;
  ~LayerState() { OGRCoordinateTransformation::DestroyCT(ct); }
};

struct Loader {
  CultureImpl& c;
  OGRSpatialReference target;
  Box dbProjected;  ///< database rectangle in (easting, northing)
  Box dbWorld;      ///< and in world metres
  /// Area features of the default class change nothing when it ranks below
  /// every other area class: they are counted, not kept.
  bool dropDefaultAreas = false;
  std::uint64_t outside = 0;  ///< features of the current source wholly outside the database
  /// Per source: its features' extent in the database CRS, and how many landed.
  struct SourceTally {
    std::string path;
    Box extent;
    std::uint64_t read = 0, landed = 0, outside = 0;
  };
  std::vector<SourceTally> tallies;
  std::size_t sourceIndex = 0, sourceCount = 1;
  std::vector<std::string> lineIds;  ///< of c.lines, in order, for the load report

  explicit Loader(CultureImpl& impl) : c(impl) {}

  void progress(double fraction, const char* stage) const {
    if (c.options.progress) c.options.progress(fraction, stage);
  }
  std::string lonLatExtent(const Box& projected);
  std::vector<Problem> nothingLanded(const CultureFrame& frame);

  void warn(const std::string& m) {
    ++c.stats_.warnings;
    if (c.stats_.messages.size() < kMaxMessages) c.stats_.messages.push_back(m);
  }
  void tally(const char* key, const std::string& id) { convert::tally(c.stats_, key, id); }

  Vec2 world(double e, double n) const { return {e - c.frame.originEasting, c.frame.originNorthing - n}; }

  Result<bool> readSource(const std::string& source);
  void addFeature(const std::string& where, OGRFeatureH f, LayerState& ls);
  void addPoints(OGRFeatureH f, const OGRGeometry& g, LayerState& ls);
  bool addLine(const std::string& where, const OGRGeometry& g, const materials::Class& cls, double width,
               ClassStats& cs);
  /// buildingHeight > 0: the footprint of an extruded class, kept as a building.
  bool addArea(const std::string& where, OGRGeometry& g, const materials::Class& cls, ClassStats& cs,
               double extrudeHeight = 0);
  void simplifyLine(const std::string& id, LineFeature& lf);
};

Result<bool> Loader::readSource(const std::string& source) {
  const std::string path = gdalPath(source);
  CPLErrorReset();
  GDALDatasetH ds = GDALOpenEx(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, nullptr, nullptr);
  if (!ds) {
    const char* e = CPLGetLastErrorMsg();
    return Problem{source, 0, "culture: cannot open as a vector source" + std::string(e && *e ? ": " : "") +
                                  (e ? e : "") + " (any OGR vector format: Shapefile, GeoPackage, GeoJSON, "
                                                 "OSM .osm/.osm.gz/.pbf)"};
  }
  const char* drv = GDALGetDriverShortName(GDALGetDatasetDriver(ds));
  const bool osm = drv && std::string(drv) == "OSM";
  std::unordered_map<OGRLayerH, std::unique_ptr<LayerState>> layers;
  auto stateOf = [&](OGRLayerH l) -> LayerState& {
    auto& slot = layers[l];
    if (slot) return *slot;
    slot = std::make_unique<LayerState>();
    LayerState& s = *slot;
    s.name = OGR_L_GetName(l);
    // OSM: lines and multipolygons are culture; points, route relations
    // (multilinestrings) and other relations are not.
    if (osm && s.name != "lines" && s.name != "multipolygons") s.skip = true;
    if (osm && s.name == "points" && !c.table.places.empty()) s.skip = false;  // `place` lines want them
    OGRFeatureDefnH defn = OGR_L_GetLayerDefn(l);
    if (osm) s.otherTags = OGR_FD_GetFieldIndex(defn, "other_tags");
    if (s.skip) return s;
    OGRSpatialReference src;
    if (const OGRSpatialReference* ref = OGRSpatialReference::FromHandle(OGR_L_GetSpatialRef(l))) {
      src = *ref;
    } else {
      warn("culture: " + source + " layer " + s.name + " has no CRS; assuming WGS 84 longitude/latitude");
      src.SetWellKnownGeogCS("WGS84");
    }
    src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    s.ct = OGRCreateCoordinateTransformation(&src, &target);
    if (!s.ct) {
      warn("culture: " + source + " layer " + s.name + ": no transformation from its CRS into the database CRS; "
           "layer skipped");
      s.skip = true;
      s.failed = true;
    }
    return s;
  };
  tallies.push_back({source, {}, 0, 0, 0});
  const std::uint64_t read0 = c.stats_.featuresRead, landed0 = c.stats_.featuresLanded;
  GDALDatasetResetReading(ds);
  for (std::uint64_t n = 0;; ++n) {
    OGRLayerH layer = nullptr;
    double pct = 0;
    OGRFeatureH f = GDALDatasetGetNextFeature(ds, &layer, &pct, nullptr, nullptr);
    if (!f) break;
    if (layer) {
      LayerState& ls = stateOf(layer);
      if (!ls.skip) addFeature(source + " layer " + ls.name, f, ls);
    }
    OGR_F_Destroy(f);
    if (cancelRequested()) {
      GDALClose(ds);
      return Problem{source, 0, "build: cancelled"};
    }
    if (n % 64 == 0) {
      // Reading is the first half of loading; widening the second.
      progress(0.5 * (double(sourceIndex) + std::clamp(pct, 0.0, 1.0)) / double(sourceCount), "reading culture");
    }
  }
  SourceTally& tally = tallies.back();
  tally.read = c.stats_.featuresRead - read0;
  tally.landed = c.stats_.featuresLanded - landed0;
  tally.outside = outside;
  c.stats_.featuresOutside += outside;
  if (outside > 0 && c.stats_.messages.size() < kMaxMessages) {
    c.stats_.messages.push_back("culture: " + source + ": " + std::to_string(outside) +
                                " features lie outside the database (dropped, not a warning)");
  }
  outside = 0;
  // In layer-name order: the map's order follows heap addresses, and the
  // manifest must not change from one run to the next.
  std::vector<const LayerState*> byName;
  for (const auto& entry : layers) byName.push_back(entry.second.get());
  std::sort(byName.begin(), byName.end(), [](const LayerState* a, const LayerState* b) { return a->name < b->name; });
  for (const LayerState* s : byName) {
    if (s->defaulted > 0 && c.stats_.messages.size() < kMaxMessages) {
      // Counted per feature already; one message per layer.
      c.stats_.messages.push_back("culture: " + source + " layer " + s->name + ": " + std::to_string(s->defaulted) +
                                  " features matched no rule and took the default class");
    }
    if (s->unmatchedLines > 0 && c.stats_.messages.size() < kMaxMessages) {
      c.stats_.messages.push_back("culture: " + source + " layer " + s->name + ": " +
                                  std::to_string(s->unmatchedLines) +
                                  " lines matched no rule and the table's default-line is none; dropped");
    }
  }
  GDALClose(ds);
  return true;
}

std::string Loader::lonLatExtent(const Box& b) {
  const auto geo = geodesy::Projection::create(c.frame.crsWkt);
  Box ll;
  for (int i = 0; i <= 4 && geo; ++i) {  // the edges, not only the corners: projections bend them
    for (int j = 0; j <= 4; ++j) {
      const double x = b.x0 + (b.x1 - b.x0) * i / 4, y = b.z0 + (b.z1 - b.z0) * j / 4;
      if (const auto p = geo->toLonLat({x, y})) ll.add(Vec2{p->lon, p->lat});
    }
  }
  if (ll.empty()) return "(not expressible in longitude/latitude)";
  char text[128];
  std::snprintf(text, sizeof text, "lon %.4f .. %.4f, lat %.4f .. %.4f", ll.x0, ll.x1, ll.z0, ll.z1);
  return text;
}

/// The error when culture was given but none of it lies on the terrain.
std::vector<Problem> Loader::nothingLanded(const CultureFrame& frame) {
  const Box db{frame.originEasting, frame.originNorthing - frame.heightM, frame.originEasting + frame.widthM,
               frame.originNorthing};
  std::vector<Problem> out;
  for (const SourceTally& t : tallies) {
    std::string m;
    if (t.read == 0) {
      m = "culture: no line or area features (points are not culture); nothing to decal";
    } else if (t.outside == 0) {
      m = "culture: none of its " + std::to_string(t.read) +
          " line and area features was used (ignored by the material table, or dropped as unusable)";
    } else {
      m = "culture: none of its " + std::to_string(t.read) + " line and area features lies on the terrain (" +
          std::to_string(t.outside) + " wholly outside): the culture covers " + lonLatExtent(t.extent) +
          ", the database " + lonLatExtent(db);
    }
    out.push_back({t.path, 0, m + "; give culture that overlaps the elevation (or a larger "
                                  "ElevationOptions::sources or ElevationOptions::extent), or leave out "
                                  "CultureOptions::sources"});
  }
  return out;
}

/// Kind of a geometry for classification: 1 line, 2 area, 0 neither.
int kindOf(const OGRGeometry* g) {
  switch (wkbFlatten(g->getGeometryType())) {
    case wkbLineString:
    case wkbMultiLineString:
    case wkbCircularString:
    case wkbCompoundCurve:
    case wkbMultiCurve:
      return 1;
    case wkbPolygon:
    case wkbMultiPolygon:
    case wkbCurvePolygon:
    case wkbMultiSurface:
    case wkbTriangle:
    case wkbPolyhedralSurface:
    case wkbTIN:
      return 2;
    case wkbGeometryCollection: {
      const auto* gc = g->toGeometryCollection();
      for (const OGRGeometry* part : *gc) {
        if (const int k = kindOf(part)) return k;
      }
      return 0;
    }
    default:
      return 0;
  }
}

void Loader::addFeature(const std::string& where, OGRFeatureH f, LayerState& ls) {
  OGRGeometry* raw = OGRGeometry::FromHandle(OGR_F_GetGeometryRef(f));
  if (!raw || raw->IsEmpty()) return;
  const int kind = kindOf(raw);
  if (kind == 0) return addPoints(f, *raw, ls);  // points are not culture, but may be objects
  ++c.stats_.featuresRead;
  const std::string id = where + " feature " + std::to_string(OGR_F_GetFID(f));
  FeatureView view{f, ls.otherTags};
  const materials::Match m = materials::classify(c.table, ls.name, &view, &attributeOf, kind == 1);
  if (m.classId == materials::kNoClass) {
    ++c.stats_.ignored;
    if (m.matched) {
      tally("ignore_rule", id);
    } else {
      // A line no rule matched, and default-line none: dropped, a warning.
      tally("unmatched_line", id);
      ++ls.unmatchedLines;
      ++c.stats_.warnings;
    }
    return;
  }
  const materials::Class* cls = c.table.find(m.classId);
  if (!cls) {
    ++c.stats_.ignored;
    tally("unknown_class", id);
    ++c.stats_.warnings;
    return;
  }
  ClassStats& cs = c.stats_.perClass[cls->name];
  ++cs.read;
  if (!m.matched) {
    ++cs.defaulted;
    ++ls.defaulted;
    ++c.stats_.warnings;
    tally("no_rule_default", id);
  }
  // Curves to line strings, then into the database CRS.
  std::unique_ptr<OGRGeometry> g(raw->hasCurveGeometry() ? raw->getLinearGeometry() : raw->clone());
  if (!g || g->transform(ls.ct) != OGRERR_NONE) {
    ++cs.dropped;
    tally("no_transform", id);
    warn("culture: " + id + ": cannot transform into the database CRS; dropped");
    return;
  }
  g->flattenTo2D();
  OGREnvelope env;
  g->getEnvelope(&env);
  const Box box{env.MinX, env.MinY, env.MaxX, env.MaxY};
  tallies.back().extent.add(box);
  if (kind == 2 && dropDefaultAreas && cls->id == c.table.defaultArea) {
    // Changes nothing on the skin, but lands if it overlaps.
    if (box.overlaps(dbProjected)) {
      ++c.stats_.featuresLanded;
    } else {
      ++outside;
      tally("outside", id);
    }
    return;
  }
  const double building = kind == 2 && cls->extrude > 0 ? buildingHeight(view, *cls) : 0.0;
  const bool kept = kind == 1 ? addLine(id, *g, *cls, m.width, cs) : addArea(id, *g, *cls, cs, building);
  if (kept) ++c.stats_.featuresLanded;
}

void Loader::addPoints(OGRFeatureH f, const OGRGeometry& g, LayerState& ls) {
  if (c.table.places.empty()) return;
  FeatureView view{f, ls.otherTags};
  const materials::Place* pl = materials::placeFor(c.table, ls.name, &view, &attributeOf);
  if (!pl) return;
  const auto place = std::uint32_t(pl - c.table.places.data());
  auto one = [&](const OGRPoint& p) {
    double e = p.getX(), n = p.getY();
    if (!ls.ct->Transform(1, &e, &n)) return;
    const Vec2 w = world(e, n);
    if (!(w.x >= 0 && w.x <= c.frame.widthM && w.z >= 0 && w.z <= c.frame.heightM)) return;
    c.points_.push_back({w.x, w.z, place});
    ++c.stats_.pointsPlaced;
  };
  const auto t = wkbFlatten(g.getGeometryType());
  if (t == wkbPoint) {
    one(*g.toPoint());
  } else if (t == wkbMultiPoint) {
    for (const OGRPoint* p : *g.toMultiPoint()) one(*p);
  }
}

template <typename Fn>
void forEachPart(const OGRGeometry& g, OGRwkbGeometryType want, Fn fn) {
  const auto t = wkbFlatten(g.getGeometryType());
  if (t == want) {
    fn(g);
  } else if (OGR_GT_IsSubClassOf(t, wkbGeometryCollection)) {
    for (const OGRGeometry* part : *g.toGeometryCollection()) forEachPart(*part, want, fn);
  } else if (t == wkbPolyhedralSurface || t == wkbTIN) {
    for (const OGRPolygon* p : *g.toPolyhedralSurface()) fn(*p);
  }
}

/// The parts of a polyline inside `r`.
std::vector<Polyline> clipPolyline(const Polyline& pts, const Box& r) {
  return clip::polyline(pts, clip::Rect{r.x0, r.z0, r.x1, r.z1}, &Vec2::x, &Vec2::z);
}

double lengthOf(const Polyline& p) {
  double s = 0;
  for (std::size_t k = 0; k + 1 < p.size(); ++k) s += length(p[k + 1] - p[k]);
  return s;
}

std::size_t verticesOf(const std::vector<Polyline>& parts) {
  std::size_t n = 0;
  for (const Polyline& p : parts) n += p.size();
  return n;
}

/// How crowded a line's vertices are, relative to its width: the sum over
/// vertices of the vertices within the 3 x 3 cells (one width a side)
/// around them. A line that runs on is about 3 x width / spacing per
/// vertex; one that folds back on itself within its width, far more. The
/// widened union's arrangement grows with it.
std::uint64_t crowding(const std::vector<Polyline>& parts, double width) {
  struct Hash {
    std::size_t operator()(std::pair<std::int64_t, std::int64_t> k) const {
      return std::hash<std::int64_t>()(k.first * 1000003 + k.second);
    }
  };
  std::unordered_map<std::pair<std::int64_t, std::int64_t>, std::uint32_t, Hash> cells;
  auto cellOf = [&](Vec2 p) { return std::pair{std::int64_t(std::floor(p.x / width)), std::int64_t(std::floor(p.z / width))}; };
  for (const Polyline& p : parts) {
    for (const Vec2& v : p) ++cells[cellOf(v)];
  }
  std::uint64_t sum = 0;
  for (const auto& [k, n] : cells) {
    std::uint64_t around = 0;
    for (std::int64_t dz = -1; dz <= 1; ++dz) {
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const auto it = cells.find({k.first + dx, k.second + dz});
        if (it != cells.end()) around += it->second;
      }
    }
    sum += std::uint64_t(n) * around;
  }
  return sum;
}

/// The size rule (docs/CULTURE.md, "Bounded work"): simplify at
/// max(merge tolerance, width / 100), then at doubled tolerances while the
/// feature has more than maxLineVertices vertices or they crowd more than
/// kMaxCrowding per vertex.
void Loader::simplifyLine(const std::string& id, LineFeature& lf) {
  const std::size_t before = verticesOf(lf.parts);
  c.stats_.lineVerticesRead += before;
  double tol = simplifyTolerance(lf.width, c.options.mergeTolerance);
  std::vector<Polyline> out;
  for (int round = 0;; ++round) {
    out.clear();
    for (const Polyline& p : lf.parts) out.push_back(simplifiedLine(p, tol));
    const std::size_t n = verticesOf(out);
    const bool fits = n <= c.options.maxLineVertices && crowding(out, lf.width) <= kMaxCrowding * n;
    if (fits || round >= 60) {
      if (round > 0) {
        ++c.stats_.coarsened;
        tally("simplified", id);
        char t[32];
        std::snprintf(t, sizeof t, "%.3g", tol);
        const std::string why = before > c.options.maxLineVertices
                                    ? "more than the limit of " + std::to_string(c.options.maxLineVertices)
                                    : "folding back on itself within its width";
        warn("culture: " + id + ": " + std::to_string(before) + " vertices, " + why + "; simplified at " + t +
             " m to " + std::to_string(n) + " vertices (docs/CULTURE.md, \"Bounded work\")");
      }
      break;
    }
    tol *= 2;
  }
  lf.parts = std::move(out);
  c.stats_.lineVerticesKept += verticesOf(lf.parts);
}

bool Loader::addLine(const std::string& id, const OGRGeometry& g, const materials::Class& cls, double width,
                     ClassStats& cs) {
  std::vector<Polyline> parts;
  bool repaired = false, bad = false;
  forEachPart(g, wkbLineString, [&](const OGRGeometry& part) {
    const auto* ls = part.toLineString();
    Polyline pts;
    for (int k = 0; k < ls->getNumPoints(); ++k) {
      const double e = ls->getX(k), n = ls->getY(k);
      if (!std::isfinite(e) || !std::isfinite(n)) {
        bad = true;
        return;
      }
      const Vec2 p = world(e, n);
      if (!pts.empty() && pts.back() == p) {
        repaired = true;  // repeated point
        continue;
      }
      pts.push_back(p);
    }
    if (pts.size() >= 2) parts.push_back(std::move(pts));
  });
  if (bad) {
    ++cs.dropped;
    tally("not_finite", id);
    warn("culture: " + id + ": coordinates that are not finite; dropped");
    return false;
  }
  if (parts.empty()) {
    ++cs.dropped;
    tally("zero_length", id);
    warn("culture: " + id + ": line of zero length; dropped");
    return false;
  }
  // Kept wherever the widened road can reach into the database; the
  // length counted is the part inside it.
  const Box reach = dbWorld.grown(width + 1.0);
  LineFeature lf;
  lf.classId = cls.id;
  lf.width = width;
  for (const Polyline& p : parts) {
    for (const Polyline& inside : clipPolyline(p, dbWorld)) cs.lengthKm += lengthOf(inside) / 1000.0;
    for (Polyline& q : clipPolyline(p, reach)) {
      // A loop keeps its closing point; a part cut out of it does not.
      lf.parts.push_back(std::move(q));
    }
  }
  if (lf.parts.empty()) {
    ++cs.dropped;
    ++outside;  // an extract larger than the database: expected, not a warning
    tally("outside", id);
    return false;
  }
  // The widening unites the outline by nonzero winding, so a figure 8 is
  // drawn right; it is still reported, as the source is likely wrong.
  const bool crossing = crossesItself(lf.parts);
  simplifyLine(id, lf);
  if (repaired) {
    tally("repeated_points", id);
    warn("culture: " + id + ": repeated points removed");
  }
  if (crossing) {
    tally("self_intersecting_line", id);
    warn("culture: " + id + ": line crosses itself; widened as one outline, the crossing drawn once");
  }
  if (repaired || crossing) ++cs.repaired;
  c.lines.push_back(std::move(lf));
  lineIds.push_back(id);
  return true;
}

bool Loader::addArea(const std::string& id, OGRGeometry& g, const materials::Class& cls, ClassStats& cs,
                     double extrudeHeight) {
  // Clean each ring (repeated points, closure) into a fresh multipolygon.
  bool repaired = false, bad = false, unclosed = false, repeated = false;
  OGRMultiPolygon mp;
  forEachPart(g, wkbPolygon, [&](const OGRGeometry& part) {
    const auto* poly = part.toPolygon();
    OGRPolygon clean;
    bool first = true;
    for (const OGRLinearRing* ring : *poly) {
      std::vector<std::pair<double, double>> pts;
      for (int k = 0; k < ring->getNumPoints(); ++k) {
        const double e = ring->getX(k), n = ring->getY(k);
        if (!std::isfinite(e) || !std::isfinite(n)) {
          bad = true;
          return;
        }
        if (!pts.empty() && pts.back() == std::make_pair(e, n)) {
          repeated = true;
          continue;
        }
        pts.emplace_back(e, n);
      }
      if (pts.size() >= 2 && pts.front() == pts.back()) {
        pts.pop_back();
      } else if (pts.size() >= 3) {
        unclosed = true;
      }
      if (pts.size() < 3) {
        if (first) return;  // no exterior: no polygon
        continue;
      }
      OGRLinearRing r;
      for (const auto& [e, n] : pts) r.addPoint(e, n);
      r.addPoint(pts.front().first, pts.front().second);
      clean.addRing(&r);
      first = false;
    }
    if (!clean.IsEmpty()) mp.addGeometry(&clean);
  });
  if (bad) {
    ++cs.dropped;
    tally("not_finite", id);
    warn("culture: " + id + ": coordinates that are not finite; dropped");
    return false;
  }
  std::unique_ptr<OGRGeometry> geom(mp.clone());
  if (unclosed) {
    tally("unclosed_ring", id);
    warn("culture: " + id + ": ring not closed; closed it");
  }
  if (repeated) {
    tally("repeated_points", id);
    warn("culture: " + id + ": repeated points removed");
  }
  repaired = unclosed || repeated;
  if (!geom->IsEmpty() && !geom->IsValid()) {
    std::unique_ptr<OGRGeometry> valid(geom->MakeValid());
    if (!valid) {
      ++cs.dropped;
      tally("invalid_polygon_dropped", id);
      warn("culture: " + id + ": invalid polygon that cannot be repaired; dropped");
      return false;
    }
    geom = std::move(valid);
    repaired = true;
    tally("invalid_polygon_repaired", id);
    warn("culture: " + id + ": invalid polygon (self-intersection); repaired");
  }
  // Clip to the database rectangle.
  bool clipped = false;
  OGREnvelope env;
  geom->getEnvelope(&env);
  const Box& r = dbProjected;
  if (env.MinX < r.x0 || env.MaxX > r.x1 || env.MinY < r.z0 || env.MaxY > r.z1) {
    OGRPolygon rect;
    OGRLinearRing ring;
    ring.addPoint(r.x0, r.z0);
    ring.addPoint(r.x1, r.z0);
    ring.addPoint(r.x1, r.z1);
    ring.addPoint(r.x0, r.z1);
    ring.addPoint(r.x0, r.z0);
    rect.addRing(&ring);
    std::unique_ptr<OGRGeometry> cut(env.MaxX < r.x0 || env.MinX > r.x1 || env.MaxY < r.z0 || env.MinY > r.z1
                                         ? nullptr
                                         : geom->Intersection(&rect));
    if (!cut) {
      ++cs.dropped;
      ++outside;
      tally("outside", id);
      return false;
    }
    geom = std::move(cut);
    clipped = true;
  }
  AreaFeature af;
  af.classId = cls.id;
  double area = 0;
  forEachPart(*geom, wkbPolygon, [&](const OGRGeometry& part) {
    const auto* poly = part.toPolygon();
    bool exterior = true;
    for (const OGRLinearRing* ring : *poly) {
      Ring w;
      for (int k = 0; k + 1 < ring->getNumPoints(); ++k) {
        const Vec2 p = world(ring->getX(k), ring->getY(k));
        if (w.empty() || !(w.back() == p)) w.push_back(p);
      }
      while (w.size() > 1 && w.front() == w.back()) w.pop_back();
      const double a = w.size() >= 3 ? signedArea(w) : 0.0;
      if (a != 0) {
        // Exterior rings positive, holes negative (the frame flips z).
        if ((a > 0) != exterior) std::reverse(w.begin(), w.end());
        area += exterior ? std::fabs(a) : -std::fabs(a);
        af.box.add(boxOf(w));
        af.rings.push_back(std::move(w));
      }
      exterior = false;
    }
  });
  if (!(area > 1e-6) || af.rings.empty()) {
    ++cs.dropped;
    if (clipped && geom->IsEmpty()) {
      ++outside;
      tally("outside", id);
    } else {
      tally("no_area", id);
      warn("culture: " + id + ": polygon of no area; dropped");
    }
    return false;
  }
  if (repaired) ++cs.repaired;
  cs.areaKm2 += area / 1e6;
  if (extrudeHeight > 0) {
    c.buildings.push_back({af.classId, std::move(af.rings), af.box, extrudeHeight, area});
    ++c.stats_.buildings;
  } else {
    c.areas.push_back(std::move(af));
  }
  return true;
}

/// Ends of line parts shared with another part's end get a join piece.
void markJoins(std::vector<LineFeature>& lines) {
  struct Hash {
    std::size_t operator()(const Vec2& p) const {
      return std::hash<double>()(p.x) * 1000003u ^ std::hash<double>()(p.z);
    }
  };
  std::unordered_map<Vec2, int, Hash> ends;
  for (const LineFeature& l : lines) {
    for (const Polyline& p : l.parts) {
      if (p.front() == p.back()) continue;  // a loop has no ends
      ++ends[p.front()];
      ++ends[p.back()];
    }
  }
  for (LineFeature& l : lines) {
    l.joinStart.assign(l.parts.size(), false);
    l.joinEnd.assign(l.parts.size(), false);
    for (std::size_t k = 0; k < l.parts.size(); ++k) {
      const Polyline& p = l.parts[k];
      if (p.front() == p.back()) continue;
      l.joinStart[k] = ends[p.front()] > 1;
      l.joinEnd[k] = ends[p.back()] > 1;
    }
  }
}

/// Widens every line feature (widenLine), in parallel. Fails only when the
/// build was cancelled; lines that could not be widened are a warning.
Status widenAll(std::vector<LineFeature>& lines, int threads, double mergeTolerance, const Loader& loader) {
  std::atomic<std::size_t> done{0};
  std::atomic<std::size_t> failed{0};
  std::atomic<bool> stop{false};
  std::mutex progressMutex;
  // Longest first: one long river started last would widen alone while
  // the other workers wait. (Each line is widened on its own, so the
  // order changes no result.)
  std::vector<std::size_t> order(lines.size());
  std::vector<std::size_t> vertices(lines.size(), 0);
  for (std::size_t k = 0; k < lines.size(); ++k) {
    order[k] = k;
    for (const Polyline& p : lines[k].parts) vertices[k] += p.size();
  }
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return vertices[a] > vertices[b]; });
  auto work = [&](std::size_t index) {
    LineFeature& l = lines[order[index]];
    try {
      l.outline = widenLine(l.parts, l.joinStart, l.joinEnd, l.width, simplifyTolerance(l.width, mergeTolerance));
    } catch (const Cancelled&) {
      stop = true;
      return;
    } catch (const std::exception&) {
      l.outline.clear();
      ++failed;
    }
    l.box = Box{};
    for (const Ring& r : l.outline) l.box.add(boxOf(r));
    {
      std::lock_guard lock(progressMutex);  // callbacks are called one at a time
      loader.progress(0.5 + 0.5 * double(++done) / double(lines.size()), "widening lines");
    }
    if (cancelRequested()) stop = true;
  };
  if (!lines.empty()) loader.progress(0.5, "widening lines");
  jobs::parallelFor(lines.size(), threads, work, &stop);
  Status st;
  if (stop) st.add(Problem{"culture", 0, "build: cancelled"});
  if (failed) {
    st.addWarning({"culture", 0,
                   "culture: " + std::to_string(failed.load()) +
                       " line features could not be widened (CGAL failure); dropped"});
  }
  return st;
}

}  // namespace

namespace culture {

CultureImpl::CultureImpl(const materials::Table& t, const CultureFrame& f, const CultureOptions& o)
    : table(t), frame(f), options(o) {
  cacheCapacity_ = o.cacheModules > 0 ? o.cacheModules : 4 * std::size_t(jobs::threadCount(0));
}

void CultureImpl::buildIndex() {
  indexCols = std::uint32_t(std::max(1.0, std::ceil(frame.widthM / indexCell)));
  indexRows = std::uint32_t(std::max(1.0, std::ceil(frame.heightM / indexCell)));
  const std::size_t cells = std::size_t(indexCols) * indexRows;
  areaIndex.assign(cells, {});
  lineIndex.assign(cells, {});
  auto add = [&](const Box& b, std::uint32_t id, std::vector<std::vector<std::uint32_t>>& index) {
    if (b.empty()) return;
    const auto col = [&](double x) { return std::uint32_t(std::clamp(std::floor(x / indexCell), 0.0, double(indexCols - 1))); };
    const auto row = [&](double z) { return std::uint32_t(std::clamp(std::floor(z / indexCell), 0.0, double(indexRows - 1))); };
    for (std::uint32_t r = row(b.z0); r <= row(b.z1); ++r) {
      for (std::uint32_t q = col(b.x0); q <= col(b.x1); ++q) index[std::size_t(r) * indexCols + q].push_back(id);
    }
  };
  for (std::uint32_t k = 0; k < areas.size(); ++k) add(areas[k].box, k, areaIndex);
  for (std::uint32_t k = 0; k < lines.size(); ++k) add(lines[k].box, k, lineIndex);
  buildingIndex.assign(cells, {});
  for (std::uint32_t k = 0; k < buildings.size(); ++k) {
    const Vec2 c = buildings[k].centre();
    add(Box{c.x, c.z, c.x, c.z}, k, buildingIndex);
  }
}

}  // namespace culture

Result<std::shared_ptr<const Culture>> Culture::load(const CultureOptions& options, const materials::Table& table,
                                                      const CultureFrame& frame) {
  const auto t0 = std::chrono::steady_clock::now();
  initGdal();
  if (!(frame.widthM > 0) || !(frame.heightM > 0) || !std::isfinite(frame.widthM + frame.heightM) ||
      !std::isfinite(frame.originEasting + frame.originNorthing)) {
    return Problem{"culture", 0, "culture: the database frame has no extent"};
  }
  if (!(options.mergeTolerance >= 0) || options.mergeTolerance > 10) {
    return Problem{"culture", 0, "culture: the merge tolerance must be 0..10 m"};
  }
  if (const double st = options.vertexStep;
      st != 0 && !(st >= std::ldexp(1.0, -20) && st <= 1 && std::ldexp(1.0, std::ilogb(st)) == st)) {
    return Problem{"culture", 0, "culture: vertexStep must be 0 or a power of two from 2^-20 to 1 m"};
  }
  if (!table.find(table.defaultArea)) {
    return Problem{"culture", 0, "culture: the material table's default-area class is not defined"};
  }
  auto impl = std::make_shared<CultureImpl>(table, frame, options);
  Loader loader(*impl);
  if (loader.target.importFromWkt(frame.crsWkt.c_str()) != OGRERR_NONE) {
    return Problem{"culture", 0, "culture: the database CRS is not valid WKT"};
  }
  loader.target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  loader.dbWorld = {0, 0, frame.widthM, frame.heightM};
  {
    const materials::Class* d = table.find(table.defaultArea);
    loader.dropDefaultAreas = std::all_of(table.classes.begin(), table.classes.end(), [&](const materials::Class& k) {
      return k.kind != materials::Kind::area || k.id == d->id || k.rank > d->rank;
    });
  }
  loader.dbProjected = {frame.originEasting, frame.originNorthing - frame.heightM, frame.originEasting + frame.widthM,
                        frame.originNorthing};
  loader.sourceCount = std::max<std::size_t>(1, options.sources.size());
  for (const std::string& s : options.sources) {
    auto r = loader.readSource(s);
    if (!r) return r.problems();
    ++loader.sourceIndex;
  }
  if (!options.sources.empty() && impl->stats_.featuresLanded == 0 && impl->points_.empty()) {
    return loader.nothingLanded(frame);
  }
  markJoins(impl->lines);
  const Status widened = widenAll(impl->lines, options.threads, options.mergeTolerance, loader);
  for (const Problem& w : widened.warnings()) loader.warn(w.message);
  if (!widened) return widened.problems();
  for (std::size_t k = 0; k < impl->lines.size(); ++k) {
    const LineFeature& l = impl->lines[k];
    if (!l.outline.empty()) continue;
    tally(impl->stats_, "widen_failed", loader.lineIds[k]);
    if (const materials::Class* cls = table.find(l.classId)) ++impl->stats_.perClass[cls->name].dropped;
    --impl->stats_.featuresLanded;
  }
  std::erase_if(impl->lines, [](const LineFeature& l) { return l.outline.empty(); });
  impl->buildIndex();
  impl->options.progress = nullptr;  // it may refer to the caller's state; load is over
  impl->stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return std::shared_ptr<const Culture>(std::move(impl));
}

}  // namespace sandtable::convert
