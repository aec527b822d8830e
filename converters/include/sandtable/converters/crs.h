#pragma once
// Coordinate reference systems for the database frame, through GDAL/OGR and
// PROJ. Every coordinate transform in sandtable goes through this file.
#include <memory>
#include <string>

#include "sandtable/base/result.h"

class OGRCoordinateTransformation;

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

/// lon/lat (WGS 84, degrees) <-> easting/northing in a projected CRS.
/// Not thread-safe: give each thread its own.
class GeoTransformer {
 public:
  static Result<std::unique_ptr<GeoTransformer>> create(const std::string& projectedWkt);
  ~GeoTransformer();
  GeoTransformer(const GeoTransformer&) = delete;
  GeoTransformer& operator=(const GeoTransformer&) = delete;

  bool toProjected(double lon, double lat, double& easting, double& northing) const;
  bool toLonLat(double easting, double northing, double& lon, double& lat) const;
  /// Batch versions (in place); false if any point failed.
  bool toProjected(std::size_t n, double* x, double* y) const;
  bool toLonLat(std::size_t n, double* x, double* y) const;

 private:
  GeoTransformer() = default;
  OGRCoordinateTransformation* forward_ = nullptr;
  OGRCoordinateTransformation* inverse_ = nullptr;
};

/// Registers GDAL drivers once; safe to call from anywhere.
void initGdal();

}  // namespace sandtable::convert
