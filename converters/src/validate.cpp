#include "sandtable/converters/validate.h"

#include <cmath>
#include <cstdio>
#include <numbers>

#include <ogr_spatialref.h>

#include "sandtable/converters/crs.h"
#include "sandtable/formats/database.h"
#include "sandtable/geodesy/geodesy.h"

namespace sandtable::convert {
namespace {

std::string format(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

/// Whether the WKT is a frame the tools can use; the message says why not
/// (no file: the caller names the manifest).
Status checkCrs(const std::string& wkt) {
  initGdal();
  OGRSpatialReference srs;
  if (srs.importFromWkt(wkt.c_str()) != OGRERR_NONE) {
    return Problem{"", 0, "crs.wkt cannot be parsed as a CRS (GDAL/PROJ refuse it), so sample, fly and export cannot "
                          "place lon/lat in the database; rebuild the database"};
  }
  if (!srs.IsProjected()) {
    return Problem{"", 0, "crs.wkt is not a projected CRS; the grid is in metres of a projected frame (the build only "
                          "writes utm, cassini or a projected EPSG code); rebuild the database"};
  }
  if (std::fabs(srs.GetLinearUnits() - 1.0) > 1e-12) {
    return Problem{"", 0, format("crs.wkt is in units of %.9g m, not metres; rebuild the database", srs.GetLinearUnits())};
  }
  return {};
}

/// Metres on the ground between two nearby lon/lat points (equirectangular;
/// exact enough at the centimetres compared here).
double groundMetres(double lon0, double lat0, double lon1, double lat1) {
  constexpr double kMetresPerDegree = 6371008.8 * std::numbers::pi / 180.0;
  const double dx = (lon1 - lon0) * std::cos(lat0 * std::numbers::pi / 180.0) * kMetresPerDegree;
  const double dy = (lat1 - lat0) * kMetresPerDegree;
  return std::hypot(dx, dy);
}

}  // namespace

Status checkGeoreference(const manifest::Manifest& m, const std::string& manifestPath) {
  auto fail = [&](const std::string& msg) { return Status(Problem{manifestPath, 0, "manifest: " + msg}); };
  if (Status crs = checkCrs(m.crsWkt); !crs) return fail(crs.message());
  auto geo = geodesy::Projection::create(m.crsWkt);
  if (!geo) return fail("crs.wkt: " + geo.problems().front().message + "; rebuild the database");
  Status out;
  const char* names[4] = {"NW", "NE", "SE", "SW"};
  const double es[4] = {m.originEasting, m.eastEasting(), m.eastEasting(), m.originEasting};
  const double ns[4] = {m.originNorthing, m.originNorthing, m.southNorthing(), m.southNorthing()};
  for (int k = 0; k < 4; ++k) {
    const auto& c = m.cornersLonLat[std::size_t(k)];
    const auto ll = geo->toLonLat({es[k], ns[k]});
    if (!ll) {
      out.add({manifestPath, 0,
                     format("manifest: the grid's %s corner post (E %.3f, N %.3f) does not transform to lon/lat "
                            "through crs.wkt",
                            names[k], es[k], ns[k])});
      continue;
    }
    const double lon = ll->lon, lat = ll->lat;
    const double d = groundMetres(c[0], c[1], lon, lat);
    if (!(d <= kCornerToleranceMetres)) {
      out.add({manifestPath, 0,
                     format("manifest: corners_lonlat[%d] (%s) is lon %.9f lat %.9f, but the grid's %s corner post "
                            "(E %.3f, N %.3f) transforms through crs.wkt to lon %.9f lat %.9f, %.3f m away (more "
                            "than %.2f m)",
                            k, names[k], c[0], c[1], names[k], es[k], ns[k], lon, lat, d, kCornerToleranceMetres)});
    }
  }
  return out;
}

Status validateDatabaseWithCrs(const std::string& dir, const Work& work) {
  Status out = validateDatabase(dir, work);
  if (work.cancelled()) return out;
  auto m = manifest::readFromDirectory(dir);
  if (!m) return out;  // validateDatabase has reported why
  out.merge(checkGeoreference(m.value(), dir + "/" + manifest::kFileName));
  return out;
}

}  // namespace sandtable::convert
