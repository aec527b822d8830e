#include "sandtable/converters/crs.h"

#include <algorithm>
#include <cmath>
#include <mutex>

#include <cpl_conv.h>
#include <gdal.h>
#include <ogr_spatialref.h>

namespace sandtable::convert {

void initGdal() {
  static std::once_flag once;
  std::call_once(once, [] {
    GDALAllRegister();
    CPLSetConfigOption("GDAL_NUM_THREADS", "ALL_CPUS");
    // Quiet GDAL's own stderr chatter; we report errors ourselves.
    CPLSetErrorHandler(CPLQuietErrorHandler);
  });
}

std::string lastGdalError() {
  const char* m = CPLGetLastErrorMsg();
  return (m && *m) ? std::string(m) : std::string("unknown GDAL error");
}

namespace {

std::string toWkt2(const OGRSpatialReference& srs) {
  char* wkt = nullptr;
  const char* opts[] = {"FORMAT=WKT2_2019", "MULTILINE=NO", nullptr};
  srs.exportToWkt(&wkt, opts);
  std::string s = wkt ? wkt : "";
  CPLFree(wkt);
  return s;
}

Result<TargetCrs> finish(OGRSpatialReference& srs, const std::string& request) {
  if (!srs.IsProjected()) {
    return Problem{"ElevationOptions::crs", 0, "crs: \"" + request + "\" is not a projected CRS; the grid needs a "
                                                     "flat frame in metres (try utm or cassini)"};
  }
  if (std::fabs(srs.GetLinearUnits() - 1.0) > 1e-12) {
    return Problem{"ElevationOptions::crs", 0, "crs: \"" + request + "\" is not in metres"};
  }
  TargetCrs t;
  t.wkt = toWkt2(srs);
  t.name = srs.GetName() ? srs.GetName() : request;
  const char* code = srs.GetAuthorityCode(nullptr);
  const char* auth = srs.GetAuthorityName(nullptr);
  if (code && auth && std::string(auth) == "EPSG") t.epsg = std::atoi(code);
  return t;
}

}  // namespace

Result<TargetCrs> resolveCrs(const std::string& request, double lon, double lat) {
  initGdal();
  OGRSpatialReference srs;
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (request == "utm") {
    const int zone = std::clamp(static_cast<int>(std::floor((lon + 180.0) / 6.0)) + 1, 1, 60);
    const int epsg = (lat >= 0 ? 32600 : 32700) + zone;
    if (srs.importFromEPSG(epsg) != OGRERR_NONE) {
      return Problem{"ElevationOptions::crs", 0, "crs: cannot load EPSG:" + std::to_string(epsg) + " (is proj-data installed?)"};
    }
    return finish(srs, request);
  }
  if (request == "cassini") {
    srs.SetWellKnownGeogCS("WGS84");
    srs.SetCS(lat, lon, 0.0, 0.0);
    srs.SetProjCS("Cassini-Soldner (sandtable database centre)");
    return finish(srs, request);
  }
  if (request.rfind("EPSG:", 0) == 0 || request.rfind("epsg:", 0) == 0) {
    char* end = nullptr;
    const long code = std::strtol(request.c_str() + 5, &end, 10);
    if (end == request.c_str() + 5 || *end != '\0' || code <= 0) {
      return Problem{"ElevationOptions::crs", 0, "crs: \"" + request + "\" is not of the form EPSG:<number>"};
    }
    if (srs.importFromEPSG(static_cast<int>(code)) != OGRERR_NONE) {
      return Problem{"ElevationOptions::crs", 0, "crs: EPSG:" + std::to_string(code) + " is unknown to PROJ"};
    }
    return finish(srs, request);
  }
  return Problem{"ElevationOptions::crs", 0, "crs: unknown request \"" + request + "\"; use utm, cassini or EPSG:<n>"};
}

}  // namespace sandtable::convert
