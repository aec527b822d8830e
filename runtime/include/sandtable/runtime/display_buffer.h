#pragma once
// The display buffer (seed Figure 43): what scene selection hands to the
// renderer for one frame. Selection fills it on the CPU with no GL calls;
// the renderer only reads it. With two of them (seed Figure 44) a main
// thread can fill one while the render thread draws the other; the flight
// loop alternates between two already, so only the hand-over is missing.
//
// Thread safety: a DisplayBuffer is plain data. One thread may fill it
// while another reads a different one; never share one buffer unguarded.
#include <cstdint>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/runtime/view_triangle.h"

namespace sandtable::runtime {

/// Where the eye is and how it looks. World frame: X east, Y up, Z south.
struct Camera {
  double x = 0, y = 0, z = 0;  ///< eye, metres (y is elevation)
  double headingDeg = 0;       ///< clockwise from grid north
  double pitchDeg = 0;         ///< negative looks down
  double hfovDeg = 60;
  double aspect = 16.0 / 9.0;  ///< width / height of the image
  double viewDistance = 10000; ///< far plane and full fog, metres
  double nearPlane = 1.0;      ///< seed: a fixed metre from the eye
  double vfovDeg() const;
};

/// One terrain vertex: position relative to the buffer origin, unit normal.
struct TerrainVertex {
  float x, y, z;
  float nx, ny, nz;
};
static_assert(sizeof(TerrainVertex) == 24, "vertex layout is shared with the shader");

struct DisplayBuffer {
  std::uint64_t frame = 0;
  Camera camera;
  /// Vertices store X and Z relative to this point (the eye) so that float
  /// keeps centimetres even hundreds of kilometres from the grid origin.
  double originX = 0, originZ = 0;
  ViewTriangle triangle;
  std::vector<RowSpan> spans;               ///< one triangle strip each
  std::vector<TerrainVertex> vertices;      ///< all strips back to back
  std::vector<std::int32_t> firsts, counts; ///< glMultiDrawArrays arguments
  std::uint64_t triangles = 0;
  double cpuMs = 0;  ///< selection + vertex build
};

/// Builds the view triangle for `cam` on grid `g`, selects the grid squares
/// and writes one strip per row span: v(i,j), v(i,j+1), v(i+1,j), ... so
/// each square splits along its south-west to north-east diagonal exactly
/// as Terrain::sampleXZ assumes. Reuses `out`'s memory.
void fillDisplayBuffer(const grid::GridFile& g, const Camera& cam, std::uint64_t frame,
                       DisplayBuffer& out);

/// The view triangle `fillDisplayBuffer` uses for a camera.
ViewTriangle viewTriangleFor(const Camera& cam, double spacing);

}  // namespace sandtable::runtime
