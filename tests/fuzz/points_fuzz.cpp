// libFuzzer target: the point file readers besides PLY, as open_model
// chooses them by the first bytes: LAS (load_las_from_memory, the reader
// load_las uses on a file) for "LASF", PCD when it looks like one (whole and
// in batches: PcdReader must give what the whole read gives), else the
// text cloud reader (XYZ, PTS, CSV). Anything malformed must be an InputError; any other exception,
// a sanitizer report or an accepted point set that breaks the PointSet contract (a LAS with another
// count than its header declares) is a crash. Small accepted inputs also go through attributes and
// the build. Run by .ci/fuzz, seeded with the files points_seeds writes.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "fuzz_checks.hpp"
#include "treecut/error.hpp"

namespace {

constexpr std::size_t kMaxBuildPoints = 2000;

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "points_fuzz: %s\n", what.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  treecut::LasLoadReport report;
  treecut::PointSet points;
  bool las = false;
  long long whole = -1;
  bool far = false;
  try {
    points = treecut::fuzz::load_point_bytes(bytes, report, las, [&](const std::string& w) {
      far = far || treecut::fuzz::about_far_points(w);
    });
    whole = static_cast<long long>(points.size());
  } catch (const treecut::InputError& e) {
    far = far || treecut::fuzz::about_far_points(e.what());
  }
  // A PCD in batches of 3 records (PcdReader): what the whole read gives.
  if (!las && treecut::looks_like_pcd(bytes)) {
    if (std::string why = treecut::fuzz::check_batches<treecut::PcdReader>(bytes, whole, far, 3);
        !why.empty())
      fail(why);
  }
  if (whole < 0) return 0;
  if (std::string why = treecut::fuzz::check_point_set(points); !why.empty()) fail(why);
  if (las && points.size() != report.info.point_count) fail("loaded another count than declared");
  if (points.size() <= kMaxBuildPoints) {
    if (std::string why = treecut::fuzz::check_builds(std::move(points)); !why.empty()) fail(why);
  }
  return 0;
}
