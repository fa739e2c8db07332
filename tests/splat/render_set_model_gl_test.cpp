// Models that change (FeedbackStage::set_model) end to end on OSMesa: the
// renderer follows the hierarchy of the list it draws. Two generated spheres
// of different sizes and colors (a large red one, a small green one, so the
// old model's ids run past the new vertex buffer): frames before the
// exchange are the old model's image, from the exchange on the new one's,
// the vertex buffer is uploaded once per switch, every draw stays within it
// (Renderer::draw refuses a cut of another hierarchy, and the test checks
// that refusal is live), a fade never mixes the two models, and query answers
// of the old model never reach the new one's strategy.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "treecut/controller.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/query_executor.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 200;
constexpr int kHeight = 150;

void context() {
  static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
  ctx->make_current();
}

std::shared_ptr<const Hierarchy> sphere(std::size_t points, glm::u8vec4 color) {
  PointSet p = tools::generate_model(tools::ModelKind::Sphere, points, 7);
  p.colors.assign(p.size(), color);
  return std::make_shared<const Hierarchy>(build_from_points(std::move(p)));
}

const std::shared_ptr<const Hierarchy>& red() {
  static const auto h = sphere(24000, {230, 30, 30, 255});
  return h;
}
const std::shared_ptr<const Hierarchy>& green() {
  static const auto h = sphere(3000, {30, 230, 30, 255});
  return h;
}

// The cut every list of a hierarchy shows: the same nodes whatever the view,
// so each model has exactly one image.
TreeCut fixed_cut(const Hierarchy& h) {
  return breadth_first_cut(h, h.node_count() / 3);
}

// Rebuild strategy handing back fixed_cut of the hierarchy it runs on; it
// asks one query about the root with every list and records the answers it
// is given, with the hierarchy it was running on then.
class FixedCutStrategy final : public Strategy {
 public:
  /// `alternate`: every other list is a finer cut (so fades run within a model).
  explicit FixedCutStrategy(bool alternate = false) : Strategy({}), alternate_(alternate) {}
  [[nodiscard]] std::string_view name() const override { return "fixed"; }
  [[nodiscard]] Mode mode() const override { return Mode::Rebuild; }
  void reset(const Hierarchy& h) override {
    const TreeCut c = fixed_cut(h);
    target_.assign(c.nodes().begin(), c.nodes().end());
    const TreeCut finer = breadth_first_cut(h, h.node_count() / 2);
    finer_.assign(finer.nodes().begin(), finer.nodes().end());
  }
  void iterate(const IterationInput& in, IterationOutput& out) override {
    const std::vector<NodeId>& t = alternate_ && (++iterations_ % 2 == 0) ? finer_ : target_;
    out.nodes->assign(t.begin(), t.end());
    out.queries->push_back(query_about(in, 0, 0));
    for (const VisibilityResult& v : in.view.visibility) seen.push_back({&in.hierarchy, v});
    out.result.converged = false;  // keep iterating: a list (and a query) per step
  }
  struct Seen {
    const Hierarchy* hierarchy;
    VisibilityResult result;
  };
  std::vector<Seen> seen;

 private:
  bool alternate_;
  unsigned iterations_ = 0;
  std::vector<NodeId> target_, finer_;
};

Camera camera() {
  // Both spheres are the unit sphere: one camera frames either.
  return default_camera(red()->bounds_min(), red()->bounds_max(), float(kWidth) / kHeight);
}

// Each model's one image, drawn by a renderer of its own.
Image reference(const Hierarchy& h) {
  Renderer r(h, {kWidth, kHeight});
  CutBuffer cut;
  cut.upload(h, fixed_cut(h).nodes());
  r.draw(cut, camera(), RenderSettings{}, true);
  return Image{kWidth, kHeight, r.read_pixels()};
}

// Pixels that are clearly of the red model (r well above g), or of the green one.
std::size_t reddish(const Image& im) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < im.rgba.size(); i += 4) n += im.rgba[i] > im.rgba[i + 1] + 40;
  return n;
}
std::size_t greenish(const Image& im) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < im.rgba.size(); i += 4) n += im.rgba[i + 1] > im.rgba[i] + 40;
  return n;
}

struct SwitchRun {
  explicit SwitchRun(unsigned blend) {
    auto s = std::make_unique<FixedCutStrategy>(blend > 0);
    strategy = s.get();
    StageOptions o;
    o.launch = Launch::Manual;
    o.blend_frames = blend;
    controller =
        std::make_unique<Controller>(Model{red(), fixed_cut(*red())}, std::move(s),
                                     view_snapshot(camera(), {kWidth, kHeight}, Light{}), o);
    frame = std::make_unique<RenderThreadFrame>(*controller, renderer, &executor);
  }
  // One frame, then the stage's iteration; the image and what the frame did.
  FrameResult step(Image& image) {
    const FrameResult r = frame->run_render_thread(camera(), RenderSettings{}, true);
    image = Image{kWidth, kHeight, renderer.read_pixels()};
    // Never an id past the vertex buffer (draw() would have thrown).
    EXPECT_LT(renderer.last_max_id(), renderer.node_count());
    controller->stage().step();
    return r;
  }

  Renderer renderer{*red(), {kWidth, kHeight}};
  QueryExecutor executor;
  FixedCutStrategy* strategy = nullptr;
  std::unique_ptr<Controller> controller;
  std::unique_ptr<RenderThreadFrame> frame;  // after what it refers to
};

TEST(RenderSetModel, FramesShowTheOldModelUntilTheExchangeThenOnlyTheNewOne) {
  context();
  ASSERT_GT(fixed_cut(*red()).nodes().back(), green()->node_count())
      << "the old model's ids must run past the new vertex buffer";
  const Image red_image = reference(*red());
  const Image green_image = reference(*green());
  ASSERT_GT(reddish(red_image), 1000u);
  ASSERT_GT(greenish(green_image), 1000u);

  SwitchRun run(0);
  Image image;
  for (int f = 0; f < 4; ++f) {
    run.step(image);
    EXPECT_EQ(image.rgba, red_image.rgba) << "frame " << f;
  }
  EXPECT_EQ(run.renderer.hierarchy_uploads(), 1u);
  run.controller->stage().set_model(Model{green(), fixed_cut(*green())});
  int switch_frame = -1;
  std::uint64_t switch_number = 0;
  for (int f = 0; f < 12; ++f) {
    const FrameResult r = run.step(image);
    if (r.model_switched) {
      EXPECT_EQ(switch_frame, -1) << "one switch";
      switch_frame = f;
      switch_number = r.frame;
      EXPECT_TRUE(r.exchanged);
    }
    if (switch_frame < 0) {
      EXPECT_EQ(image.rgba, red_image.rgba) << "frame " << f << " before the exchange";
      EXPECT_EQ(run.renderer.hierarchy(), red().get());
    } else {
      EXPECT_EQ(image.rgba, green_image.rgba) << "frame " << f << " after the exchange";
      EXPECT_EQ(run.renderer.hierarchy(), green().get());
      EXPECT_EQ(run.renderer.node_count(), green()->node_count());
      EXPECT_EQ(run.frame->cut().hierarchy(), green().get());
    }
  }
  ASSERT_GE(switch_frame, 0) << "the new model was never drawn";
  EXPECT_EQ(run.renderer.hierarchy_uploads(), 2u) << "one upload per switch";
  // The old model's answers never reach the new model's strategy.
  std::size_t green_answers = 0;
  for (const FixedCutStrategy::Seen& s : run.strategy->seen) {
    if (s.hierarchy != green().get()) continue;
    ++green_answers;
    EXPECT_GE(s.result.frame_issued, switch_number)
        << "an answer to a query issued for the old model";
  }
  EXPECT_GT(green_answers, 0u) << "the new model's own queries are answered";
  std::printf("switch at frame %d of 12 after set_model; %llu stale answers dropped\n",
              switch_frame, static_cast<unsigned long long>(run.frame->stale_results()));
}

TEST(RenderSetModel, SwitchingBackAndForthWithFadesNeverMixesTheModels) {
  context();
  constexpr unsigned kBlend = 4;
  SwitchRun run(kBlend);
  Image image;
  std::size_t switches = 0;
  std::size_t fading_frames = 0;
  const Hierarchy* wanted = red().get();
  for (int f = 0; f < 120; ++f) {
    // A new model every 9 frames, alternating; often in the middle of a fade.
    if (f % 9 == 4) {
      const auto& next = wanted == red().get() ? green() : red();
      run.controller->stage().set_model(Model{next, fixed_cut(*next)});
      wanted = next.get();
    }
    const FrameResult r = run.step(image);
    switches += r.model_switched;
    const CutBuffer& cut = run.frame->cut();
    fading_frames += cut.fading();
    if (r.model_switched) {
      EXPECT_FALSE(cut.fading()) << "frame " << f << ": a fade across models";
    }
    // The drawn list's model alone (its own fades go between two of its
    // cuts): its colour, no pixel of the other model's.
    const bool is_red = run.renderer.hierarchy() == red().get();
    EXPECT_EQ(cut.hierarchy(), run.renderer.hierarchy()) << "frame " << f;
    EXPECT_GT(is_red ? reddish(image) : greenish(image), 1000u) << "frame " << f;
    EXPECT_EQ(is_red ? greenish(image) : reddish(image), 0u) << "frame " << f;
  }
  EXPECT_GE(switches, 10u);
  EXPECT_GT(fading_frames, 10u) << "fades within a model must run";
  EXPECT_EQ(run.renderer.hierarchy_uploads(), switches + 1);
  std::printf("%zu switches, %zu frames drawn while a fade ran\n", switches, fading_frames);
}

TEST(RenderSetModel, ADrawOfAnotherHierarchysCutIsRefused) {
  context();
  Renderer renderer(*green(), {kWidth, kHeight});
  CutBuffer cut;
  cut.upload(*red(), fixed_cut(*red()).nodes());
  EXPECT_THROW(renderer.draw(cut, camera(), RenderSettings{}), std::logic_error);
  const CutRange all{0, static_cast<std::uint32_t>(cut.size())};
  EXPECT_THROW(
      renderer.draw_ranges(cut, std::span<const CutRange>(&all, 1), camera(), RenderSettings{}),
      std::logic_error);
  // After the upload of that hierarchy the same cut draws.
  renderer.set_hierarchy(*red());
  EXPECT_NO_THROW(renderer.draw(cut, camera(), RenderSettings{}, true));
  EXPECT_EQ(renderer.read_pixels(), reference(*red()).rgba);
  EXPECT_EQ(renderer.last_max_id(), cut.max_id());
  // An empty list draws nothing, whatever it was uploaded for.
  CutBuffer empty;
  EXPECT_NO_THROW(renderer.draw(empty, camera(), RenderSettings{}));
}

}  // namespace
}  // namespace treecut::splat
