#pragma once
// The elevation grid as a GeoTIFF for GIS tools (gdalinfo, gdal_calc.py,
// QGIS): `sandtable export DB --grid` (docs/EXPORT.md, "The elevation grid").
// Any HeightField is written, the grid file's or an edited one, so the
// ground before and after a battle can be compared in those tools.
//
// One pixel per post: pixel (i, j) is post (i, j), easting
// originEasting + i * spacing and northing originNorthing - j * spacing, its
// elevation as the field's float, bit for bit. The file says
// AREA_OR_POINT=Point (GeoTIFF PixelIsPoint: a value is the height at a
// point, not the mean over a cell), so GDAL's geotransform, which always
// names the corner of pixel (0, 0), starts half a spacing west and north of
// the north-west post.
//
// Thread safety: one call per output path at a time; the field is read
// from the calling thread only.
#include <cstdint>
#include <string>

#include "sandtable/base/result.h"
#include "sandtable/base/work.h"
#include "sandtable/formats/height_field.h"

namespace sandtable::convert {

/// What was written.
struct GridExportReport {
  std::string path;
  std::uint32_t postsX = 0, postsZ = 0;
  std::uint64_t posts = 0;  ///< postsX * postsZ
  std::uint64_t bytes = 0;  ///< the file's size
};

/// The message of the problem a cancelled export returns (nothing written).
inline constexpr const char* kGridExportCancelled = "export: cancelled before the end; nothing was written";

/// Writes `field` to `path` as a single-band Float32 GeoTIFF in the CRS
/// `crsWkt` (the manifest's WKT): GTiff, 256 x 256 tiles, DEFLATE with the
/// floating-point predictor (lossless), no NoData value, band unit "m",
/// AREA_OR_POINT=Point. Written to a temporary file beside `path`, synced,
/// then renamed over it: a reader sees the old file or the whole new one,
/// never a part. `work` reports the fraction of rows written (stage
/// "writing grid") and may cancel between bands of 256 rows: the temporary
/// file is removed and the problem is kGridExportCancelled. Problems name
/// `path` (a CRS GDAL does not read, a directory that cannot be written, a
/// full disk).
Result<GridExportReport> exportGridGeoTiff(const grid::HeightField& field, const std::string& crsWkt,
                                           const std::string& path, const Work& work = {});

}  // namespace sandtable::convert
