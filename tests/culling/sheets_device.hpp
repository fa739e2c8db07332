// The CPU device of the CHC tests (chc_test.cpp): a
// perspective "GPU" looking down +x whose depth buffer is a grid of pixels
// over the projected rectangles of block boxes (a drawn leaf block fills its
// box's rectangle at the box's nearest depth; a box query counts the pixels
// of its rectangle where its nearest depth is in front). Answers come
// `latency` device calls after the query, so the query queue, polling and
// blocking are all observable. The reference ("truth") is brute force on the
// same device model: a leaf is visible when some pixel of its rectangle is
// nearer than every other leaf's rectangle there.
#pragma once

#include "treecut/culling/chc.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "treecut/attributes.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/point_set.hpp"

namespace {

using treecut::Hierarchy;
using treecut::PointSet;
using treecut::ViewSnapshot;
using treecut::culling::BlockId;
using treecut::culling::Box;
using treecut::culling::ChcFrameStats;
using treecut::culling::ChcOptions;
using treecut::culling::ChcTraversal;
using treecut::culling::DeviceFrameStats;
using treecut::culling::HlodBlocks;
using treecut::culling::kBinaryFanOut;
using treecut::culling::kNoBlock;
using treecut::culling::OcclusionDeviceRenderThread;
using treecut::culling::OcclusionMode;
using treecut::culling::QueryHandle;

constexpr int kRes = 96;  // pixels per side over u, v in [-1, 1]

// Sheets of points in planes x = const (facing the eye), spread in y and z;
// and one cluster far off to the side (outside the 90 degree frustum).
std::shared_ptr<const Hierarchy> sheets() {
  static std::shared_ptr<const Hierarchy> h;
  if (h) return h;
  struct Sheet {
    float x, y, z, half;
  };
  const std::vector<Sheet> list = {
      {0.0f, 0.0f, 0.0f, 0.55f}, {1.0f, 0.9f, 0.2f, 0.5f}, {1.5f, -0.9f, -0.3f, 0.45f},
      {2.5f, 0.1f, 0.0f, 0.6f},  {3.0f, 1.8f, 1.2f, 0.5f}, {4.0f, -0.2f, 0.1f, 0.9f},
      {5.0f, -2.5f, 0.5f, 0.7f}, {6.0f, 0.0f, 0.0f, 2.8f}, {2.0f, 40.0f, 0.0f, 0.5f},
  };
  PointSet ps;
  for (const Sheet& s : list) {
    const int n = 16;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        const float fy = -s.half + 2.0f * s.half * (i + 0.5f) / n;
        const float fz = -s.half + 2.0f * s.half * (j + 0.5f) / n;
        ps.positions.push_back({s.x, s.y + fy, s.z + fz});
        ps.normals.push_back({-1.0f, 0.0f, 0.0f});
      }
    }
  }
  treecut::complete_attributes(ps);
  h = std::make_shared<const Hierarchy>(treecut::build_hierarchy(std::move(ps)));
  return h;
}

struct Rect {
  int i0 = 0, i1 = -1, j0 = 0, j1 = -1;  // inclusive pixel ranges, empty if i1 < i0
  float depth = 0.0f;
};

class FakeDevice final : public OcclusionDeviceRenderThread {
 public:
  FakeDevice(const HlodBlocks& blocks, int latency) : blocks_(&blocks), latency_(latency) {}

  void set_eye(glm::vec3 eye) { eye_ = eye; }
  void watch(const ChcTraversal* t) { traversal_ = t; }

  Rect rect(BlockId b) const {
    const Box& box = blocks_->box(b);
    // Depth: the distance from the eye to the box, the traversal's order, so
    // front to back is an occlusion order and S&W is exact on this device.
    const glm::vec3 d = glm::max(glm::max(box.lo - eye_, eye_ - box.hi), glm::vec3(0.0f));
    const float depth = glm::length(d);
    float umin = 1e30f, umax = -1e30f, vmin = 1e30f, vmax = -1e30f;
    for (int c = 0; c < 8; ++c) {
      const glm::vec3 p((c & 1) ? box.hi.x : box.lo.x, (c & 2) ? box.hi.y : box.lo.y,
                        (c & 4) ? box.hi.z : box.lo.z);
      const float w = p.x - eye_.x;
      // A box reaching to or behind the eye's plane (an interior block's
      // box of large coarse splats) may cover any pixel: the whole screen.
      if (w < 1e-3f) return Rect{0, kRes - 1, 0, kRes - 1, depth};
      umin = std::min(umin, (p.y - eye_.y) / w), umax = std::max(umax, (p.y - eye_.y) / w);
      vmin = std::min(vmin, (p.z - eye_.z) / w), vmax = std::max(vmax, (p.z - eye_.z) / w);
    }
    // Pixels whose centres (-1 + (i + 0.5) * 2 / kRes) lie inside.
    auto first = [](float a) { return std::max(0, int(std::ceil((a + 1.0f) * kRes / 2 - 0.5f))); };
    auto last = [](float a) {
      return std::min(kRes - 1, int(std::floor((a + 1.0f) * kRes / 2 - 0.5f)));
    };
    umin = std::clamp(umin, -2.0f, 2.0f), umax = std::clamp(umax, -2.0f, 2.0f);
    vmin = std::clamp(vmin, -2.0f, 2.0f), vmax = std::clamp(vmax, -2.0f, 2.0f);
    Rect r{first(umin), last(umax), first(vmin), last(vmax), depth};
    return r;
  }

  void begin_frame_render_thread() override {
    depth_.assign(kRes * kRes, std::numeric_limits<float>::infinity());
    stats_ = {};
    answers_.clear();
    queried_.clear();
    ++frame_;
  }
  QueryHandle query_box_render_thread(BlockId b) override {
    tick();
    const Rect r = rect(b);
    std::uint64_t samples = 0;
    for (int i = r.i0; i <= r.i1; ++i)
      for (int j = r.j0; j <= r.j1; ++j)
        samples +=
            r.depth <= depth_[i * kRes + j] ? 1 : 0;  // GL_LEQUAL, as the GL device's proxies
    return issue(b, samples);
  }
  QueryHandle query_draw_render_thread(BlockId b) override {
    const QueryHandle q = query_box_render_thread(b);
    draw_render_thread(b);
    return q;
  }
  bool result_available_render_thread(QueryHandle q) override {
    tick();
    ++polls;
    return ticks_ >= queries_.at(q).ready;
  }
  std::uint64_t result_render_thread(QueryHandle q) override {
    tick();
    const Query query = queries_.at(q);
    queries_.erase(q);
    if (ticks_ < query.ready) {
      ++stats_.blocking_reads;
      ++blocking_total;
      if (traversal_ != nullptr && traversal_->queued() > 0) ++blocked_with_work;
      ticks_ = query.ready;  // the "GPU" catches up while the CPU waits
    }
    answers_[query.block] = query.samples;
    return query.samples;
  }
  void draw_render_thread(BlockId b) override {
    tick();
    const Rect r = rect(b);
    for (int i = r.i0; i <= r.i1; ++i)
      for (int j = r.j0; j <= r.j1; ++j)
        depth_[i * kRes + j] = std::min(depth_[i * kRes + j], r.depth);
    ++stats_.blocks_drawn;
    stats_.splats_drawn += blocks_->representation(b).size();
  }
  void end_frame_render_thread(bool) override { tick(); }
  [[nodiscard]] const DeviceFrameStats& frame_stats() const override { return stats_; }

  // Per frame: the answer each queried block got, and the queried blocks.
  std::map<BlockId, std::uint64_t> answers_;
  std::vector<BlockId> queried_;
  std::uint64_t blocking_total = 0;
  std::uint64_t blocked_with_work = 0;
  std::uint64_t polls = 0;

 private:
  struct Query {
    BlockId block;
    std::uint64_t samples, ready;
  };
  void tick() { ++ticks_; }
  QueryHandle issue(BlockId b, std::uint64_t samples) {
    ++stats_.queries;
    queried_.push_back(b);
    const QueryHandle q = next_++;
    queries_[q] = {b, samples, ticks_ + static_cast<std::uint64_t>(latency_)};
    return q;
  }

  const HlodBlocks* blocks_;
  int latency_;
  const ChcTraversal* traversal_ = nullptr;
  glm::vec3 eye_{-3.0f, 0.0f, 0.0f};
  std::vector<float> depth_;
  std::map<QueryHandle, Query> queries_;
  QueryHandle next_ = 0;
  std::uint64_t ticks_ = 0;
  std::uint64_t frame_ = 0;
  DeviceFrameStats stats_;
};

ViewSnapshot view_from(glm::vec3 eye) {
  ViewSnapshot v;
  v.projection = glm::perspective(glm::radians(90.0f), 1.0f, 0.1f, 100.0f);
  v.view = glm::lookAt(eye, eye + glm::vec3(1, 0, 0), glm::vec3(0, 0, 1));
  v.viewport = {64, 64};
  v.finalize();
  return v;
}

class Chc : public ::testing::Test {
 public:
  /// truth() for code outside the fixture (the tests' helpers).
  std::set<BlockId> truth_of(const FakeDevice& d) const { return truth(d); }

 protected:
  // The binary tree of blocks CHC runs on (the paper's kD-tree).
  void SetUp() override { blocks_ = HlodBlocks::build(*sheets(), 64, kBinaryFanOut); }

  std::vector<BlockId> leaves_in_frustum(const FakeDevice& d) const {
    std::vector<BlockId> out;
    for (BlockId b = 0; b < blocks_.block_count(); ++b) {
      const Rect r = d.rect(b);
      if (blocks_.is_leaf(b) && r.i1 >= r.i0 && r.j1 >= r.j0) out.push_back(b);
    }
    return out;
  }
  // Brute force: visible where no other leaf block is strictly nearer.
  std::set<BlockId> truth(const FakeDevice& d, std::uint64_t min_samples = 1) const {
    std::vector<float> depth(kRes * kRes, std::numeric_limits<float>::infinity());
    const auto leaves = leaves_in_frustum(d);
    std::set<BlockId> out;
    for (const BlockId b : leaves) {
      const Rect r = d.rect(b);
      std::uint64_t samples = 0;
      for (int i = r.i0; i <= r.i1; ++i) {
        for (int j = r.j0; j <= r.j1; ++j) {
          bool front = true;
          for (const BlockId o : leaves) {
            if (o == b) continue;
            const Rect q = d.rect(o);
            if (i >= q.i0 && i <= q.i1 && j >= q.j0 && j <= q.j1 && q.depth < r.depth) {
              front = false;
              break;
            }
          }
          samples += front ? 1 : 0;
        }
      }
      if (samples >= min_samples) out.insert(b);
    }
    return out;
  }
  static std::set<BlockId> as_set(const std::vector<BlockId>& v) { return {v.begin(), v.end()}; }

  HlodBlocks blocks_;
};

}  // namespace
