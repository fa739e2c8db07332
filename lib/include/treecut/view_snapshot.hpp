// ViewSnapshot: everything a strategy may read about the View for one
// iteration (Marton & Schiffner et al., "Parallel TreeCut Manipulation",
// section 3: "LOD-strategies may need to acquire additional data from the View
// ... which can also be copied without a lock").
//
// The render thread fills a snapshot (camera, projection, viewport, light,
// frame number, visibility results of GPU queries) and hands a copy to the
// Feedback Stage with an update request; the strategy sees it as a const
// reference valid for the duration of one iteration. Plain value type.
//
// GPU queries (occlusion strategies): a strategy posts QueryRequests with its
// result; the render thread executes them on the GPU and reports the results
// as VisibilityResults in a later snapshot, frames later. Nothing ever waits
// for a query result.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <vector>

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

#include "treecut/hierarchy.hpp"

namespace treecut {

/// What a query counts. A strategy that only needs "visible or not" asks for
/// AnySamples (the View's executor counts both the same way, see
/// treecut/splat/query_executor.hpp; a boolean leaves it free to answer
/// sooner, erring only towards visible).
enum class QueryKind : std::uint8_t {
  Samples,     ///< how many samples of the proxy pass the depth test (as GL_SAMPLES_PASSED)
  AnySamples,  ///< 0 or 1 (as GL_ANY_SAMPLES_PASSED_CONSERVATIVE)
};

/// One occlusion (or other visibility) query a strategy asks the View to run.
struct QueryRequest {
  std::uint32_t object = 0;  ///< which hierarchy of a many-object scene (0 for one model)
  NodeId node = kNoNode;     ///< the node whose bounding sphere is tested
  std::uint32_t tag = 0;     ///< opaque to the View, returned unchanged in the result
  QueryKind kind = QueryKind::Samples;
  /// The node's bounding sphere (center, radius) as the strategy read it:
  /// what the View tests (query_about() in treecut/strategy.hpp fills it).
  /// The render thread reads no hierarchy for a query and keeps no copy of
  /// one (a paged model's node may be given back before a deferred request
  /// goes out). A radius that is not positive and finite is answered 0.
  glm::vec4 sphere{0.0f};
};

/// The answer to a QueryRequest, delivered frames later in a ViewSnapshot.
struct VisibilityResult {
  std::uint32_t object = 0;
  NodeId node = kNoNode;
  std::uint32_t tag = 0;
  std::uint32_t samples_passed = 0;  ///< GL_SAMPLES_PASSED (0 = occluded); 0 or 1 for AnySamples
  /// Both on the one frame counter of the render thread (FeedbackStage::frame(),
  /// ViewSnapshot::frame): the frame the proxy was drawn in and the frame its
  /// answer was read in. frame_read > frame_issued unless the View answered
  /// without the GPU (the eye inside the sphere).
  std::uint64_t frame_issued = 0;
  std::uint64_t frame_read = 0;
  QueryKind kind = QueryKind::Samples;
};

/// A plane n.x + d >= 0 for points inside.
using Plane = glm::vec4;

/// The six planes of the view frustum of CLIP_FROM_WORLD (a projection times
/// a view), normalized, normals inward: left, right, bottom, top, near, far.
/// Gribb & Hartmann, "Fast Extraction of Viewing Frustum Planes from the
/// World-View-Projection Matrix". The one extraction: ViewSnapshot's derived
/// planes are this.
std::array<glm::vec4, 6> frustum_planes(const glm::mat4& clip_from_world);

struct ViewSnapshot {
  glm::mat4 view{1.0f};                   ///< model-to-eye (the model matrix is folded in)
  glm::mat4 projection{1.0f};             ///< eye-to-clip, perspective or orthographic
  glm::ivec2 viewport{1, 1};              ///< pixels
  glm::vec3 light_dir{0.0f, 0.0f, 1.0f};  ///< unit, model space, pointing towards the light
  /// The render thread's frame number when the update was requested: the
  /// stage's poll count (FeedbackStage::frame()), the counter every
  /// VisibilityResult is numbered on. Set by the stage.
  std::uint64_t frame = 0;
  /// Incremented by the render thread whenever camera, projection, viewport or
  /// light change; strategies use it to tell "same view" (convergence) apart.
  std::uint64_t version = 0;
  /// Query results gathered since the previous snapshot, in issue order.
  std::vector<VisibilityResult> visibility;

  /// Where the camera that made `view` stands, exactly, and the `view` it
  /// stood for (place_eye() sets both). The eye finalize() derives from the
  /// matrix alone is off by the float rounding of |eye| (millimetres 30 km
  /// from the origin), and the renderer draws relative to the eye
  /// (shaders.hpp), so a camera gives its own. Kept only while `view` is
  /// still that matrix: a view changed since (a model matrix folded in)
  /// derives its eye again.
  glm::vec3 placed_eye{0.0f};
  glm::mat4 placed_view{0.0f};
  /// Records `eye` as the exact eye of the current `view`; finalize() after.
  void place_eye(glm::vec3 eye) {
    placed_eye = eye;
    placed_view = view;
  }

  /// Derived from the fields above by finalize(), once per view; read-only
  /// for everyone who is handed the view (strategies, the culling
  /// traversals, the renderer's query hooks).
  struct Derived {
    glm::mat4 view_projection{1.0f};  ///< clip = view_projection * model (OpenGL, z in [-1, 1])
    /// Camera position in model space: placed_eye while `view` is
    /// placed_view, else from the inverse of `view`.
    glm::vec3 eye{0.0f};
    glm::vec3 forward{0.0f, 0.0f, -1.0f};  ///< unit viewing direction in model space
    /// Eye depths of the near and far planes, model units.
    float near_plane = 0.0f;
    float far_plane = 0.0f;
    /// A box or sphere nearer to the eye than this may cross the near plane:
    /// 1 % more than the distance from the eye to the farthest corner of the
    /// near plane's rectangle (the margin covers rounding). The occlusion
    /// traversals draw such blocks without a query.
    float near_radius = 0.0f;
    /// Pixel rays of a perspective frustum (all zero otherwise): the
    /// model-space direction through normalized device coordinates (x, y)
    /// is ray_x * x + ray_y * y + ray_0, scaled so that its parameter t is
    /// the eye depth of the point reached (see ray_direction()).
    glm::vec3 ray_x{0.0f}, ray_y{0.0f}, ray_0{0.0f};
    std::array<Plane, 6> frustum{};  ///< normalized, inward-facing
    /// The same planes by component, in 8 lanes (the last two never cull),
    /// so outside_frustum() tests all six with vector instructions.
    struct alignas(32) PlaneLanes {
      std::array<float, 8> x{}, y{}, z{}, w{};
    } lanes;
    float pixel_scale = 1.0f;  ///< pixels per unit of (radius / distance), or per unit for ortho
    bool perspective = true;
  } derived;

  /// Recomputes `derived`; call after changing view, projection or viewport.
  void finalize();

  /// `view` without its translation: model axes with the eye at zero to eye
  /// space, for positions taken relative to derived.eye (what the renderer
  /// and its query proxies draw with: no float cancellation of two large
  /// coordinates near the eye).
  [[nodiscard]] glm::mat4 eye_relative_view() const { return glm::mat4(glm::mat3(view)); }

  /// The projection has the perspective frustum form (is_perspective_frustum
  /// of treecut/query_proxy.hpp: glm::perspective, glm::frustum) and the
  /// viewport is not empty: what the pixel rays, the screen rectangles of the
  /// culling layer and the query proxies' pixel counts need.
  [[nodiscard]] bool perspective_frustum() const;

  /// Model-space direction of the ray through window point (x, y) (pixels,
  /// y up) of a perspective frustum, scaled so that its parameter t is the
  /// eye depth of the point reached.
  [[nodiscard]] glm::vec3 ray_direction(float x, float y) const {
    const float nx = 2.0f * x / static_cast<float>(viewport.x) - 1.0f;
    const float ny = 2.0f * y / static_cast<float>(viewport.y) - 1.0f;
    return derived.ray_x * nx + derived.ray_y * ny + derived.ray_0;
  }

  /// A camera at `eye` looking at `target` with a vertical field of view
  /// (radians), finalized. `near`/`far` in model units.
  static ViewSnapshot look_at(glm::vec3 eye, glm::vec3 target, glm::ivec2 viewport,
                              float fov_y = 0.8f, float near_plane = 0.01f,
                              float far_plane = 1000.0f);

  /// True when the sphere lies completely outside one frustum plane.
  [[nodiscard]] bool outside_frustum(glm::vec3 center, float radius) const {
    // Branch-free over the lanes: the strategies call this for every cut
    // node, and most nodes pass all six planes anyway.
    const Derived::PlaneLanes& p = derived.lanes;
#if defined(__SSE2__)
    const __m128 cx = _mm_set1_ps(center.x);
    const __m128 cy = _mm_set1_ps(center.y);
    const __m128 cz = _mm_set1_ps(center.z);
    const __m128 limit = _mm_set1_ps(-radius);
    int outside = 0;
    for (std::size_t i = 0; i < 8; i += 4) {
      const __m128 d = _mm_add_ps(
          _mm_add_ps(_mm_mul_ps(_mm_load_ps(&p.x[i]), cx), _mm_mul_ps(_mm_load_ps(&p.y[i]), cy)),
          _mm_add_ps(_mm_mul_ps(_mm_load_ps(&p.z[i]), cz), _mm_load_ps(&p.w[i])));
      outside |= _mm_movemask_ps(_mm_cmplt_ps(d, limit));
    }
    return outside != 0;
#else
    for (std::size_t i = 0; i < 6; ++i) {
      if (p.x[i] * center.x + p.y[i] * center.y + p.z[i] * center.z + p.w[i] < -radius) return true;
    }
    return false;
#endif
  }

  /// Upper bound of the projected radius in pixels of a sphere. Uses the
  /// distance to the sphere's nearest point, so it is monotone: a sphere inside
  /// another never projects larger (what keeps priorities parent >= child).
  [[nodiscard]] float projected_radius_px(glm::vec3 center, float radius) const {
    if (!derived.perspective) return radius * derived.pixel_scale;
    const glm::vec3 d = center - derived.eye;
    const float dist = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z) - radius;
    constexpr float kMinDistance = 1e-6f;
    return radius * derived.pixel_scale / (dist > kMinDistance ? dist : kMinDistance);
  }

  /// True when every point of the sphere is seen from behind by every normal of
  /// the cone (QSplat's backface cone test, conservative).
  [[nodiscard]] bool backfacing(glm::vec3 center, float radius, glm::vec3 normal,
                                float cone_cos) const;
};

}  // namespace treecut
