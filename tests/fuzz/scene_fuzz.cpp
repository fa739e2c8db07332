// libFuzzer target: the scene file parser (parse_scene_text, the path of
// parse_scene_file after the read). Anything malformed must be an InputError
// naming FILE:LINE; any other exception, a sanitizer report or an accepted
// description that breaks its contract (no objects, an object naming no
// declaration, a transform that is not finite or whose inverse is not one)
// is a crash. Model lines name files that must exist: the fuzzer's names
// almost never do, so it mostly explores the syntax and the transforms.
// Run by .ci/fuzz, seeded from tests/fuzz/scene-seeds.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <glm/mat4x4.hpp>
#include <string>
#include <string_view>

#include "treecut/error.hpp"
#include "treecut/scene.hpp"
#include "treecut/tools/scene_generate.hpp"

namespace {

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "scene_fuzz: %s\n", what.c_str());
  std::abort();
}

// world * inverse within a tolerance relative to the matrix's scale.
bool inverse_holds(const glm::mat4& m, const glm::mat4& inv) {
  const glm::mat4 p = m * inv;
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      if (!std::isfinite(m[c][r]) || !std::isfinite(inv[c][r])) return false;
      if (std::abs(p[c][r] - (c == r ? 1.0f : 0.0f)) > 1e-2f) return false;
    }
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  treecut::SceneParseOptions options;
  options.max_objects = 4096;  // the limit's own check, without a million objects per input
  static const treecut::SceneGenerator generator = treecut::tools::scene_generator();
  options.generator = generator;
  treecut::SceneDescription d;
  try {
    d = treecut::parse_scene_text(text, "fuzz.scene", options);
  } catch (const treecut::InputError& e) {
    if (std::string_view(e.what()).find("fuzz.scene") == std::string_view::npos) {
      fail(std::string("an error that names no file: ") + e.what());
    }
    return 0;
  }
  if (d.objects.empty()) fail("accepted a scene without objects");
  if (d.objects.size() > options.max_objects) fail("more objects than the limit");
  for (const treecut::SceneObject& o : d.objects) {
    if (o.model >= d.models.size()) fail("an object names no model declaration");
    if (o.file >= d.files.size()) fail("an object names no file");
    // Badly conditioned but invertible transforms may pass; only a
    // non-finite one, or an inverse that is not one at all, is a bug.
    const float scale = std::abs(o.world[0][0]) + std::abs(o.world[1][1]) + std::abs(o.world[2][2]);
    if (!std::isfinite(scale)) fail("a non-finite transform was accepted");
    if (scale > 1e-3f && scale < 1e3f && !inverse_holds(o.world, o.world_inverse)) {
      fail("world_inverse is not the inverse of world");
    }
  }
  return 0;
}
