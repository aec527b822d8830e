#include "sandtable/converters/validate.h"

#include <cmath>
#include <cstdio>
#include <numbers>

#include <ogr_spatialref.h>

#include "sandtable/converters/crs.h"
#include "sandtable/formats/database.h"

namespace sandtable::convert {
namespace {

std::string format(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

/// Why the WKT is not a frame the tools can use, or "".
std::string crsProblem(const std::string& wkt) {
  initGdal();
  OGRSpatialReference srs;
  if (srs.importFromWkt(wkt.c_str()) != OGRERR_NONE) {
    return "crs.wkt cannot be parsed as a CRS (GDAL/PROJ refuse it), so sample, fly and export cannot place "
           "lon/lat in the database; rebuild the database";
  }
  if (!srs.IsProjected()) {
    return "crs.wkt is not a projected CRS; the grid is in metres of a projected frame (the build only "
           "writes utm, cassini or a projected EPSG code); rebuild the database";
  }
  if (std::fabs(srs.GetLinearUnits() - 1.0) > 1e-12) {
    return format("crs.wkt is in units of %.9g m, not metres; rebuild the database", srs.GetLinearUnits());
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

std::vector<Problem> checkGeoreference(const manifest::Manifest& m, const std::string& manifestPath) {
  auto fail = [&](const std::string& msg) { return std::vector<Problem>{{manifestPath, 0, "manifest: " + msg}}; };
  if (std::string why = crsProblem(m.crsWkt); !why.empty()) return fail(why);
  auto geo = GeoTransformer::create(m.crsWkt);
  if (!geo) return fail("crs.wkt: " + geo.problems().front().message + "; rebuild the database");
  std::vector<Problem> out;
  const char* names[4] = {"NW", "NE", "SE", "SW"};
  const double es[4] = {m.originEasting, m.eastEasting(), m.eastEasting(), m.originEasting};
  const double ns[4] = {m.originNorthing, m.originNorthing, m.southNorthing(), m.southNorthing()};
  for (int k = 0; k < 4; ++k) {
    const auto& c = m.cornersLonLat[std::size_t(k)];
    double lon = 0, lat = 0;
    if (!geo.value()->toLonLat(es[k], ns[k], lon, lat)) {
      out.push_back({manifestPath, 0,
                     format("manifest: the grid's %s corner post (E %.3f, N %.3f) does not transform to lon/lat "
                            "through crs.wkt",
                            names[k], es[k], ns[k])});
      continue;
    }
    const double d = groundMetres(c[0], c[1], lon, lat);
    if (!(d <= kCornerToleranceMetres)) {
      out.push_back({manifestPath, 0,
                     format("manifest: corners_lonlat[%d] (%s) is lon %.9f lat %.9f, but the grid's %s corner post "
                            "(E %.3f, N %.3f) transforms through crs.wkt to lon %.9f lat %.9f, %.3f m away (more "
                            "than %.2f m)",
                            k, names[k], c[0], c[1], names[k], es[k], ns[k], lon, lat, d, kCornerToleranceMetres)});
    }
  }
  return out;
}

std::vector<Problem> validateDatabaseWithCrs(const std::string& dir, const Work& work) {
  std::vector<Problem> out = validateDatabase(dir, work).problems();
  if (work.cancelled()) return out;
  auto m = manifest::readFromDirectory(dir);
  if (!m) return out;  // validateDatabase has reported why
  auto geo = checkGeoreference(m.value(), dir + "/" + manifest::kFileName);
  out.insert(out.end(), geo.begin(), geo.end());
  return out;
}

}  // namespace sandtable::convert
