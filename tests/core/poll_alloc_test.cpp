// The render thread's side of the exchange does no allocation: once the list
// buffers have grown, poll() (with its exchange and request) and set_view()
// never call operator new, whatever the cut size, blending or thread. The global operator new of
// this test binary counts the calls made by the render thread while `counting` is set.
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <new>
#include <thread>

#include "strategy_fixtures.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"

namespace {
thread_local bool counting = false;
thread_local std::size_t allocations = 0;
}  // namespace

void* operator new(std::size_t size) {
  if (counting) ++allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
// GCC, seeing through an inlined replacement pair, takes free() of a pointer
// from operator new for a mismatch (-Wmismatched-new-delete); here both sides
// are ours and use malloc/free.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

namespace treecut {
namespace {

struct Case {
  const char* name;
  std::size_t cut;
  unsigned blend;
  Launch launch;
};

std::size_t render_thread_allocations(const Case& c) {
  const auto h = test::small_hierarchy(tools::ModelKind::Terrain, 60000);
  StageOptions o;
  o.blend_frames = c.blend;
  o.launch = c.launch;
  auto walk = std::make_unique<test::RandomWalkStrategy>(3);
  walk->set_param("ops", 2);  // a refine grows the cut: the buffers settle at their peak
  FeedbackStage stage(Model{h, breadth_first_cut(*h, c.cut)}, std::move(walk), o);
  std::uint64_t version = 0;
  const auto frame = [&](bool count) {
    ViewSnapshot v = test::orbit_view(*h, 0.01f * static_cast<float>(version));
    v.version = ++version;
    counting = count;
    stage.set_view(v);
    stage.poll();
    counting = false;
    if (c.launch == Launch::Manual) stage.step();
  };
  // Warm-up: every buffer has been written and the cut has grown by more
  // than it can in the counted frames, so no capacity is exceeded later.
  // Frames are counted in exchanges: a stage thread needs its own time.
  const auto frames_until = [&](std::uint64_t exchanges, bool count) {
    while (stage.counters().exchanges < exchanges) {
      frame(count);
      if (c.launch == Launch::Thread) std::this_thread::yield();
    }
  };
  frames_until(2000, false);
  allocations = 0;
  frames_until(stage.counters().exchanges + 500, true);
  return allocations;
}

TEST(RenderThread, PollExchangeAndRequestNeverAllocate) {
  for (const Case& c :
       {Case{"10k", 10'000, 0, Launch::Manual}, Case{"30k, blending", 30'000, 3, Launch::Manual},
        Case{"10k, stage thread", 10'000, 0, Launch::Thread}}) {
    EXPECT_EQ(render_thread_allocations(c), 0u) << c.name;
  }
}

}  // namespace
}  // namespace treecut
