// libFuzzer target: PLY import through our header/body guard and OpenMesh
// (load_ply_from_memory, the same path as load_ply), whole and in batches
// (PlyReader, which must give what the whole read gives). Anything malformed must
// be an InputError; any other exception, a sanitizer report or an accepted
// point set that breaks the PointSet contract is a crash. Small accepted
// inputs also go through attributes and the hierarchy build.
// Run by .ci/fuzz, seeded from ../shared/ply-corpus.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "fuzz_checks.hpp"
#include "treecut/error.hpp"
#include "treecut/ply.hpp"

namespace {

// Above this many points the build costs more than it finds.
constexpr std::size_t kMaxBuildPoints = 2000;

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "ply_fuzz: %s\n", what.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  treecut::PlyLoadReport report;
  treecut::PointSet points;
  long long whole = -1;
  bool far = false;
  const auto note = [&](const std::string& w) { far = far || treecut::fuzz::about_far_points(w); };
  try {
    points = treecut::load_ply_from_memory(bytes, "fuzz.ply", &report, note);
    whole = static_cast<long long>(points.size());
  } catch (const treecut::InputError& e) {
    // Rejected with a message: what malformed input must get.
    note(e.what());
  }
  // In batches of 3 rows (PlyReader): what the whole read gives.
  if (std::string why = treecut::fuzz::check_batches<treecut::PlyReader>(bytes, whole, far, 3);
      !why.empty())
    fail(why);
  if (whole < 0) return 0;
  if (std::string why = treecut::fuzz::check_point_set(points); !why.empty()) fail(why);
  if (points.size() + report.dropped_nonfinite != report.vertices_in_file) {
    fail("loaded + dropped points differ from the header's count");
  }
  if (points.size() <= kMaxBuildPoints) {
    if (std::string why = treecut::fuzz::check_builds(std::move(points)); !why.empty()) fail(why);
  }
  return 0;
}
