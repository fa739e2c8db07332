// GLSL 4.50 sources of the splat renderer, embedded as raw strings. Each
// program is kCommon + its stages' bodies (make_program in renderer.cpp).
#pragma once

namespace treecut::splat::shaders {

// Uniforms and functions every stage may use. Colors are sRGB in the node
// arrays and the output; lighting happens in linear space.
//
// Relative to the eye (issue 29): every position past the vertex stage is in
// the world's axes with the eye at zero, and u_view is the view's rotation
// only (Renderer::set_common_uniforms). A model at map coordinates has
// positions of kilometres from its origin; `view * p` in float would cancel
// two such numbers and leave millimetres of error that change as the camera
// moves (points near the eye jitter). p - eye of two nearby floats is exact
// (Sterbenz), so what is near the eye is drawn exactly (object_point).
inline constexpr const char* kCommon = R"(#version 450 core
uniform mat4 u_view;             // rotation only: eye-relative world -> eye space
uniform mat4 u_proj;
uniform vec3 u_eye;              // world space; positions here are relative to it
uniform float u_radius_scale;
uniform int u_cull;              // 1: drop nodes whose normal cone faces away
uniform float u_min_radius_px;   // quads smaller than this grow to it (no sub-pixel dropouts)
uniform float u_viewport_h;      // pixels
uniform vec3 u_light_dir;        // world space, unit, towards the light
uniform vec4 u_light;            // ambient, diffuse, specular, shininess
uniform int u_clip;              // 1: only splats whose centre is in the clip box
uniform vec3 u_clip_min;         // the box, relative to the eye
uniform vec3 u_clip_max;
bool clipped(vec3 c) {
  return u_clip == 1 && (any(lessThan(c, u_clip_min)) || any(greaterThan(c, u_clip_max)));
}

vec3 srgb_to_linear(vec3 c) {
  return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(0.04045, c));
}
vec3 linear_to_srgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}
// Blinn-Phong, two-sided: a normal facing away from the eye is flipped.
vec3 shade(vec3 albedo, vec3 n, vec3 pos) {
  vec3 v = normalize(-pos);
  if (dot(n, v) < 0.0) n = -n;
  float diffuse = max(dot(n, u_light_dir), 0.0);
  vec3 h = normalize(u_light_dir + v);
  float specular = diffuse > 0.0 ? pow(max(dot(n, h), 0.0), u_light.w) : 0.0;
  return albedo * (u_light.x + u_light.y * diffuse) + vec3(u_light.z * specular);
}
// True when every normal of the cone (axis n, cosine cc) faces away from the
// unit direction e towards the eye: angle(n, e) > 90 deg + half-angle, with a
// little slack for noisy leaf normals.
bool cone_faces_away(vec3 n, float cc, vec3 e) {
  if (u_cull == 0 || cc <= 0.0) return false;
  float sin_half = sqrt(max(1.0 - cc * cc, 0.0));
  return dot(n, e) < -sin_half - 0.1;
}
)";

// Fragment stages only (after kCommon and the defines): the screen-door fade
// of an exchange (CutBuffer::set_fade). An 8x8 ordered-dither (Bayer)
// threshold per pixel; a pixel shows the new list once the fade weight passes
// its threshold, the old one before. The depth-tested opaque pipeline stays,
// and the result does not depend on the drawing order: every pixel is either
// the old or the new image, and the share of new pixels grows with the weight.
inline constexpr const char* kFragmentCommon = R"(
uniform int u_fade_mode;  // 0: always drawn, 1: entering splat, 2: leaving splat
uniform float u_fade;     // weight of the new list in [0, 1]
bool faded_out() {
  if (u_fade_mode == 0) return false;
  int x = int(gl_FragCoord.x) & 7;
  int y = int(gl_FragCoord.y) & 7;
  int v = x ^ y;
  // Bit-reversed interleave of (x ^ y, y): the 64 thresholds of an 8x8 Bayer matrix.
  int b = ((v & 1) << 5) | ((y & 1) << 4) | ((v & 2) << 2) | ((y & 2) << 1) | ((v & 4) >> 1) |
          ((y & 4) >> 2);
  bool new_here = (float(b) + 0.5) / 64.0 < u_fade;
  return u_fade_mode == 1 ? !new_here : new_here;
}
)";

// The object a node belongs to (one vertex attribute per instance: the
// renderer's identity for a single model, a scene object's record for
// Renderer::draw_scene, whose indirect commands set baseInstance to the
// object). Rows 0-2 of the affine model -> world matrix, and what a splat
// needs besides: the largest singular value of its linear part (a sphere of
// radius r becomes an ellipsoid within radius sigma r: the splat grows to
// cover it) and a bound on how much it widens a normal cone (1 for a
// similarity, whose cones keep their angle).
inline constexpr const char* kObjectVertex = R"(
layout(location = 3) in vec4 a_world_row0;
layout(location = 4) in vec4 a_world_row1;
layout(location = 5) in vec4 a_world_row2;
layout(location = 6) in vec4 a_object;  // sigma_max, cone widening, det sign, object index
// A model point relative to the eye: the linear part, then the translation
// less the eye (for a single model, exactly p - eye).
vec3 object_point(vec3 p) {
  precise vec3 t = vec3(a_world_row0.w, a_world_row1.w, a_world_row2.w) - u_eye;
  precise vec3 q = vec3(dot(a_world_row0.xyz, p), dot(a_world_row1.xyz, p),
                        dot(a_world_row2.xyz, p)) + t;
  return q;
}
// Normals transform with the cofactor matrix (det * inverse transpose): the
// cross products of the linear part's columns, times the determinant's sign.
vec3 object_normal(vec3 n) {
  vec3 c0 = vec3(a_world_row0.x, a_world_row1.x, a_world_row2.x);
  vec3 c1 = vec3(a_world_row0.y, a_world_row1.y, a_world_row2.y);
  vec3 c2 = vec3(a_world_row0.z, a_world_row1.z, a_world_row2.z);
  return a_object.z * (cross(c1, c2) * n.x + cross(c2, c0) * n.y + cross(c0, c1) * n.z);
}
// A cone of cosine cc after the transform: sin grows by at most the factor
// (1 for a similarity: the cone as is). Past 72 degrees it no longer culls.
float object_cone(float cc) {
  if (a_object.y == 1.0 || cc <= 0.0) return cc;
  float s = a_object.y * sqrt(max(1.0 - cc * cc, 0.0));
  return s < 0.95 ? sqrt(1.0 - s * s) : 0.0;
}
)";

// Vertex stage of the disc modes: passes the node through (relative to the eye).
inline constexpr const char* kSplatVertex = R"(
layout(location = 0) in vec3 a_center;        // the node's center (its sphere's)
layout(location = 1) in vec4 a_normal_cone;  // snorm16, normalized by the VAO
layout(location = 2) in vec4 a_color;        // unorm8 sRGB
layout(location = 7) in float a_splat_radius;  // the disc drawn, not the bound
out Node {
  vec3 center;
  float radius;
  vec3 normal;
  float cone_cos;
  vec3 color;
  float object;
} v_node;
void main() {
  v_node.center = object_point(a_center);
  // Alpha 0: a hidden node (a class filtered out, coloring.hpp), no splat.
  v_node.radius = a_color.a < 0.5 || clipped(v_node.center)
                      ? 0.0
                      : a_splat_radius * a_object.x * u_radius_scale;
  v_node.normal = object_normal(a_normal_cone.xyz);
  v_node.cone_cos = object_cone(a_normal_cone.w);
  v_node.color = srgb_to_linear(a_color.rgb);
  v_node.object = a_object.w;
}
)";

// Geometry stage of the disc modes: one quad per node in the disc's plane, so
// the rasterizer interpolates a perspective-correct depth per fragment. A node
// with a tight normal cone is a disc oriented by its normal; a node whose cone
// is wider than ~45 degrees (coarse interior nodes) faces the eye, as QSplat's
// round splats do. u_depth_offset (in radii) pushes the quad away from the eye
// for the visibility pass of the high-quality mode.
inline constexpr const char* kSplatGeometry = R"(
layout(points) in;
#ifdef SPLAT_LIT
layout(triangle_strip, max_vertices = 3) out;
#else
layout(triangle_strip, max_vertices = 4) out;
#endif
in Node {
  vec3 center;
  float radius;
  vec3 normal;
  float cone_cos;
  vec3 color;
  float object;
} g_node[];
uniform float u_depth_offset;
out vec2 f_uv;
#ifdef SPLAT_LIT
flat out vec3 f_color;  // lit, sRGB: the fragment stage only tests the disc
#else
out vec3 f_pos;
flat out vec3 f_normal;
flat out vec3 f_color;
#endif
#ifdef SPLAT_ID
flat out float f_object;
#endif
void main() {
  vec3 c = g_node[0].center;
  float r = g_node[0].radius;
  vec3 to_eye = -c;
  float dist = length(to_eye);
  vec3 e = dist > 0.0 ? to_eye / dist : vec3(0.0, 0.0, 1.0);
  float nl = length(g_node[0].normal);
  vec3 n = nl > 1e-4 ? g_node[0].normal / nl : e;
  float cc = g_node[0].cone_cos;
  if (r <= 0.0 || cone_faces_away(n, cc, e)) return;

  // Grow splats that would cover less than u_min_radius_px (they could fall
  // between pixel centres and leave holes in a far-away surface).
  float view_depth = max(-(u_view * vec4(c, 1.0)).z, 1e-6);
  float r_px = r * u_proj[1][1] * 0.5 * u_viewport_h / view_depth;
  if (r_px < u_min_radius_px) r *= u_min_radius_px / max(r_px, 1e-6);

  vec3 d = cc < 0.7 ? e : n;
  vec3 a = abs(d.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 u = normalize(cross(d, a));
  vec3 w = cross(d, u);
  vec3 base = c - e * (u_depth_offset * r);
  mat4 vp = u_proj * u_view;
#ifdef SPLAT_LIT
  // The whole splat has one normal, so it is lit once, at its centre.
  vec3 lit = linear_to_srgb(shade(g_node[0].color, n, c));
#endif
#ifdef SPLAT_LIT
  // One triangle whose inscribed circle is the unit disc: 30 % more area
  // than the quad, but half the primitives to set up and rasterize.
  const int kCorners = 3;
  const vec2 corners[3] = vec2[3](vec2(-1.7320508, -1.0), vec2(1.7320508, -1.0), vec2(0.0, 2.0));
#else
  const int kCorners = 4;
  const vec2 corners[4] = vec2[4](vec2(-1.0, -1.0), vec2(1.0, -1.0), vec2(-1.0, 1.0), vec2(1.0, 1.0));
#endif
  for (int i = 0; i < kCorners; ++i) {
    vec3 p = base + r * (corners[i].x * u + corners[i].y * w);
    gl_Position = vp * vec4(p, 1.0);
    f_uv = corners[i];
#ifdef SPLAT_LIT
    f_color = lit;
#else
    f_pos = p;
    f_normal = n;
    f_color = g_node[0].color;
#endif
#ifdef SPLAT_ID
    f_object = g_node[0].object;
#endif
    EmitVertex();
  }
  EndPrimitive();
}
)";

// Fast mode: the disc, lit once per splat by the geometry stage (SPLAT_LIT).
inline constexpr const char* kFastFragment = R"(
in vec2 f_uv;
flat in vec3 f_color;
layout(location = 0) out vec4 o_color;
void main() {
  if (dot(f_uv, f_uv) > 1.0 || faded_out()) discard;
  o_color = vec4(f_color, 1.0);
}
)";

// Object ids: the disc in the index of its object, 8 bits a channel (exact
// in float up to 2^24 objects). The geometry stage is fast mode's
// (SPLAT_LIT: the same triangle and disc test), so an object covers exactly
// the pixels it covers there.
inline constexpr const char* kObjectIdFragment = R"(
in vec2 f_uv;
flat in float f_object;
layout(location = 0) out vec4 o_color;
void main() {
  if (dot(f_uv, f_uv) > 1.0 || faded_out()) discard;
  uint id = uint(f_object);
  o_color = vec4(float(id & 255u), float((id >> 8) & 255u), float((id >> 16) & 255u), 255.0) / 255.0;
}
)";

// High quality, pass 1 (visibility): depth of the discs only.
inline constexpr const char* kVisibilityFragment = R"(
in vec2 f_uv;
void main() {
  if (dot(f_uv, f_uv) > 1.0 || faded_out()) discard;
}
)";

// High quality, pass 2 (attributes): every disc fragment within the depth
// offset of the visible surface adds its Gaussian-weighted linear color and
// (eye-facing) normal; additive blending sums them.
inline constexpr const char* kAttributeFragment = R"(
in vec2 f_uv;
in vec3 f_pos;
flat in vec3 f_normal;
flat in vec3 f_color;
layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_normal;
void main() {
  float q = dot(f_uv, f_uv);
  if (q > 1.0 || faded_out()) discard;
  float w = exp(-3.0 * q);
  vec3 n = dot(f_normal, f_pos) > 0.0 ? -f_normal : f_normal;
  o_color = vec4(f_color * w, w);
  o_normal = vec4(n * w, 0.0);
}
)";

// High quality, pass 3 (normalization + deferred shading): a full-screen
// triangle divides the sums by the weight and lights each pixel with the
// blended normal at the position reconstructed from the visibility depth.
inline constexpr const char* kFullscreenVertex = R"(
out vec2 f_ndc;
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  f_ndc = p * 2.0 - 1.0;
  gl_Position = vec4(f_ndc, 0.0, 1.0);
}
)";

inline constexpr const char* kNormalizeFragment = R"(
layout(binding = 0) uniform sampler2D u_accum_color;
layout(binding = 1) uniform sampler2D u_accum_normal;
layout(binding = 2) uniform sampler2D u_depth;
uniform mat4 u_inv_view_proj;
in vec2 f_ndc;
layout(location = 0) out vec4 o_color;
void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 acc = texelFetch(u_accum_color, px, 0);
  if (acc.a <= 1e-6) discard;  // no splat here: the cleared background stays
  vec3 albedo = acc.rgb / acc.a;
  vec3 n = texelFetch(u_accum_normal, px, 0).xyz;
  float z = texelFetch(u_depth, px, 0).r;
  vec4 p = u_inv_view_proj * vec4(f_ndc, z * 2.0 - 1.0, 1.0);
  vec3 pos = p.xyz / p.w;  // relative to the eye
  float nl = length(n);
  n = nl > 1e-6 ? n / nl : normalize(-pos);
  o_color = vec4(linear_to_srgb(shade(albedo, n, pos)), 1.0);
}
)";

// Eye-dome lighting (Boucheny, "Interactive Scientific Visualization of
// Large Datasets", 2009; the look of Potree and CloudCompare): a pixel
// behind its neighbours is darkened by how far behind, in log depth, so
// depth edges and silhouettes read without normals. Drawn over the frame
// with a multiplying blend (dst * shade); reads the depth only. A
// background pixel next to a point takes the largest response, a dark
// outline around the cloud.
inline constexpr const char* kEyeDomeFragment = R"(
layout(binding = 0) uniform sampler2D u_depth;
uniform float u_near;       // eye depths of the clip planes
uniform float u_far;
uniform int u_perspective;
uniform float u_strength;   // 1: Potree's default
uniform float u_radius;     // pixels to the neighbours
layout(location = 0) out vec4 o_color;
// log2 of the eye depth at pixel px; 0 for the background.
float log_depth(ivec2 px) {
  px = clamp(px, ivec2(0), textureSize(u_depth, 0) - 1);
  float d = texelFetch(u_depth, px, 0).r;
  if (d >= 1.0) return 0.0;
  float z = u_perspective == 1
                ? 2.0 * u_near * u_far / (u_far + u_near - (2.0 * d - 1.0) * (u_far - u_near))
                : u_near + d * (u_far - u_near);
  return log2(max(z, 1e-30)) + 64.0;  // > 0 for every depth a float holds
}
void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  float here = log_depth(px);
  const vec2 kNeighbours[8] = vec2[8](vec2(1, 0), vec2(0.7071, 0.7071), vec2(0, 1),
                                      vec2(-0.7071, 0.7071), vec2(-1, 0), vec2(-0.7071, -0.7071),
                                      vec2(0, -1), vec2(0.7071, -0.7071));
  float sum = 0.0;
  for (int i = 0; i < 8; ++i) {
    float there = log_depth(px + ivec2(round(kNeighbours[i] * u_radius)));
    if (there == 0.0) continue;  // the background darkens nothing
    sum += here == 0.0 ? 100.0 : max(0.0, here - there);
  }
  if (sum == 0.0) discard;
  float shade = exp(-sum / 8.0 * 300.0 * u_strength);
  o_color = vec4(shade, shade, shade, 1.0);
}
)";

// Fixed-size mode: square (or, from 3 px, round) screen-space points.
inline constexpr const char* kFixedVertex = R"(
layout(location = 0) in vec3 a_center;
layout(location = 1) in vec4 a_normal_cone;
layout(location = 2) in vec4 a_color;
layout(location = 7) in float a_splat_radius;
uniform float u_point_size;
out vec3 f_pos;
flat out vec3 f_normal;
flat out vec3 f_color;
flat out float f_size;  // the point's diameter in pixels
void main() {
  vec3 c = object_point(a_center);
  vec3 e = normalize(-c);
  vec3 normal = object_normal(a_normal_cone.xyz);
  float nl = length(normal);
  vec3 n = nl > 1e-4 ? normal / nl : e;
  f_pos = c;
  f_normal = n;
  f_color = srgb_to_linear(a_color.rgb);
  // At least the splat's footprint: points that leave gaps at this distance
  // would let what lies behind show through (issue 30).
  float r = a_splat_radius * a_object.x * u_radius_scale;
  float view_depth = max(-(u_view * vec4(c, 1.0)).z, 1e-6);
  float footprint = 2.0 * r * u_proj[1][1] * 0.5 * u_viewport_h / view_depth;
  gl_PointSize = clamp(max(u_point_size, footprint), 1.0, 64.0);
  f_size = gl_PointSize;
  // Outside the clip volume = not drawn.
  gl_Position = a_color.a < 0.5 || clipped(c) || cone_faces_away(n, object_cone(a_normal_cone.w), e)
                    ? vec4(2.0, 2.0, 2.0, 1.0)
                                                        : u_proj * u_view * vec4(c, 1.0);
}
)";

inline constexpr const char* kFixedFragment = R"(
uniform float u_point_size;
in vec3 f_pos;
flat in vec3 f_normal;
flat in vec3 f_color;
flat in float f_size;
layout(location = 0) out vec4 o_color;
void main() {
  if (f_size >= 3.0 && length(gl_PointCoord - vec2(0.5)) > 0.5) discard;
  if (faded_out()) discard;
  o_color = vec4(linear_to_srgb(shade(f_color, f_normal, f_pos)), 1.0);
}
)";

}  // namespace treecut::splat::shaders
