// The elevation grid as a GeoTIFF (grid_export.h, docs/EXPORT.md).
#include "sandtable/converters/grid_export.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <vector>

#include <cpl_conv.h>
#include <cpl_error.h>
#include <gdal.h>
#include <ogr_srs_api.h>

#include "sandtable/converters/crs.h"

namespace sandtable::convert {
namespace {

namespace fs = std::filesystem;

/// Rows per RasterIO call: one row of tiles, so GDAL compresses whole
/// tiles and memory stays at one band however big the grid.
constexpr std::uint32_t kBandRows = 256;

/// The temporary file until it is renamed into place: closed and removed
/// on every way out but success.
class TempTiff {
 public:
  explicit TempTiff(std::string path) : path_(std::move(path)) {}
  ~TempTiff() {
    if (ds_) GDALClose(ds_);
    if (!kept_) remove();
  }
  TempTiff(const TempTiff&) = delete;
  TempTiff& operator=(const TempTiff&) = delete;

  const std::string& path() const { return path_; }
  GDALDatasetH& dataset() { return ds_; }
  /// Closes the dataset, writing what GDAL still holds; false when GDAL
  /// reported a failure while doing so (GDALClose returns nothing in 3.6).
  bool close() {
    CPLErrorReset();
    GDALClose(ds_);
    ds_ = nullptr;
    return CPLGetLastErrorType() != CE_Failure && CPLGetLastErrorType() != CE_Fatal;
  }
  void keep() { kept_ = true; }

 private:
  void remove() const {
    std::error_code ec;
    fs::remove(path_, ec);
    // GDAL's side file, should it ever write one for the temporary name.
    fs::remove(path_ + ".aux.xml", ec);
  }
  std::string path_;
  GDALDatasetH ds_ = nullptr;
  bool kept_ = false;
};

/// fsync of a closed file: the rename must not publish data still in the
/// page cache only.
bool syncFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  return ::close(fd) == 0 && ok;
}

/// GDAL's geotransform of the grid: pixel (i, j)'s centre at post (i, j).
/// GDAL's model names the corner of pixel (0, 0) whatever AREA_OR_POINT
/// says, so the transform starts half a spacing west and north of the
/// north-west post; the GTiff driver stores the post itself as the
/// PixelIsPoint tie point.
void geoTransform(const grid::PostLayout& l, double gt[6]) {
  const double half = 0.5 * l.spacing;
  gt[0] = l.originEasting - half;
  gt[1] = l.spacing;
  gt[2] = 0;
  gt[3] = l.originNorthing + half;
  gt[4] = 0;
  gt[5] = -l.spacing;
}

}  // namespace

Result<GridExportReport> exportGridGeoTiff(const grid::HeightField& field, const std::string& crsWkt,
                                           const std::string& path, const Work& work) {
  auto fail = [&](const std::string& m) { return Result<GridExportReport>(Problem{path, 0, "export: " + m}); };
  initGdal();
  const grid::PostLayout& l = field.layout();
  if (l.postsX < 2 || l.postsZ < 2 || l.postsX > INT_MAX || l.postsZ > INT_MAX) {
    return fail("the grid has " + std::to_string(l.postsX) + " x " + std::to_string(l.postsZ) +
                " posts; a GeoTIFF takes 2 to " + std::to_string(INT_MAX) + " each way");
  }
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  const bool crsReads = OSRSetFromUserInput(srs, crsWkt.c_str()) == OGRERR_NONE;
  if (!crsReads) {
    OSRDestroySpatialReference(srs);
    return fail("the database's CRS does not read in GDAL (" + lastGdalError() + "); run sandtable validate");
  }

  TempTiff tmp(path + ".tmp." + std::to_string(::getpid()));
  const char* opts[] = {"TILED=YES",         "BLOCKXSIZE=256", "BLOCKYSIZE=256", "COMPRESS=DEFLATE",
                        "PREDICTOR=3",       "BIGTIFF=IF_SAFER", nullptr};
  GDALDriverH gtiff = GDALGetDriverByName("GTiff");
  tmp.dataset() = gtiff ? GDALCreate(gtiff, tmp.path().c_str(), int(l.postsX), int(l.postsZ), 1, GDT_Float32,
                                     const_cast<char**>(opts))
                        : nullptr;
  if (!tmp.dataset()) {
    OSRDestroySpatialReference(srs);
    return fail("cannot create " + tmp.path() + ": " + lastGdalError());
  }
  GDALDatasetH ds = tmp.dataset();
  // Before the geotransform: the driver writes the tie point for the
  // raster type the metadata names.
  GDALSetMetadataItem(ds, GDALMD_AREA_OR_POINT, GDALMD_AOP_POINT, nullptr);
  double gt[6];
  geoTransform(l, gt);
  const bool georeferenced = GDALSetGeoTransform(ds, gt) == CE_None && GDALSetSpatialRef(ds, srs) == CE_None;
  OSRDestroySpatialReference(srs);
  if (!georeferenced) return fail("cannot georeference " + tmp.path() + ": " + lastGdalError());
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  GDALSetRasterUnitType(band, "m");
  GDALSetDescription(band, "elevation");

  std::vector<float> rows(std::size_t(l.postsX) * kBandRows);
  for (std::uint32_t j0 = 0; j0 < l.postsZ; j0 += kBandRows) {
    if (work.cancelled()) return Result<GridExportReport>(Problem{path, 0, kGridExportCancelled});
    const std::uint32_t n = std::min(kBandRows, l.postsZ - j0);
    for (std::uint32_t r = 0; r < n; ++r) {
      float* row = rows.data() + std::size_t(r) * l.postsX;
      for (std::uint32_t i = 0; i < l.postsX; ++i) row[i] = field.elevation(i, j0 + r);
    }
    CPLErr err = GDALRasterIO(band, GF_Write, 0, int(j0), int(l.postsX), int(n), rows.data(), int(l.postsX), int(n),
                              GDT_Float32, 0, 0);
    // Write this row of tiles out now: memory stays at one band.
    if (err == CE_None) err = GDALFlushRasterCache(band);
    if (err != CE_None) return fail("cannot write " + tmp.path() + ": " + lastGdalError());
    work.report(double(j0 + n) / double(l.postsZ), "writing grid");
  }
  if (!tmp.close()) return fail("cannot finish " + tmp.path() + ": " + lastGdalError());
  if (!syncFile(tmp.path())) return fail("cannot flush " + tmp.path() + ": " + std::strerror(errno));
  if (::rename(tmp.path().c_str(), path.c_str()) != 0) {
    return fail("cannot rename " + tmp.path() + " to " + path + ": " + std::strerror(errno));
  }
  tmp.keep();
  GridExportReport rep;
  rep.path = path;
  rep.postsX = l.postsX;
  rep.postsZ = l.postsZ;
  rep.posts = std::uint64_t(l.postsX) * l.postsZ;
  std::error_code ec;
  rep.bytes = fs::file_size(path, ec);
  return rep;
}

}  // namespace sandtable::convert
