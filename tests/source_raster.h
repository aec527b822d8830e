#pragma once
// A source raster read whole through GDAL, with bilinear interpolation
// between its posts: the reference the converted grid is compared against.
#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <gdal_priv.h>

namespace sandtable::test {

class SourceRaster {
 public:
  explicit SourceRaster(const std::string& path) {
    GDALAllRegister();
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    if (!ds) return;
    ds->GetGeoTransform(geo_.data());
    w_ = ds->GetRasterXSize();
    h_ = ds->GetRasterYSize();
    auto* band = ds->GetRasterBand(1);
    int has = 0;
    nodata_ = band->GetNoDataValue(&has);
    hasNoData_ = has != 0;
    v_.resize(std::size_t(w_) * h_);
    ok_ = band->RasterIO(GF_Read, 0, 0, w_, h_, v_.data(), w_, h_, GDT_Float64, 0, 0) == CE_None;
  }
  bool ok() const { return ok_; }
  const std::array<double, 6>& geo() const { return geo_; }
  int width() const { return w_; }
  int height() const { return h_; }
  /// Post (column c, row r); nullopt for a void.
  std::optional<double> post(int c, int r) const {
    const double v = v_[std::size_t(r) * w_ + c];
    if ((hasNoData_ && v == nodata_) || v < -12000 || v > 9000) return std::nullopt;
    return v;
  }
  /// Source-CRS coordinates of post (c, r) (post centres).
  std::array<double, 2> postXY(int c, int r) const {
    return {geo_[0] + (c + 0.5) * geo_[1], geo_[3] + (r + 0.5) * geo_[5]};
  }

  /// Bilinear value at geographic (or source-CRS) coordinates; nullopt if
  /// outside or if any of the four posts is a void. `minValue` excludes
  /// posts at or below it (e.g. 0 to stay on land).
  std::optional<double> bilinear(double x, double y, double minValue = -1e9) const {
    const double c = (x - geo_[0]) / geo_[1] - 0.5, r = (y - geo_[3]) / geo_[5] - 0.5;
    const int c0 = static_cast<int>(std::floor(c)), r0 = static_cast<int>(std::floor(r));
    if (c0 < 0 || r0 < 0 || c0 + 1 >= w_ || r0 + 1 >= h_) return std::nullopt;
    const double fx = c - c0, fy = r - r0;
    double q[4];
    const int idx[4][2] = {{c0, r0}, {c0 + 1, r0}, {c0, r0 + 1}, {c0 + 1, r0 + 1}};
    for (int k = 0; k < 4; ++k) {
      q[k] = v_[std::size_t(idx[k][1]) * w_ + idx[k][0]];
      if ((hasNoData_ && q[k] == nodata_) || q[k] < -12000 || q[k] > 9000 || q[k] <= minValue) return std::nullopt;
    }
    const double top = q[0] + fx * (q[1] - q[0]), bot = q[2] + fx * (q[3] - q[2]);
    return top + fy * (bot - top);
  }

 private:
  bool ok_ = false;
  std::array<double, 6> geo_{};
  int w_ = 0, h_ = 0;
  double nodata_ = 0;
  bool hasNoData_ = false;
  std::vector<double> v_;
};

}  // namespace sandtable::test
