// How well the built grid's drawn triangles reproduce the source posts:
// the RMSE and the worst error every build reports.
#include <algorithm>
#include <cmath>
#include <memory>

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "elevation_internal.h"
#include "sandtable/geodesy/geodesy.h"
#include "sandtable/formats/terrain_rule.h"

namespace sandtable::convert::detail {
namespace {

/// The source post box (column, row; inclusive) that the grid covers.
bool sourceBox(const Frame& f, OGRCoordinateTransformation& toSource, const std::array<double, 6>& geo, int W,
               int H, int box[4]) {
  std::vector<double> x, y;
  auto add = [&](std::uint32_t i, std::uint32_t j) {
    x.push_back(f.originEasting + i * f.spacing);
    y.push_back(f.originNorthing - j * f.spacing);
  };
  for (std::uint32_t i = 0; i < f.postsX; i += 8) add(i, 0), add(i, f.postsZ - 1);
  for (std::uint32_t j = 0; j < f.postsZ; j += 8) add(0, j), add(f.postsX - 1, j);
  add(f.postsX - 1, f.postsZ - 1);
  if (!toSource.Transform(static_cast<int>(x.size()), x.data(), y.data())) return false;
  double c0 = INFINITY, c1 = -INFINITY, r0 = INFINITY, r1 = -INFINITY;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double c = (x[k] - geo[0]) / geo[1] - 0.5, r = (y[k] - geo[3]) / geo[5] - 0.5;
    c0 = std::min(c0, c), c1 = std::max(c1, c), r0 = std::min(r0, r), r1 = std::max(r1, r);
  }
  if (!std::isfinite(c0 + c1 + r0 + r1)) return false;
  box[0] = std::clamp(static_cast<int>(std::floor(c0)), 0, W - 1);
  box[1] = std::clamp(static_cast<int>(std::floor(r0)), 0, H - 1);
  box[2] = std::clamp(static_cast<int>(std::ceil(c1)), 0, W - 1);
  box[3] = std::clamp(static_cast<int>(std::ceil(r1)), 0, H - 1);
  return true;
}

}  // namespace

Status AccuracySampler::prepare(const std::string& vrtPath, const Frame& f) {
  *this = {};
  w_ = f.postsX, h_ = f.postsZ;
  wkt_ = f.crs.wkt;
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(vrtPath.c_str(), GDAL_OF_RASTER));
  if (!ds || !ds->GetSpatialRef()) return stageError("accuracy: cannot open the mosaic");
  std::array<double, 6> geo{};
  ds->GetGeoTransform(geo.data());
  OGRSpatialReference src(*ds->GetSpatialRef()), dst;
  dst.importFromWkt(f.crs.wkt.c_str());
  for (auto* s : {&src, &dst}) s->SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> toSource(OGRCreateCoordinateTransformation(&dst, &src));
  std::unique_ptr<OGRCoordinateTransformation> toTarget(OGRCreateCoordinateTransformation(&src, &dst));
  if (!toSource || !toTarget) return stageError("accuracy: PROJ cannot transform between the mosaic and the grid");
  GDALRasterBand& band = *ds->GetRasterBand(1);
  int box[4] = {0, 0, -1, -1};
  if (!sourceBox(f, *toSource, geo, band.GetXSize(), band.GetYSize(), box)) return stageError("accuracy: PROJ failed");
  const double area = double(box[2] - box[0] + 1) * double(box[3] - box[1] + 1);
  const int step = std::max(1, static_cast<int>(std::floor(std::sqrt(area / kAccuracyPosts))));
  int hasNoData = 0;
  const float nd = static_cast<float>(band.GetNoDataValue(&hasNoData));
  // Row by row, so compressed sources (.hgt.zip) are read forwards.
  std::vector<double> x, y, z;
  for (int r = box[1]; r <= box[3]; r += step) {
    for (int c = box[0]; c <= box[2]; c += step) {
      float v = 0;
      if (band.RasterIO(GF_Read, c, r, 1, 1, &v, 1, 1, GDT_Float32, 0, 0) != CE_None) {
        return stageError("accuracy: cannot read the sources");
      }
      if (std::isnan(validOrNan(v, hasNoData != 0, nd))) continue;
      x.push_back(geo[0] + (c + 0.5) * geo[1] + (r + 0.5) * geo[2]);
      y.push_back(geo[3] + (c + 0.5) * geo[4] + (r + 0.5) * geo[5]);
      z.push_back(v);
    }
  }
  if (x.empty()) return {};
  if (!toTarget->Transform(static_cast<int>(x.size()), x.data(), y.data())) return stageError("accuracy: PROJ failed");
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double u = (x[k] - f.originEasting) / f.spacing, v = (f.originNorthing - y[k]) / f.spacing;
    if (!(u >= 0 && v >= 0 && u <= f.postsX - 1 && v <= f.postsZ - 1)) continue;
    posts_.push_back({u, v, z[k], x[k], y[k]});
  }
  byRow_.resize(posts_.size());
  for (std::size_t k = 0; k < byRow_.size(); ++k) byRow_[k] = k;
  std::stable_sort(byRow_.begin(), byRow_.end(), [&](std::size_t a, std::size_t b) {
    return std::min(std::floor(posts_[a].v), double(h_ - 2)) < std::min(std::floor(posts_[b].v), double(h_ - 2));
  });
  err_.assign(posts_.size(), NAN);
  return {};
}

double AccuracySampler::error(std::uint32_t i, double fx, double fz, const float* r0, const float* r1,
                              const Post& p) const {
  const double nw = r0[i], ne = r0[i + 1], sw = r1[i], se = r1[i + 1];
  return terrain::planeHeight(fx, fz, nw, ne, sw, se) - p.z;
}

SourceAccuracy AccuracySampler::finish() const {
  SourceAccuracy out;
  double sum = 0, sum2 = 0, worstE = 0, worstN = 0;
  for (std::size_t k = 0; k < posts_.size(); ++k) {
    const double e = err_[k];
    if (std::isnan(e)) continue;  // no band covered it (cannot happen when every row was added)
    sum += e;
    sum2 += e * e;
    ++out.samples;
    if (std::fabs(e) >= out.maxAbs) {
      out.maxAbs = std::fabs(e);
      out.worstError = e;
      out.worstSource = posts_[k].z;
      worstE = posts_[k].e, worstN = posts_[k].n;
    }
  }
  if (out.samples == 0) return out;
  out.mean = sum / double(out.samples);
  out.rmse = std::sqrt(sum2 / double(out.samples));
  if (const auto geo = geodesy::Projection::create(wkt_)) {
    if (const auto ll = geo->toLonLat({worstE, worstN})) out.worstLonLat = {ll->lon, ll->lat};
  }
  return out;
}

Result<SourceAccuracy> measureAccuracy(const std::string& vrtPath, const Frame& f, const std::vector<float>& grid) {
  AccuracySampler s;
  if (Status st = s.prepare(vrtPath, f); !st) return st.problems();
  s.add(0, f.postsZ, [&](std::uint32_t j) { return grid.data() + std::size_t(std::min(j, f.postsZ - 1)) * f.postsX; });
  return s.finish();
}

}  // namespace sandtable::convert::detail
