#pragma once
// Choosing the coordinate reference system of a database, through GDAL/OGR
// and PROJ. Transforms between the database frame, lon/lat and geocentric
// coordinates are geodesy's (sandtable/geodesy/geodesy.h).
#include <string>

#include "sandtable/base/result.h"

namespace sandtable::convert {

/// The projected frame a database is built in.
struct TargetCrs {
  std::string wkt;   ///< WKT2 of the CRS
  std::string name;  ///< e.g. "WGS 84 / UTM zone 32N"
  int epsg = 0;      ///< 0 when there is none (Cassini)
};

/// Resolves an ElevationOptions::crs request for a database centred at (lon, lat):
/// "utm" (the UTM zone of the centre, WGS 84), "cassini" (Cassini-Soldner
/// centred there), or "EPSG:n" (must be a projected CRS in metres).
Result<TargetCrs> resolveCrs(const std::string& request, double centerLon, double centerLat);

/// Registers GDAL drivers once; safe to call from anywhere.
void initGdal();

/// GDAL's last error message on this thread, or "unknown GDAL error".
std::string lastGdalError();

}  // namespace sandtable::convert
