#include "sandtable/geodesy/geodesy.h"

#include <proj.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <map>
#include <mutex>
#include <utility>

namespace sandtable::geodesy {

namespace {

/// Which operation of a definition a thread caches.
enum class Op { geographicToProjected, projectedToGeographic, geographicToGeocentric, geoid };

/// One PROJ context and the operations built in it, for one thread: PJ
/// objects may only be used from the context's thread.
class ThreadProj {
 public:
  ThreadProj() : ctx_(proj_context_create()) {
    // PROJ would print failed points to stderr; we report them as problems.
    if (ctx_) proj_log_level(ctx_, PJ_LOG_NONE);
  }
  ~ThreadProj() {
    clear();
    proj_context_destroy(ctx_);
  }
  ThreadProj(const ThreadProj&) = delete;
  ThreadProj& operator=(const ThreadProj&) = delete;

  /// The operation (id, op), made by `make` in this thread's context on
  /// first use; null with `error` set when PROJ refuses it.
  PJ* get(std::uint64_t id, Op op, const std::function<PJ*(PJ_CONTEXT*)>& make, std::string& error) {
    const auto key = std::make_pair(id, op);
    if (auto it = ops_.find(key); it != ops_.end()) return it->second;
    if (!ctx_) {
      error = "PROJ cannot create a context";
      return nullptr;
    }
    // Definitions come and go (one per opened database); a bound keeps a
    // long-lived thread's cache small.
    if (ops_.size() >= kMaxOps) clear();
    PJ* pj = make(ctx_);
    if (!pj) {
      error = proj_context_errno_string(ctx_, proj_context_errno(ctx_));
      return nullptr;
    }
    ops_.emplace(key, pj);
    return pj;
  }

 private:
  static constexpr std::size_t kMaxOps = 64;
  void clear() {
    for (auto& [key, pj] : ops_) proj_destroy(pj);
    ops_.clear();
  }
  PJ_CONTEXT* ctx_;
  std::map<std::pair<std::uint64_t, Op>, PJ*> ops_;
};

ThreadProj& threadProj() {
  thread_local ThreadProj t;
  return t;
}

std::uint64_t newId() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

/// crs_to_crs with longitude-first, easting-first axes (as GDAL's
/// traditional GIS order, so results match what the converters had).
PJ* crsToCrs(PJ_CONTEXT* ctx, const char* from, const char* to) {
  PJ* raw = proj_create_crs_to_crs(ctx, from, to, nullptr);
  if (!raw) return nullptr;
  PJ* norm = proj_normalize_for_visualization(ctx, raw);
  proj_destroy(raw);
  return norm;
}

constexpr std::uint64_t kGeocentricId = 0;  // the one WGS 84 geographic -> geocentric operation

PJ* geocentricOp(std::string& error) {
  return threadProj().get(kGeocentricId, Op::geographicToGeocentric,
                          [](PJ_CONTEXT* ctx) { return crsToCrs(ctx, "EPSG:4979", "EPSG:4978"); }, error);
}

bool finite(const PJ_COORD& c, int n) {
  for (int k = 0; k < n; ++k) {
    if (!std::isfinite(c.v[k])) return false;
  }
  return true;
}

Problem problem(const std::string& what, const std::string& message) { return Problem{what, 0, "geodesy: " + message}; }

}  // namespace

// ---------------------------------------------------------------- Projection

struct Projection::Shared {
  std::uint64_t id = 0;
  std::string definition;
  std::string what;

  PJ* operation(Op op, std::string& error) const {
    const bool forward = op == Op::geographicToProjected;
    return threadProj().get(id, op, [&](PJ_CONTEXT* ctx) {
      return forward ? crsToCrs(ctx, "EPSG:4326", definition.c_str()) : crsToCrs(ctx, definition.c_str(), "EPSG:4326");
    }, error);
  }

  /// (a, b) through `op`; a problem when PROJ fails (it gives HUGE_VAL).
  Result<std::pair<double, double>> transform(Op op, double a, double b) const {
    std::string error;
    PJ* pj = operation(op, error);
    if (!pj) return problem(what, "PROJ cannot transform with the CRS: " + error);
    const PJ_COORD out = proj_trans(pj, PJ_FWD, proj_coord(a, b, 0, 0));
    if (!finite(out, 2)) {
      return problem(what, "the point (" + std::to_string(a) + ", " + std::to_string(b) + ") does not transform " +
                               (op == Op::geographicToProjected ? "into the CRS" : "to lon/lat"));
    }
    return std::make_pair(out.xy.x, out.xy.y);
  }

  Status transform(Op op, std::span<double> x, std::span<double> y) const {
    if (x.size() != y.size()) return problem(what, "internal: x and y differ in length");
    std::string error;
    PJ* pj = operation(op, error);
    if (!pj) return problem(what, "PROJ cannot transform with the CRS: " + error);
    proj_trans_generic(pj, PJ_FWD, x.data(), sizeof(double), x.size(), y.data(), sizeof(double), y.size(), nullptr, 0,
                       0, nullptr, 0, 0);
    std::size_t failed = 0;
    for (std::size_t k = 0; k < x.size(); ++k) {
      if (!std::isfinite(x[k]) || !std::isfinite(y[k])) {
        x[k] = y[k] = NAN;
        ++failed;
      }
    }
    if (failed) return problem(what, std::to_string(failed) + " of " + std::to_string(x.size()) + " points do not transform");
    return {};
  }
};

Result<Projection> Projection::create(const std::string& wkt, const std::string& what) {
  auto s = std::make_shared<Shared>();
  s->id = newId();
  s->definition = wkt;
  s->what = what;
  // Checked on the creating thread, so that a bad definition fails here
  // and not at the first transform on some worker.
  PJ_CONTEXT* ctx = proj_context_create();
  if (!ctx) return problem(what, "PROJ cannot create a context");
  proj_log_level(ctx, PJ_LOG_NONE);
  std::string error;
  PJ* crs = proj_create(ctx, wkt.c_str());
  if (!crs) {
    error = "PROJ cannot read the CRS definition (" + std::string(proj_context_errno_string(ctx, proj_context_errno(ctx))) + ")";
  } else if (proj_get_type(crs) != PJ_TYPE_PROJECTED_CRS) {
    error = "the CRS is not a projected CRS";
  }
  proj_destroy(crs);
  proj_context_destroy(ctx);
  if (!error.empty()) return problem(what, error);
  for (Op op : {Op::geographicToProjected, Op::projectedToGeographic}) {
    if (!s->operation(op, error)) return problem(what, "PROJ cannot transform between WGS 84 and the CRS: " + error);
  }
  return Projection(std::move(s));
}

Result<EastNorth> Projection::toProjected(LonLat p) const {
  auto r = s_->transform(Op::geographicToProjected, p.lon, p.lat);
  if (!r) return r.problems();
  return EastNorth{r->first, r->second};
}

Result<LonLat> Projection::toLonLat(EastNorth p) const {
  auto r = s_->transform(Op::projectedToGeographic, p.easting, p.northing);
  if (!r) return r.problems();
  return LonLat{r->first, r->second};
}

Status Projection::toProjected(std::span<double> x, std::span<double> y) const {
  return s_->transform(Op::geographicToProjected, x, y);
}

Status Projection::toLonLat(std::span<double> x, std::span<double> y) const {
  return s_->transform(Op::projectedToGeographic, x, y);
}

const std::string& Projection::definition() const { return s_->definition; }

// ---------------------------------------------------------------- geocentric

Result<Ecef> toEcef(const LonLatHeight& g) {
  std::string error;
  PJ* pj = geocentricOp(error);
  if (!pj) return problem("geodesy", "PROJ cannot transform EPSG:4979 to EPSG:4978: " + error);
  const PJ_COORD out = proj_trans(pj, PJ_FWD, proj_coord(g.lon, g.lat, g.height, 0));
  if (!finite(out, 3)) return problem("geodesy", "lon/lat/height does not transform to geocentric");
  return Ecef{out.xyz.x, out.xyz.y, out.xyz.z};
}

Result<LonLatHeight> fromEcef(const Ecef& e) {
  std::string error;
  PJ* pj = geocentricOp(error);
  if (!pj) return problem("geodesy", "PROJ cannot transform EPSG:4978 to EPSG:4979: " + error);
  const PJ_COORD out = proj_trans(pj, PJ_INV, proj_coord(e.x, e.y, e.z, 0));
  if (!finite(out, 3)) return problem("geodesy", "the geocentric point does not transform to lon/lat/height");
  return LonLatHeight{out.lpz.lam, out.lpz.phi, out.lpz.z};
}

// ---------------------------------------------------------------- DatabaseFrame

namespace {

/// Geoid grids by name, each with one id for the thread caches.
std::uint64_t geoidId(const std::string& grid) {
  static std::mutex m;
  static std::map<std::string, std::uint64_t> ids;
  std::lock_guard lock(m);
  auto [it, added] = ids.try_emplace(grid, 0);
  if (added) it->second = newId();
  return it->second;
}

/// lon/lat (degrees) with z = H -> z = H + N: vgridshift with multiplier +1.
PJ* geoidOp(const std::string& grid, std::string& error) {
  return threadProj().get(geoidId(grid), Op::geoid, [&](PJ_CONTEXT* ctx) {
    const std::string def = "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=vgridshift +grids=" +
                            grid + " +multiplier=1 +step +proj=unitconvert +xy_in=rad +xy_out=deg";
    return proj_create(ctx, def.c_str());
  }, error);
}

}  // namespace

Result<DatabaseFrame> DatabaseFrame::create(const std::string& crsWkt, double originEasting, double originNorthing,
                                            const FrameOptions& options) {
  if (!std::isfinite(originEasting) || !std::isfinite(originNorthing)) {
    return problem("crs", "the frame's origin is not finite");
  }
  auto p = Projection::create(crsWkt);
  if (!p) return p.problems();
  DatabaseFrame f(std::move(p.value()), originEasting, originNorthing, options.geoidGrid);
  if (!f.geoidGrid_.empty()) {
    auto n = f.undulation(LonLat{0, 0});
    if (!n) return problem("FrameOptions::geoidGrid", "the geoid grid \"" + f.geoidGrid_ + "\" cannot be used: " + n.message());
  }
  return f;
}

Result<double> DatabaseFrame::undulation(LonLat p) const {
  if (geoidGrid_.empty()) return 0.0;
  std::string error;
  PJ* pj = geoidOp(geoidGrid_, error);
  if (!pj) return problem("FrameOptions::geoidGrid", "PROJ cannot open the geoid grid: " + error);
  const PJ_COORD out = proj_trans(pj, PJ_FWD, proj_coord(p.lon, p.lat, 0, 0));
  if (!finite(out, 3)) return problem("FrameOptions::geoidGrid", "the geoid grid does not cover this point");
  return out.xyz.z;
}

Result<LonLatHeight> DatabaseFrame::toLonLatHeight(const FramePoint& p) const {
  auto ll = projection_.toLonLat(toProjected(p));
  if (!ll) return ll.problems();
  auto n = undulation(ll.value());
  if (!n) return n.problems();
  return LonLatHeight{ll->lon, ll->lat, p.y + n.value()};
}

Result<FramePoint> DatabaseFrame::fromLonLatHeight(const LonLatHeight& g) const {
  auto en = projection_.toProjected(LonLat{g.lon, g.lat});
  if (!en) return en.problems();
  auto n = undulation(LonLat{g.lon, g.lat});
  if (!n) return n.problems();
  return fromProjected(en.value(), g.height - n.value());
}

Result<Ecef> DatabaseFrame::toEcef(const FramePoint& p) const {
  auto g = toLonLatHeight(p);
  if (!g) return g.problems();
  return geodesy::toEcef(g.value());
}

Result<FramePoint> DatabaseFrame::fromEcef(const Ecef& e) const {
  auto g = geodesy::fromEcef(e);
  if (!g) return g.problems();
  return fromLonLatHeight(g.value());
}

Result<DatabaseFrame::LocalAxes> DatabaseFrame::localAxes(const FramePoint& p) const {
  auto g = toLonLatHeight(p);
  if (!g) return g.problems();
  constexpr double kDegree = 3.14159265358979323846 / 180.0;
  const double lat = g->lat * kDegree, lon = g->lon * kDegree;
  // The ellipsoid's normal at the geodetic latitude, closed form.
  const Ecef up{std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
  // Grid north by a central difference of 1 m along -Z through PROJ: the
  // second-order terms cancel, leaving an angle error far under 1e-6 rad.
  auto ahead = toEcef({p.x, p.y, p.z - 1.0});
  if (!ahead) return ahead.problems();
  auto behind = toEcef({p.x, p.y, p.z + 1.0});
  if (!behind) return behind.problems();
  Ecef n{ahead->x - behind->x, ahead->y - behind->y, ahead->z - behind->z};
  const double along = n.x * up.x + n.y * up.y + n.z * up.z;
  n = {n.x - along * up.x, n.y - along * up.y, n.z - along * up.z};
  const double length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  if (!(length > 0)) {
    return Problem{"", 0, "geodesy: grid north is undefined at frame point (" + std::to_string(p.x) + ", " +
                              std::to_string(p.z) + ") (a pole?)"};
  }
  n = {n.x / length, n.y / length, n.z / length};
  // east = north x up, so that north, east, down is right-handed.
  const Ecef e{n.y * up.z - n.z * up.y, n.z * up.x - n.x * up.z, n.x * up.y - n.y * up.x};
  return LocalAxes{n, e, {-up.x, -up.y, -up.z}};
}

}  // namespace sandtable::geodesy
