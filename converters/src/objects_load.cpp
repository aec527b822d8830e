// The object plan of a build: scatter and place lines resolved to icons,
// and explicit points files read through OGR (docs/ICONS.md §8).
#include <cmath>
#include <memory>

#include <gdal.h>
#include <ogr_api.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include "sandtable/converters/crs.h"
#include "sandtable/converters/objects.h"

namespace sandtable::convert {

namespace {

std::optional<std::uint16_t> iconIndex(const iconpack::Pack& icons, const std::string& name) {
  for (std::size_t k = 0; k < icons.icons.size(); ++k) {
    if (icons.icons[k].name == name) return std::uint16_t(k);
  }
  return std::nullopt;
}

std::string iconList(const iconpack::Pack& icons) {
  std::string s;
  for (const auto& i : icons.icons) s += (s.empty() ? "" : ", ") + i.name;
  return s;
}

struct Dataset {
  GDALDatasetH h = nullptr;
  ~Dataset() {
    if (h) GDALClose(h);
  }
};

/// One points file into plan.points.
Status readPoints(const std::string& file, const CultureFrame& frame, const iconpack::Pack& icons,
                  ObjectPlan& plan) {
  const char* open[] = {"X_POSSIBLE_NAMES=x,lon,long,longitude,easting", "Y_POSSIBLE_NAMES=y,lat,latitude,northing",
                        "KEEP_GEOM_COLUMNS=NO", nullptr};
  Dataset ds;
  CPLErrorReset();
  ds.h = GDALOpenEx(file.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr, open, nullptr);
  if (!ds.h) {
    return Problem{file, 0, "objects: cannot open the points file (" + std::string(CPLGetLastErrorMsg()) +
                                "); give GeoJSON, GeoPackage, CSV or another OGR vector file to --objects"};
  }
  OGRSpatialReference target;
  if (target.importFromWkt(frame.crsWkt.c_str()) != OGRERR_NONE) return Problem{file, 0, "objects: database CRS"};
  target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::uint64_t outside = 0, read = 0;
  for (int li = 0; li < GDALDatasetGetLayerCount(ds.h); ++li) {
    OGRLayer* layer = OGRLayer::FromHandle(GDALDatasetGetLayer(ds.h, li));
    OGRSpatialReference src;
    if (const OGRSpatialReference* ref = layer->GetSpatialRef()) src = *ref;
    else src.SetWellKnownGeogCS("WGS84");
    src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&src, &target));
    if (!ct) return Problem{file, 0, "objects: no transformation from layer " + std::string(layer->GetName()) + "'s CRS into the database CRS"};
    const int iconField = layer->GetLayerDefn()->GetFieldIndex("icon");
    if (iconField < 0) {
      return Problem{file, 0, "objects: layer " + std::string(layer->GetName()) +
                                  " has no \"icon\" field; every point needs the name of an icon"};
    }
    const int headingField = layer->GetLayerDefn()->GetFieldIndex("heading");
    const int scaleField = layer->GetLayerDefn()->GetFieldIndex("scale");
    layer->ResetReading();
    for (std::unique_ptr<OGRFeature> f(layer->GetNextFeature()); f; f.reset(layer->GetNextFeature())) {
      const std::string id = "feature " + std::to_string(f->GetFID());
      const OGRGeometry* g = f->GetGeometryRef();
      if (!g || wkbFlatten(g->getGeometryType()) != wkbPoint) {
        return Problem{file, 0, "objects: " + id + " is not a point; a points file holds points"};
      }
      const std::string name = f->GetFieldAsString(iconField);
      const auto icon = iconIndex(icons, name);
      if (!icon) {
        return Problem{file, 0, "objects: " + id + " names icon \"" + name + "\", which the icon database lacks (it has " +
                                    iconList(icons) + "); add it to the --icons file"};
      }
      const double heading = headingField >= 0 ? f->GetFieldAsDouble(headingField) : 0.0;
      const double scale = scaleField >= 0 && f->IsFieldSetAndNotNull(scaleField) ? f->GetFieldAsDouble(scaleField) : 1.0;
      if (!std::isfinite(heading) || !(std::isfinite(scale) && scale > 0 && scale <= 100)) {
        return Problem{file, 0, "objects: " + id + ": heading must be degrees and scale in (0, 100]"};
      }
      double e = g->toPoint()->getX(), n = g->toPoint()->getY();
      if (!ct->Transform(1, &e, &n)) return Problem{file, 0, "objects: " + id + " cannot be transformed"};
      const double x = e - frame.originEasting, z = frame.originNorthing - n;
      ++read;
      if (!(x >= 0 && x <= frame.widthM && z >= 0 && z <= frame.heightM)) {
        ++outside;
        continue;
      }
      plan.points.push_back({x, z, *icon, module::kObjectClassExplicit,
                             module::headingCode(heading * 3.141592653589793 / 180.0), float(scale)});
    }
  }
  Status st;
  if (outside > 0) {
    st.addWarning({file, 0, "objects: " + std::to_string(outside) + " of " + std::to_string(read) +
                                " points lie outside the database (dropped)"});
  }
  return st;
}

}  // namespace

Result<ObjectPlan> makeObjectPlan(const std::vector<std::string>& files, const CultureFrame& frame,
                                  const materials::Table& table, const Culture* culture,
                                  const iconpack::Pack& icons) {
  initGdal();
  ObjectPlan plan;
  Warnings warnings;
  for (const auto& i : icons.icons) plan.cylinders.push_back({i.cylinderRadius, i.cylinderHeight});
  for (const materials::Scatter& sc : table.scatters) {
    const materials::Class* c = table.findByName(sc.className);
    const auto icon = iconIndex(icons, sc.icon);
    if (!c || !icon) {
      warnings.push_back({materials::kFileName, 0, "objects: scatter " + sc.className + " names icon \"" + sc.icon +
                                                       "\", which the icon database lacks; nothing scattered"});
      continue;
    }
    plan.scatters.push_back({c->id, *icon, std::sqrt(10000.0 / sc.perHectare), sc.variation, sc.seed});
  }
  if (culture) {
    std::vector<std::optional<std::uint16_t>> placeIcon;
    for (const materials::Place& pl : table.places) {
      placeIcon.push_back(iconIndex(icons, pl.icon));
      if (!placeIcon.back()) {
        warnings.push_back({materials::kFileName, 0, "objects: place " + pl.key + "=" + pl.value + " names icon \"" +
                                                         pl.icon + "\", which the icon database lacks; not placed"});
      }
    }
    for (const PointFeature& p : culture->points()) {
      if (p.place >= placeIcon.size() || !placeIcon[p.place] || p.place >= module::kMaxPlaceLines) continue;
      const materials::Place& pl = table.places[p.place];
      ObjectPlan::Point q{p.x, p.z, *placeIcon[p.place], std::uint16_t(module::kObjectClassPlace + p.place), 0, 1};
      const auto key = std::uint64_t(std::llround(p.x * 100)) * 0x9e3779b97f4a7c15ull ^ std::uint64_t(std::llround(p.z * 100));
      vary(pl.variation, 1, key, q.scale, q.heading);
      plan.points.push_back(q);
    }
  }
  for (const std::string& f : files) {
    Status st = readPoints(f, frame, icons, plan);
    if (!st) return st.problems();
    warnings.insert(warnings.end(), st.warnings().begin(), st.warnings().end());
  }
  Result<ObjectPlan> r(std::move(plan));
  r.addWarnings(warnings);
  return r;
}

}  // namespace sandtable::convert
