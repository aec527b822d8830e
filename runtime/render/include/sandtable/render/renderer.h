#pragma once
// The renderer: draws a DisplayBuffer with OpenGL 4.5 core through EGL,
// headless (an offscreen target, read back only when asked) or into a
// window's EGL surface (present.h: shown by a GPU blit and a swap).
//
// Each frame runs the passes of kRenderPasses into the frame's target
// (docs/VIEWER.md, "Passes"):
//   sky      a full-screen triangle shaded from the background colour at
//            the horizon to a deeper tone at the zenith;
//   terrain  the grid mesh's strips from a streamed vertex buffer with one
//            glMultiDrawArrays, or the load modules' skin and underlay;
//   decals   the modules' decal priorities over their skin (and their own
//            object polygons); nothing in mesh mode;
//   models   the modules' static objects drawn with the icons of
//            RenderSettings::icons (docs/VIEWER.md, "Objects"), the
//            buffer's entities, munition trails and detonation flashes
//            (DisplayBuffer::dynamic, "Entities"), then the ModelsPass
//            given to setModelsPass(), if any;
//   resolve  a multisampled target into the single-sampled one;
//   hud      the Overlay (overlay.h): darkened boxes, then the layer
//            blended over them. Height frames skip it.
// Both terrain modes colour the ground by the same rules (docs/VIEWER.md,
// "Colours"): culture class colours where culture covers it (modules),
// water where the grid's material is water, else a fixed elevation tint;
// lit by a fixed sun from smooth per-post normals and fogged towards the
// background colour, full fog at the view distance. Shading::flat gives
// the seed's look instead.
//
// Thread safety: a Renderer owns a GL context that is current on the thread
// that created it. Create, use and destroy it on that one thread (the render
// thread); it reads DisplayBuffers that other threads filled.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sandtable/formats/grid.h"
#include "sandtable/formats/height_field.h"
#include "sandtable/formats/icon_pack.h"
#include "sandtable/base/result.h"
#include "sandtable/scene/display_buffer.h"
#include "sandtable/render/image.h"
#include "sandtable/render/overlay.h"
#include "sandtable/render/present.h"

namespace sandtable::render {

/// Problem::file of every failure to open the headless context, so callers
/// can tell "no GL here" from other errors.
inline constexpr const char* kGlContextProblem = "EGL";

/// Colours of one material class (materials.h): upper and lower grid
/// triangle, as the seed shades the two halves of a square differently
/// (Shading::flat; smooth shading uses their mean for both).
struct MaterialColour {
  Rgb upper{0x6E, 0x8C, 0x46}, lower{0x64, 0x82, 0x40};
  /// A road: drawn with the road texture (edges, grain) over its colour.
  bool road = false;
  /// With the texture's white markings (edge lines, dashed centre line).
  bool markings = false;
};

/// How the terrain is lit and coloured.
enum class Shading : std::uint8_t {
  smooth,  ///< per-post normals, one colour per material, elevation tint where no culture
  flat,    ///< the seed's look: a flat normal and the upper/lower colour per triangle
};

/// What a pixel's colour holds.
enum class ColourMode : std::uint8_t {
  natural,  ///< the shaded terrain
  height,   ///< the world height of the terrain under the pixel, as kHeightCode* says
};

/// ColourMode::height: a terrain pixel's R, G, B bytes are the code
/// c = R * 65536 + G * 256 + B, its height h = c / kHeightCodeScale -
/// kHeightCodeOffset metres (quantisation 1/256 m, range -1000 .. 64535 m);
/// c = 0 is no terrain (the clear colour). No sky, fog, panel or map.
inline constexpr double kHeightCodeScale = 256.0;
inline constexpr double kHeightCodeOffset = 1000.0;
/// The height a ColourMode::height frame holds at (x, y); nullopt: no terrain.
std::optional<double> heightAt(const Image& img, std::uint32_t x, std::uint32_t y);

/// RenderSettings::objectFade by default: the last 15 % of the far range.
inline constexpr double kDefaultObjectFade = 0.15;

/// RenderSettings::impostorPixels by default: objects under 16 pixels tall
/// are drawn as sprites.
inline constexpr double kDefaultImpostorPixels = 16.0;

/// RenderSettings::objectThinPixels by default.
inline constexpr double kDefaultObjectThinPixels = 6.0;

/// RenderSettings::uploadBudgetBytes by default: 1 MiB a frame.
inline constexpr std::uint64_t kDefaultUploadBudgetBytes = 1ull << 20;

/// How frames are drawn, as a user chooses it: the renderer's settings and
/// the viewer's RenderOptions (viewer/flight.h) both are these, so the
/// fields and their defaults are written once.
struct DrawChoices {
  /// Multisampling (0 = off, up to 16): resolves thin, far decals to their
  /// coverage instead of letting them shimmer from frame to frame.
  std::uint32_t samples = 0;
  /// Smooth (default) or the seed's flat look (docs/VIEWER.md, "Colours").
  Shading shading = Shading::smooth;
  /// ColourMode::height writes each pixel's world height (kHeightCode*)
  /// with no sky, fog, multisampling, panel or composite.
  ColourMode colour = ColourMode::natural;
  /// Grid material indices that are water (docs/FORMAT.md 4.7).
  std::vector<std::uint8_t> waterMaterials{1};
  /// Module mode: bytes of (module, level) buffers built and uploaded per
  /// frame, so that a jump does not make one long frame; 0: no limit.
  /// Levels over the budget wait for a later frame (at least one goes up
  /// each frame) and are drawn meanwhile from a coarser resident level;
  /// every module's coarsest level goes up at once, whatever the budget.
  std::uint64_t uploadBudgetBytes = kDefaultUploadBudgetBytes;
  /// Objects fade in over this fraction of each icon's far range (its
  /// last switch range, capped at the view distance) instead of popping
  /// in; 0 pops. 0 .. 1.
  double objectFade = kDefaultObjectFade;
  /// Objects and entities take their icon's level of detail by range and
  /// objects vanish past its far range (seed IX.B.1); false: every object
  /// out to the view distance, and every entity out to its far range, is
  /// drawn at full detail (the benchmark's baseline).
  bool objectLod = true;
  /// An object whose projected size (its icon's sprite square: the larger
  /// of its height and its width about its origin, times its scale) is
  /// under this many pixels is drawn as one point sprite textured with its
  /// icon's impostor (docs/VIEWER.md, "Impostors") instead of its mesh;
  /// 0: always meshes. Only with objectLod.
  double impostorPixels = kDefaultImpostorPixels;
  /// Sprites under this many pixels are thinned: each is kept with
  /// probability (pixels / objectThinPixels)^2 times its fog weight, fixed
  /// per object, and the kept ones are drawn up to twice their size for
  /// the first factor (docs/VIEWER.md, "Thinning"); 0: every sprite is drawn.
  double objectThinPixels = kDefaultObjectThinPixels;
};

struct RenderSettings : DrawChoices {
  std::uint32_t width = 1280, height = 720;
  Rgb background{0x87, 0xCE, 0xEB};  ///< sky at the horizon and fog colour
  bool fog = true;
  /// Draw the sky; false leaves the clear colour wherever no terrain is
  /// drawn (the crack tests clear to magenta).
  bool sky = true;
  Rgb clearColour{0xFF, 0x00, 0xFF};
  /// Module mode: colour of each material id (index); ids beyond it get
  /// the default MaterialColour.
  std::vector<MaterialColour> palette;
  /// Module mode: the class of skin no culture covers (the table's
  /// default-area). Smooth shading colours it by the grid: water or tint.
  std::uint16_t uncoveredMaterial = 0;
  /// Module mode, smooth shading: normals and water come from the posts
  /// (the grid file or a changing field) at each module vertex (computed
  /// once per upload). Null: up and no water.
  std::shared_ptr<const grid::HeightField> grid;
  /// The icon database (icons.pack) that the modules' objects and the
  /// DisplayBuffer's entities (scene/dynamic.h) index; null draws neither.
  /// Height frames never draw them.
  std::shared_ptr<const iconpack::Pack> icons;
  /// Module mode: draw the modules' static objects (with `icons`); false
  /// draws only the entities.
  bool staticObjects = true;
};

/// What the render thread did for the last frame (module mode).
struct RenderStats {
  std::uint32_t uploads = 0;        ///< (module, level) buffers built this frame
  std::uint32_t released = 0;       ///< buffers released this frame
  std::uint32_t cachedLevels = 0;   ///< (module, level) buffers held on the GPU
  std::uint64_t gpuBytes = 0;       ///< their vertex and index bytes
  double uploadMs = 0;              ///< building and uploading them
  std::uint64_t uploadBytes = 0;    ///< bytes uploaded this frame
  std::uint32_t uploadsDeferred = 0;  ///< levels left for a later frame by the budget
  std::uint32_t nodesFallback = 0;  ///< node runs drawn coarser: their level not uploaded yet
  std::uint32_t underlayMissing = 0;  ///< cut squares with a lattice post missing (no underlay)
  std::uint32_t draws = 0;          ///< draw commands (one per node range and block)
  std::uint32_t drawCalls = 0;      ///< GL multi-draw calls that issued them
  std::uint64_t trianglesDrawn = 0; ///< triangles in those commands
  /// Static objects (models pass): objects drawn (in range, under the view
  /// triangle, inside the frustum), instances submitted, instanced draws
  /// (one per icon and level with instances), and their triangles.
  std::uint32_t objectsDrawn = 0, objectInstances = 0, objectDraws = 0;
  std::uint64_t objectTriangles = 0;
  /// Of objectsDrawn, those drawn as impostor sprites (not in objectInstances).
  std::uint32_t objectSprites = 0;
  /// Objects in range and view left out by the sprites' thinning.
  std::uint32_t objectsThinned = 0;
  /// Static objects a simulation destroyed (not drawn), and the changed
  /// ones (knocked over, stumps, ruins) drawn by the entity pass.
  std::uint32_t objectsRemoved = 0, objectsChangedDrawn = 0;
  /// The DisplayBuffer's dynamic scene (scene/dynamic.h): entities drawn
  /// (in range and view), their triangles, trails and flashes drawn.
  std::uint32_t entitiesDrawn = 0;
  std::uint64_t entityTriangles = 0;
  std::uint32_t trailsDrawn = 0, flashesDrawn = 0;
};

/// Renderer::measureIndexedGrid: llvmpipe's (or the GPU's) own rate on a
/// plain indexed grid through the module program and draw path.
struct IndexedGridRate {
  std::uint64_t triangles = 0;  ///< per frame
  std::uint32_t draws = 0;      ///< per frame (one per node)
  std::uint32_t frames = 0;
  double p50Ms = 0, p99Ms = 0, meanMs = 0;
  double trianglesPerSecond = 0;  ///< triangles / p50
};

/// The passes of one frame, in order (the class comment says what each draws).
enum class RenderPass : std::uint8_t { sky, terrain, decals, models, resolve, hud };
inline constexpr std::array<RenderPass, 6> kRenderPasses = {RenderPass::sky,    RenderPass::terrain,
                                                            RenderPass::decals, RenderPass::models,
                                                            RenderPass::resolve, RenderPass::hud};
const char* renderPassName(RenderPass p);

/// What a pass is given: the frame's buffer and its view-projection, a
/// column-major 4 x 4 matrix (positions relative to buf.originX / originZ,
/// reversed Z; camera_math.h's viewProjection).
struct PassContext {
  const scene::DisplayBuffer& buf;
  std::array<float, 16> viewProjection;
};

/// The models pass: the hook the next issue (icons and static objects)
/// fills. draw() runs on the render thread after the decals, with the
/// frame's target bound (multisampled when RenderSettings::samples > 0),
/// the terrain's depth buffer, depth test GREATER (reversed Z) and depth
/// writes on; it may change any GL state but must leave the target bound.
class ModelsPass {
 public:
  virtual ~ModelsPass() = default;
  virtual Status draw(const PassContext& frame) = 0;
};

class Renderer {
 public:
  /// A headless renderer, or with `window` one whose context lives on the
  /// window's EGL surface so present() can show frames there. `window`
  /// must outlive the renderer.
  static Result<std::unique_ptr<Renderer>> create(const RenderSettings& s, PresentTarget* window = nullptr);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Runs the passes up to and including resolve for `buf`.
  Status draw(const scene::DisplayBuffer& buf);
  /// The HUD pass: `overlay`'s darkened boxes, then its layer, blended
  /// into the frame drawn last (uploading only its changed boxes). The
  /// overlay must have the frame's size.
  Status drawOverlay(const Overlay& overlay);
  /// Waits until the GPU has finished the frame drawn so far, so that the
  /// caller's clock measures the work (read-back and present wait anyway).
  void finish();
  /// Reads the frame back (top row first). Only for sinks that need the
  /// pixels (PNG, video, screenshot, tests): a windowed frame need not.
  Status readFrame(Image& out);
  /// Shows the frame in the window the renderer was created on, scaled to
  /// fit (letterboxed), by a blit on the GPU, and swaps.
  Status present();

  /// Draws `frames` frames of a plain indexed grid of squares x squares
  /// (one vertex per post, nodes of nodeSquares squares, one draw each)
  /// centred under `camera`, through the module program and draw path,
  /// clear and terrain pass only, each timed to the GPU's finish. The
  /// frame's target is left undefined.
  IndexedGridRate measureIndexedGrid(const scene::Camera& camera, std::uint32_t squares, double spacing,
                                     std::uint32_t nodeSquares, std::uint32_t frames);

  /// Sets the models pass (null: the slot stays empty).
  void setModelsPass(std::unique_ptr<ModelsPass> pass);

  /// Counters of the last draw.
  const RenderStats& stats() const;
  /// Frames read back with readFrame() since create() (not counting its warm-up).
  std::uint64_t framesReadBack() const;

  /// GL_RENDERER, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
  const std::string& glRenderer() const;
  /// GL_VERSION and the EGL platform used.
  std::string description() const;

 private:
  struct Impl;
  explicit Renderer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Whether a headless GL 4.5 core context can be opened here; `why` gets
/// the reason when not. Opens and closes one context.
bool headlessGlAvailable(std::string& why);

/// The CPU half of drawing load modules, for PagerOptions::prepareLevel:
/// on the pager's loader threads it builds each level's vertices, indices
/// and node blocks (morph deltas, grid normals and water, skirts) and
/// raises the skirt feet once every level is written, so the render
/// thread only copies them into the GPU (docs/VIEWER.md, "Module draws").
/// `s` as the Renderer is created with; `nodeSquares` and `moduleSize` as
/// the scene's DisplayBuffer carries them (a level built with other
/// settings is built again on the render thread). Thread-safe: every
/// loader may run it at once; no GL.
std::function<void(paging::ResidentModule& m, std::uint32_t level)> moduleLevelPreparer(const RenderSettings& s,
                                                                                std::uint32_t nodeSquares,
                                                                                double moduleSize);

}  // namespace sandtable::render
