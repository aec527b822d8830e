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
#include "sandtable/formats/height_field.h"
#include "sandtable/paging/pager.h"
#include "sandtable/paging/view_triangle.h"
#include "sandtable/scene/dynamic.h"

namespace sandtable::scene {

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

/// One terrain vertex: position relative to the buffer origin, unit normal,
/// and 1 where the post's grid material is water (else 0).
struct TerrainVertex {
  float x, y, z;
  float nx, ny, nz;
  float water;
};
static_assert(sizeof(TerrainVertex) == 28, "vertex layout is shared with the shader");

/// One run of quadtree nodes of one module drawn at one level: Morton
/// indices [first, last) of that level's node grid (lod.h), morphed by
/// `morph` towards the next coarser level (0 = this level, 1 = the next).
struct NodeDraw {
  std::uint32_t module = 0;  ///< index into DisplayBuffer::modules
  std::uint32_t level = 0;
  std::uint32_t first = 0, last = 0;
  float morph = 0;
};

/// One load module to draw (module mode) and the pager's read guard that
/// keeps its levels alive until the render thread has used them. The
/// render thread keys its GPU buffers by (kx, kz, level, generation).
struct ModuleDraw {
  std::uint32_t kx = 0, kz = 0;
  double distance = 0;  ///< nearest point of the module, metres (3-D)
  std::uint64_t triangles = 0;
  paging::ResidentRef ref;
};

/// What scene selection saw, for the panel and stats.json.
struct SceneStats {
  std::uint32_t modulesSelected = 0;  ///< under the view triangle, within range
  std::uint32_t modulesDrawn = 0;
  std::uint32_t modulesCulled = 0;    ///< wholly outside the view volume (vertical extent too)
  std::uint32_t nodesCulled = 0;      ///< quadtree nodes outside the view volume
  std::uint32_t modulesMissing = 0;   ///< not resident yet: nothing drawn there
  std::uint32_t nodesDrawn = 0;       ///< quadtree nodes drawn
  std::uint32_t nodesCoarser = 0;     ///< nodes drawn coarser than wanted (finer level not in yet)
  std::vector<std::uint32_t> levelCounts;  ///< quadtree nodes drawn per level
  double maxErrorPx = 0;              ///< largest projected error bound drawn (any mode)
  std::uint32_t residentInWindow = 0; ///< pager: modules resident in its window
  std::uint32_t windowModules = 0;
  std::uint32_t pagerQueue = 0;       ///< pager: loads queued or in flight, all loaders
  std::uint32_t nodesPlaceholder = 0; ///< nodes drawn from placeholder modules (also coarser)
  /// Pager counters since open: placeholders published, modules refused and
  /// fine levels left out for the memory budget; the pool's bytes now.
  std::uint64_t pagerPlaceholders = 0, pagerBudgetRefusals = 0, pagerTrimmedLevels = 0;
  std::uint64_t pagerPoolBytes = 0;
};

struct DisplayBuffer {
  std::uint64_t frame = 0;
  Camera camera;
  /// Vertices store X and Z relative to this point (the eye) so that float
  /// keeps centimetres even hundreds of kilometres from the grid origin.
  double originX = 0, originZ = 0;
  paging::ViewTriangle triangle;
  std::vector<paging::RowSpan> spans;               ///< one triangle strip each
  std::vector<TerrainVertex> vertices;      ///< all strips back to back
  std::vector<std::int32_t> firsts, counts; ///< glMultiDrawArrays arguments
  std::uint64_t triangles = 0;
  double cpuMs = 0;  ///< selection + vertex build
  // Module mode (empty in grid mesh mode).
  bool moduleMode = false;
  double moduleSize = 0;            ///< metres along a module edge
  std::uint32_t nodeSquares = 4;    ///< squares along a quadtree node at every level (lod.h)
  std::vector<ModuleDraw> modules;  ///< nearest first
  std::vector<NodeDraw> nodes;      ///< grouped by module, in module order
  paging::ModuleRect pagerWindow;           ///< GPU copies outside it are released
  SceneStats scene;
  /// Entities, trails, flashes and changed static objects (dynamic.h),
  /// filled by the application after the selection; empty without one.
  DynamicScene dynamic;
};

/// Mesh mode. Builds the view triangle for `cam` on the posts of `g` (the
/// grid file or a changing field, read as they are now), selects the grid squares
/// and writes one strip per row span (TerrainVertex::water from the grid
/// material: water when listed in `waterMaterials`, default {1}): v(i,j), v(i,j+1), v(i+1,j), ... so
/// each square splits along its south-west to north-east diagonal exactly
/// as Terrain::sampleXZ assumes. Reuses `out`'s memory.
void fillDisplayBuffer(const grid::HeightField& g, const Camera& cam, std::uint64_t frame,
                       DisplayBuffer& out, const std::vector<std::uint8_t>& waterMaterials = {1});

/// The view triangle `fillDisplayBuffer` uses for a camera.
paging::ViewTriangle viewTriangleFor(const Camera& cam, double spacing);

}  // namespace sandtable::scene
