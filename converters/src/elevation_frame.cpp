// Choosing the target frame: CRS, extent and post spacing.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <ogr_spatialref.h>

#include "elevation_internal.h"
#include "sandtable/geodesy/geodesy.h"

namespace sandtable::convert::detail {
namespace {

using Box = std::array<double, 4>;  // west, south, east, north

Result<Box> lonLatExtent(const ElevationOptions& o, const std::vector<Source>& sources) {
  Box b = sources.front().lonLatBox;
  for (const auto& s : sources) {
    b = {std::min(b[0], s.lonLatBox[0]), std::min(b[1], s.lonLatBox[1]),
         std::max(b[2], s.lonLatBox[2]), std::max(b[3], s.lonLatBox[3])};
  }
  if (!o.extent) return b;
  const Box& e = *o.extent;
  if (!(e[0] < e[2] && e[1] < e[3])) {
    return Problem{"ElevationOptions::extent", 0, "frame: ElevationOptions::extent must be WEST SOUTH EAST NORTH with west < east and south < north"};
  }
  const Box c = {std::max(b[0], e[0]), std::max(b[1], e[1]), std::min(b[2], e[2]), std::min(b[3], e[3])};
  if (!(c[0] < c[2] && c[1] < c[3])) {
    return Problem{"ElevationOptions::extent", 0, "frame: ElevationOptions::extent does not overlap the sources (they cover lon " +
                                      std::to_string(b[0]) + ".." + std::to_string(b[2]) + ", lat " +
                                      std::to_string(b[1]) + ".." + std::to_string(b[3]) + ")"};
  }
  return c;
}

/// Ground metres per degree of latitude and longitude (WGS 84 series).
std::array<double, 2> metresPerDegree(double latDeg) {
  const double lat = latDeg * M_PI / 180.0;
  return {111412.84 * std::cos(lat) - 93.5 * std::cos(3 * lat),
          111132.954 - 559.822 * std::cos(2 * lat) + 1.175 * std::cos(4 * lat)};
}

/// Largest |scale - 1| of the projection at this point, east and north.
double scaleError(const geodesy::Projection& t, double lon, double lat, bool& ok) {
  constexpr double d = 0.001;
  const auto p0 = t.toProjected({lon, lat}), p1 = t.toProjected({lon + d, lat}), p2 = t.toProjected({lon, lat + d});
  ok = p0 && p1 && p2;
  if (!ok) return INFINITY;
  const auto m = metresPerDegree(lat);
  const double kx = std::hypot(p1->easting - p0->easting, p1->northing - p0->northing) / (d * m[0]);
  const double ky = std::hypot(p2->easting - p0->easting, p2->northing - p0->northing) / (d * m[1]);
  return std::max(std::fabs(kx - 1), std::fabs(ky - 1));
}

struct Inner {
  double west = -INFINITY, east = INFINITY, south = -INFINITY, north = INFINITY;
  void intersect(const Inner& o) {
    west = std::max(west, o.west), east = std::min(east, o.east);
    south = std::max(south, o.south), north = std::min(north, o.north);
  }
};

/// Rejects a target CRS that distorts too much anywhere on the lon/lat box.
Result<bool> checkScale(const geodesy::Projection& t, const Box& b, const std::string& crsName, double maxScaleError) {
  double worst = 0, worstLon = 0, worstLat = 0;
  constexpr int kSteps = 32;
  for (int k = 0; k <= kSteps; ++k) {
    const double f = double(k) / kSteps;
    const double lon = b[0] + f * (b[2] - b[0]), lat = b[1] + f * (b[3] - b[1]);
    const double pts[5][2] = {{b[0], lat}, {b[2], lat}, {lon, b[1]}, {lon, b[3]}, {lon, lat}};
    for (const auto& p : pts) {
      bool ok = true;
      const double err = scaleError(t, p[0], p[1], ok);
      if (!ok) {
        return Problem{"ElevationOptions::crs", 0, "frame: " + crsName + " cannot hold the extent: lon " + std::to_string(p[0]) +
                                       " lat " + std::to_string(p[1]) + " does not project; use ElevationOptions::crs utm or cassini"};
      }
      if (err > worst) worst = err, worstLon = p[0], worstLat = p[1];
    }
  }
  if (worst > maxScaleError) {
    return Problem{"ElevationOptions::crs", 0, "frame: " + crsName + " cannot hold the extent: its scale error reaches " +
                                   std::to_string(worst * 100) + "% at lon " + std::to_string(worstLon) + " lat " +
                                   std::to_string(worstLat) + " (limit " + std::to_string(maxScaleError * 100) +
                                   "%); use ElevationOptions::crs utm or cassini, or a smaller extent"};
  }
  return true;
}

/// Projects the edges of a box given in `from` and keeps the largest
/// axis-aligned target rectangle inside them, so every target post has
/// source data around it.
Result<Inner> innerRectangle(const Box& b, const OGRSpatialReference& from, const TargetCrs& to) {
  OGRSpatialReference src(from), dst;
  dst.importFromWkt(to.wkt.c_str());
  src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  dst.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&src, &dst));
  if (!ct) return Problem{"ElevationOptions::crs", 0, "frame: PROJ cannot transform the sources into " + to.name};
  Inner in;
  constexpr int kSteps = 64;
  for (int k = 0; k <= kSteps; ++k) {
    const double f = double(k) / kSteps;
    const double u = b[0] + f * (b[2] - b[0]), v = b[1] + f * (b[3] - b[1]);
    double xs[4] = {b[0], b[2], u, u}, ys[4] = {v, v, b[1], b[3]};
    if (!ct->Transform(4, xs, ys)) {
      return Problem{"ElevationOptions::crs", 0, "frame: " + to.name + " cannot hold the extent; use ElevationOptions::crs utm or cassini"};
    }
    in.west = std::max(in.west, xs[0]);
    in.east = std::min(in.east, xs[1]);
    in.south = std::max(in.south, ys[2]);
    in.north = std::min(in.north, ys[3]);
  }
  if (!(in.west < in.east && in.south < in.north)) return Problem{"ElevationOptions::crs", 0, "frame: the extent is empty in " + to.name};
  return in;
}

/// Union of the sources' post-centre boxes in their own (shared) CRS.
Box sourceBox(const std::vector<Source>& sources) {
  Box u = {INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (const auto& s : sources) {
    const auto& g = s.geo;
    const double x0 = g[0] + 0.5 * g[1], x1 = g[0] + (s.width - 0.5) * g[1];
    const double y0 = g[3] + 0.5 * g[5], y1 = g[3] + (s.height - 0.5) * g[5];
    u = {std::min({u[0], x0, x1}), std::min({u[1], y0, y1}), std::max({u[2], x0, x1}), std::max({u[3], y0, y1})};
  }
  return u;
}

Result<Inner> targetRectangle(const ElevationOptions& o, const std::vector<Source>& sources, const TargetCrs& crs) {
  OGRSpatialReference srcSrs;
  if (srcSrs.importFromWkt(sources.front().srsWkt.c_str()) != OGRERR_NONE) {
    return Problem{sources.front().path, 0, "frame: cannot parse the source CRS"};
  }
  for (const auto& s : sources) {
    OGRSpatialReference other;
    other.importFromWkt(s.srsWkt.c_str());
    if (!other.IsSame(&srcSrs)) {
      return Problem{s.path, 0, "frame: this source's CRS differs from " + sources.front().path +
                                    "'s; mosaics need one CRS (reproject with gdalwarp first)"};
    }
  }
  auto in = innerRectangle(sourceBox(sources), srcSrs, crs);
  if (!in) return in.problems();
  if (o.extent) {
    OGRSpatialReference wgs;
    wgs.SetWellKnownGeogCS("WGS84");
    auto crop = innerRectangle(*o.extent, wgs, crs);
    if (!crop) return crop.problems();
    in->intersect(crop.value());
    if (!(in->west < in->east && in->south < in->north)) {
      return Problem{"ElevationOptions::extent", 0, "frame: ElevationOptions::extent does not overlap the sources"};
    }
  }
  return in;
}

/// The grid's posts at spacing s over the rectangle, snapped to whole
/// multiples of s as planFrame snaps them (so databases of one area align).
struct Posts {
  double west = 0, north = 0, east = 0, south = 0, nx = 0, nz = 0;
};
Posts postsAt(const Inner& in, double s) {
  Posts p;
  p.west = std::ceil(in.west / s - 1e-9) * s;
  p.north = std::floor(in.north / s + 1e-9) * s;
  p.east = std::floor(in.east / s + 1e-9) * s;
  p.south = std::ceil(in.south / s - 1e-9) * s;
  p.nx = std::round((p.east - p.west) / s) + 1;
  p.nz = std::round((p.north - p.south) / s) + 1;
  return p;
}

constexpr double kMaxPosts = 4.0e9;  ///< posts in all (16 GB of elevations alone)

bool fits(const Posts& p) {
  return p.nx <= grid::kMaxPostsPerAxis && p.nz <= grid::kMaxPostsPerAxis && p.nx * p.nz <= kMaxPosts;
}

/// The smallest spacing in whole centimetres at which the posts fit.
double smallestFittingSpacing(const Inner& in) {
  const double w = in.east - in.west, h = in.north - in.south;
  const double bound = std::max({w / (grid::kMaxPostsPerAxis - 1.0), h / (grid::kMaxPostsPerAxis - 1.0),
                                 std::sqrt(w * h / kMaxPosts), 0.01});
  double s = std::ceil(bound * 100.0) / 100.0;
  for (int k = 0; k < 1000 && !fits(postsAt(in, s)); ++k) s += 0.01;
  return s;
}

}  // namespace

Result<Frame> planFrame(const ElevationOptions& o, const std::vector<Source>& sources) {
  auto box = lonLatExtent(o, sources);
  if (!box) return box.problems();
  const Box& b = box.value();
  const double cLon = 0.5 * (b[0] + b[2]), cLat = 0.5 * (b[1] + b[3]);
  auto crs = resolveCrs(o.crs, cLon, cLat);
  if (!crs) return crs.problems();
  auto t = geodesy::Projection::create(crs->wkt, "ElevationOptions::crs");
  if (!t) return t.problems();
  if (auto ok = checkScale(t.value(), b, crs->name, o.maxScaleError); !ok) return ok.problems();
  auto inner = targetRectangle(o, sources, crs.value());
  if (!inner) return inner.problems();

  Frame f;
  f.crs = crs.value();
  f.spacing = o.spacing > 0 ? o.spacing : std::max(0.01, std::round(nativeSpacingMetres(sources) * 100) / 100);
  if (!(f.spacing > 0) || !std::isfinite(f.spacing)) return Problem{"ElevationOptions::spacing", 0, "frame: spacing must be positive"};
  const double s = f.spacing;
  const Posts posts = postsAt(inner.value(), s);
  f.originEasting = posts.west;
  f.originNorthing = posts.north;
  const double east = posts.east, south = posts.south, nx = posts.nx, nz = posts.nz;
  if (nx < 2 || nz < 2) {
    return Problem{"ElevationOptions::spacing", 0, "frame: the extent holds fewer than 2 x 2 posts at " + std::to_string(s) +
                                       " m spacing; use a smaller ElevationOptions::spacing"};
  }
  if (!fits(posts)) {
    const double fitting = smallestFittingSpacing(inner.value());
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "frame: %.0f x %.0f posts at %g m spacing is too many: the limit is %u posts along each "
                  "axis and %.0f in all; the smallest spacing that fits this extent is %.2f m (use ElevationOptions::spacing "
                  "%.2f or more, or a smaller ElevationOptions::extent)",
                  nx, nz, s, grid::kMaxPostsPerAxis, kMaxPosts, fitting, fitting);
    return Problem{"ElevationOptions::spacing", 0, buf};
  }
  f.postsX = static_cast<std::uint32_t>(nx);
  f.postsZ = static_cast<std::uint32_t>(nz);
  const double xs[4] = {f.originEasting, east, east, f.originEasting};
  const double ys[4] = {f.originNorthing, f.originNorthing, south, south};
  for (int k = 0; k < 4; ++k) {
    const auto corner = t->toLonLat({xs[k], ys[k]});
    if (!corner) return Problem{"ElevationOptions::crs", 0, "frame: a corner of the grid does not transform back to lon/lat"};
    f.cornersLonLat[k] = {corner->lon, corner->lat};
  }
  return f;
}

}  // namespace sandtable::convert::detail
