#pragma once
// Geodesy through PROJ: the database frame, WGS-84 lon/lat/height and
// geocentric WGS-84 (ECEF, EPSG:4978). The one place in sandtable that
// transforms coordinates between CRSs for the database (the converters'
// source data reprojection through GDAL aside); the CLI, the converters and
// the runtime (DIS is geocentric) all come here.
//
// Frames (docs/FORMAT.md §2, seed Figure 6):
//  - projected: easting/northing in metres in the database's CRS
//    (manifest `crs.wkt`: UTM, Cassini or a projected EPSG CRS);
//  - database frame: X east, Y up, Z south, in metres, from the grid's
//    north-west corner post: X = easting - originEasting,
//    Z = originNorthing - northing, Y = height;
//  - lon/lat/height: WGS 84 geographic (EPSG:4326 for lon/lat, EPSG:4979
//    with height), degrees, longitude first;
//  - ECEF: WGS 84 geocentric, metres (EPSG:4978).
//
// Vertical datum. Database heights come from DTED and SRTM, which are
// orthometric (above mean sea level, EGM96), while lon/lat/height and ECEF
// need heights above the WGS-84 ellipsoid. They differ by the geoid
// undulation N (h = H + N; N is within about ±110 m worldwide, about +47 m
// over Germany). We apply no geoid by default: the ellipsoidal height IS
// the grid height, so a point's ECEF position is off by N along the
// vertical, the same for every point of a small area (relative positions
// are good to centimetres; absolute height is not). When a caller names a
// geoid grid (FrameOptions::geoidGrid, e.g. "egm96_15.gtx" from proj-data,
// which Debian installs with PROJ), heights go through it: h = H + N(lon, lat).
// Horizontal positions never depend on height (the database CRS is 2-D).
//
// Thread safety: every object here is an immutable value once created;
// any number of threads may call its const methods at the same time. PROJ
// objects are not shareable between threads (a PJ belongs to its
// PJ_CONTEXT), so each calling thread builds its own context and its own
// PJ per CRS pair on first use and keeps them in a thread-local cache
// (bounded; freed when the thread ends). The first call on a thread pays
// for parsing the CRS and looking it up in proj.db (milliseconds); later
// calls do not.
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "sandtable/base/result.h"

namespace sandtable::geodesy {

/// WGS 84 degrees, longitude first.
struct LonLat {
  double lon = 0;
  double lat = 0;
};

/// WGS 84 degrees and metres above the ellipsoid (see "Vertical datum").
struct LonLatHeight {
  double lon = 0;
  double lat = 0;
  double height = 0;
};

/// WGS 84 geocentric metres (EPSG:4978): X to (0°, 0°), Z to the north pole.
struct Ecef {
  double x = 0;
  double y = 0;
  double z = 0;
};

/// Metres in a projected CRS.
struct EastNorth {
  double easting = 0;
  double northing = 0;
};

/// The database frame: metres from the north-west corner post, X east,
/// Y up (the grid's height), Z south.
struct FramePoint {
  double x = 0;
  double y = 0;
  double z = 0;
};

/// WGS 84 lon/lat <-> a projected CRS in metres (the database's CRS).
/// A value: copies share the parsed definition. Thread-safe (see above).
class Projection {
 public:
  /// `wkt`: any CRS definition PROJ reads (WKT1/2, "EPSG:n"); it must be
  /// projected. Fails naming `what` (the caller's field) when PROJ cannot
  /// read it or cannot transform it to WGS 84.
  static Result<Projection> create(const std::string& wkt, const std::string& what = "crs");

  Result<EastNorth> toProjected(LonLat p) const;
  Result<LonLat> toLonLat(EastNorth p) const;
  /// In place for n points (x = lon or easting, y = lat or northing);
  /// fails when any point does not transform (that point becomes NaN).
  Status toProjected(std::span<double> x, std::span<double> y) const;
  Status toLonLat(std::span<double> x, std::span<double> y) const;

  const std::string& definition() const;

 private:
  struct Shared;
  explicit Projection(std::shared_ptr<const Shared> s) : s_(std::move(s)) {}
  std::shared_ptr<const Shared> s_;
};

struct FrameOptions {
  /// A PROJ geoid grid (file name in PROJ's search path, e.g.
  /// "egm96_15.gtx") turning grid heights (orthometric) into ellipsoidal
  /// ones; empty: none, the ellipsoidal height is the grid height.
  std::string geoidGrid;
};

/// The database frame of one database: its projection and its origin.
/// A value; thread-safe (see above).
class DatabaseFrame {
 public:
  static Result<DatabaseFrame> create(const std::string& crsWkt, double originEasting, double originNorthing,
                                      const FrameOptions& options = {});

  /// Plain arithmetic; no PROJ.
  EastNorth toProjected(const FramePoint& p) const { return {originEasting_ + p.x, originNorthing_ - p.z}; }
  FramePoint fromProjected(EastNorth e, double height) const {
    return {e.easting - originEasting_, height, originNorthing_ - e.northing};
  }

  Result<LonLatHeight> toLonLatHeight(const FramePoint& p) const;
  Result<FramePoint> fromLonLatHeight(const LonLatHeight& g) const;
  Result<Ecef> toEcef(const FramePoint& p) const;
  Result<FramePoint> fromEcef(const Ecef& e) const;
  /// Unit vectors in geocentric (ECEF) axes at `p`: down along the
  /// ellipsoid's normal, grid north (the frame's -Z) turned into the plane
  /// normal to it, and east completing north, east, down. A heading in the
  /// frame (clockwise from grid north) is a rotation about `down` from
  /// `north`: these axes carry the projection's convergence, so headings
  /// convert to and from geocentric orientations (DIS) exactly.
  struct LocalAxes {
    Ecef north, east, down;
  };
  Result<LocalAxes> localAxes(const FramePoint& p) const;

  const Projection& projection() const { return projection_; }
  double originEasting() const { return originEasting_; }
  double originNorthing() const { return originNorthing_; }

 private:
  DatabaseFrame(Projection p, double e, double n, std::string geoid)
      : projection_(std::move(p)), originEasting_(e), originNorthing_(n), geoidGrid_(std::move(geoid)) {}
  /// Ellipsoidal minus grid height at (lon, lat): N, or 0 without a geoid.
  Result<double> undulation(LonLat p) const;

  Projection projection_;
  double originEasting_ = 0;
  double originNorthing_ = 0;
  std::string geoidGrid_;
};

/// WGS 84 geographic (EPSG:4979) <-> geocentric (EPSG:4978) through PROJ.
Result<Ecef> toEcef(const LonLatHeight& g);
Result<LonLatHeight> fromEcef(const Ecef& e);

}  // namespace sandtable::geodesy
