#pragma once
// `sandtable validate`: every check of formats/ (validateDatabase) plus the
// ones that need PROJ, which formats/ does not link: the manifest's CRS and
// its lon/lat corners (docs/VALIDATE.md, "Georeference").
#include <string>
#include <vector>

#include "sandtable/formats/manifest.h"
#include "sandtable/base/result.h"
#include "sandtable/base/work.h"

namespace sandtable::convert {

/// How far, in metres on the ground, a corners_lonlat entry may lie from
/// the grid's corner post transformed through crs.wkt. The builder writes
/// that very transform; the slack covers another PROJ version's rounding.
inline constexpr double kCornerToleranceMetres = 0.01;

/// The manifest's georeference, as sample, fly and export --lonlat use it:
/// crs.wkt must parse, be a projected CRS in metres, and transform to and
/// from WGS 84; each of corners_lonlat (NW, NE, SE, SW) must be its grid
/// corner post transformed to lon/lat. Problems name `manifestPath`, offset
/// 0, and the key. Ok when sound.
Status checkGeoreference(const manifest::Manifest& m, const std::string& manifestPath);

/// validateDatabase(dir, work), then checkGeoreference when the manifest
/// reads and the check was not cancelled.
Status validateDatabaseWithCrs(const std::string& dir, const Work& work = {});

}  // namespace sandtable::convert
