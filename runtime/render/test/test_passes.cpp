// The renderer's passes through headless EGL: the HUD pass on the GPU
// gives the very pixels the CPU panel (drawHudPanel on a read-back frame)
// gives, frame after frame as the panel changes; the models slot runs
// after the terrain and before the HUD; frames are read back only when
// asked. Skips without a headless GL context.
#include <gtest/gtest.h>

#include <epoxy/gl.h>

#include <string>
#include <vector>

#include "sandtable/render/hud.h"
#include "sandtable/render/overlay.h"
#include "sandtable/render/renderer.h"
#include "sandtable/testing/require.h"

namespace sandtable::render {
namespace {

constexpr std::uint32_t kW = 320, kH = 200;

/// A flat 2 km square of ground in front of an eye 30 m up, looking a
/// little down: sky above the horizon, fogged ground below it.
scene::DisplayBuffer groundAhead(std::uint32_t frame) {
  scene::DisplayBuffer b;
  b.frame = frame;
  b.camera.y = 30;
  b.camera.pitchDeg = -8;
  b.camera.aspect = double(kW) / double(kH);
  b.camera.viewDistance = 3000;
  b.vertices = {{-1000, 0, -2000, 0, 1, 0, 0}, {-1000, 0, 0, 0, 1, 0, 0}, {1000, 0, -2000, 0, 1, 0, 0},
                {1000, 0, 0, 0, 1, 0, 0}};
  b.firsts = {0};
  b.counts = {4};
  return b;
}

std::unique_ptr<Renderer> makeRenderer(std::uint32_t samples = 0) {
  RenderSettings s;
  s.width = kW;
  s.height = kH;
  s.samples = samples;
  auto r = Renderer::create(s);
  if (!r) return nullptr;
  return std::move(r.value());
}

std::string firstDifference(const Image& got, const Image& want) {
  if (got.width != want.width || got.height != want.height) return "size differs";
  for (std::uint32_t y = 0; y < want.height; ++y) {
    for (std::uint32_t x = 0; x < want.width; ++x) {
      const Rgb a = got.at(x, y), b = want.at(x, y);
      if (a.r != b.r || a.g != b.g || a.b != b.b) {
        return "pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is " + std::to_string(a.r) + "," +
               std::to_string(a.g) + "," + std::to_string(a.b) + ", the CPU panel gives " + std::to_string(b.r) +
               "," + std::to_string(b.g) + "," + std::to_string(b.b);
      }
    }
  }
  return {};
}

class Passes : public ::testing::TestWithParam<std::uint32_t> {
 protected:
  void SetUp() override {
    std::string why;
    SANDTABLE_REQUIRE(headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  }
};

TEST_P(Passes, HudPassGivesTheCpuPanelsPixels) {
  auto r = makeRenderer(GetParam());
  ASSERT_TRUE(r);
  Overlay overlay;
  // Lines that change from frame to frame (and a frame without a panel),
  // so a stale upload or an uncleared box would show.
  const std::vector<std::vector<std::string>> panels = {
      {"FRAME 0  T 0.00 S", "HDG 020.0\xC2\xB0  SPD 300 KM/H", "FPS 12.5"},
      {"FRAME 1", "A MUCH LONGER SECOND LINE 0123456789"},
      {},
      {"FRAME 3  T 0.10 S", "X"}};
  for (std::uint32_t k = 0; k < panels.size(); ++k) {
    ASSERT_TRUE(r->draw(groundAhead(k)).ok());
    Image want;
    ASSERT_TRUE(r->readFrame(want).ok());
    drawHudPanel(want, panels[k]);
    // A box of the layer covering the frame, as the map does.
    for (std::uint32_t y = 150; y < 160; ++y) {
      for (std::uint32_t x = 250; x < 270; ++x) {
        std::uint8_t* p = &want.rgba[(std::size_t(y) * kW + x) * 4];
        p[0] = 200, p[1] = 10, p[2] = std::uint8_t(k * 40), p[3] = 255;
      }
    }

    ASSERT_TRUE(r->draw(groundAhead(k)).ok());
    overlay.begin(kW, kH);
    drawHudPanel(overlay, panels[k]);
    Image& layer = overlay.layer();
    for (std::uint32_t y = 150; y < 160; ++y) {
      for (std::uint32_t x = 250; x < 270; ++x) {
        std::uint8_t* p = &layer.rgba[(std::size_t(y) * kW + x) * 4];
        p[0] = 200, p[1] = 10, p[2] = std::uint8_t(k * 40), p[3] = 255;
      }
    }
    overlay.drawn({250, 150, 20, 10});
    ASSERT_TRUE(r->drawOverlay(overlay).ok());
    Image got;
    ASSERT_TRUE(r->readFrame(got).ok());
    EXPECT_EQ(firstDifference(got, want), "") << "frame " << k;
  }
}

INSTANTIATE_TEST_SUITE_P(Samples, Passes, ::testing::Values(0u, 4u));

/// Fills the middle of the target with one colour: what an object drawn
/// over the terrain would do.
class SquareModels : public ModelsPass {
 public:
  Status draw(const PassContext& frame) override {
    ++calls;
    lastFrame = frame.buf.frame;
    glEnable(GL_SCISSOR_TEST);
    glScissor(100, 50, 40, 40);  // GL rows from the bottom
    glClearColor(1.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    glDisable(GL_SCISSOR_TEST);
    return {};
  }
  int calls = 0;
  std::uint64_t lastFrame = 0;
};

TEST(RenderPasses, ModelsSlotDrawsOverTheTerrainAndUnderTheHud) {
  std::string why;
  SANDTABLE_REQUIRE(headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  EXPECT_EQ(kRenderPasses.front(), RenderPass::sky);
  EXPECT_EQ(kRenderPasses.back(), RenderPass::hud);
  auto r = makeRenderer();
  ASSERT_TRUE(r);
  auto pass = std::make_unique<SquareModels>();
  SquareModels* models = pass.get();
  r->setModelsPass(std::move(pass));
  ASSERT_TRUE(r->draw(groundAhead(7)).ok());
  EXPECT_EQ(models->calls, 1);
  EXPECT_EQ(models->lastFrame, 7u);
  // A darkened box over part of the square: the HUD comes after the models.
  Overlay overlay;
  overlay.begin(kW, kH);
  overlay.darken({100, 110, 20, 40}, 0.5f);
  ASSERT_TRUE(r->drawOverlay(overlay).ok());
  Image img;
  ASSERT_TRUE(r->readFrame(img).ok());
  // Image row y is GL row kH - 1 - y: the square covers image rows 110..149.
  const Rgb square = img.at(130, 130), under = img.at(110, 130);
  EXPECT_EQ(square.r, 255);
  EXPECT_EQ(square.g, 0);
  EXPECT_EQ(under.r, 128) << "255 darkened by half, rounded as the CPU panel does";
  EXPECT_EQ(r->framesReadBack(), 1u);
  r->setModelsPass(nullptr);
  ASSERT_TRUE(r->draw(groundAhead(8)).ok());
  ASSERT_TRUE(r->readFrame(img).ok());
  EXPECT_NE(img.at(130, 130).r, 255) << "without a models pass the terrain shows";
}

TEST(RenderPasses, OverlayOfAnotherSizeIsRefused) {
  std::string why;
  SANDTABLE_REQUIRE(headlessGlAvailable(why), "headless GL (EGL, Mesa): " << why);
  auto r = makeRenderer();
  ASSERT_TRUE(r);
  ASSERT_TRUE(r->draw(groundAhead(0)).ok());
  Overlay overlay;
  overlay.begin(kW / 2, kH);
  const Status st = r->drawOverlay(overlay);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("the overlay is 160x200, the frame 320x200"), std::string::npos) << st.error();
  EXPECT_FALSE(r->present().ok()) << "a headless renderer has no window";
}

}  // namespace
}  // namespace sandtable::render
