// The viewer's background model loader (demo/viewer_loader.cpp): a load runs
// on its own thread and is taken by the render thread once finished; its
// progress names the file from the start; a failure is one line naming the
// file (a bad or missing file marked as input error); a newer load replaces
// an older one (only the newest result is ever handed over); a loader
// destroyed mid-load stops it and leaves no partial cache. GL-free.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <thread>

#include "test_support.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/generate.hpp"
#include "viewer_loader.hpp"

namespace treecut::cli {
namespace {

namespace fs = std::filesystem;

class ViewerLoader : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One folder per process: ctest runs each test of this file as its own
    // process, in parallel, and each would otherwise empty the others' folder.
    dir_ = new fs::path(test::scratch_dir("viewer_loader/" + std::to_string(::getpid())));
    // Caches go to the scratch folder, not the user's.
    setenv("XDG_CACHE_HOME", (*dir_ / "cache").c_str(), 1);
    save_ply(*dir_ / "small.ply", tools::generate_model(tools::ModelKind::Sphere, 2000, 1));
    save_ply(*dir_ / "large.ply", tools::generate_model(tools::ModelKind::Terrain, 400000, 2));
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(*dir_, ec);
    delete dir_;
    dir_ = nullptr;
  }
  static SceneArgs args(const std::string& name) {
    SceneArgs a;
    a.model = (*dir_ / name).string();
    return a;
  }
  // Polls as the viewer's frames do; a bound (not a measurement) so that a
  // lost result fails instead of hanging.
  static LoadedModel wait(ModelLoader& loader) {
    for (int i = 0; i < 120000; ++i) {
      if (std::optional<LoadedModel> r = loader.take()) return std::move(*r);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ADD_FAILURE() << "no result";
    return {};
  }
  static fs::path* dir_;
};
fs::path* ViewerLoader::dir_ = nullptr;

TEST_F(ViewerLoader, LoadsAModelOnItsThreadAndHandsItOverOnce) {
  ModelLoader loader;
  EXPECT_FALSE(loader.busy());
  loader.start(args("small.ply"));
  EXPECT_TRUE(loader.busy());
  const std::optional<LoadProgress> p = loader.progress();
  ASSERT_TRUE(p.has_value()) << "a running load shows in the HUD from the start";
  EXPECT_EQ(p->file, args("small.ply").model);
  const LoadedModel m = wait(loader);
  EXPECT_EQ(m.file, args("small.ply").model);
  ASSERT_TRUE(m.scene.has_value()) << m.error;
  EXPECT_TRUE(m.error.empty());
  EXPECT_EQ(m.scene->label, "small.ply");
  EXPECT_GT(m.scene->hierarchy->node_count(), 2000u);
  EXPECT_FALSE(loader.busy());
  EXPECT_FALSE(loader.take().has_value()) << "handed over once";
  EXPECT_FALSE(loader.progress().has_value());
}

TEST_F(ViewerLoader, AFailureIsOneLineNamingTheFile) {
  ModelLoader loader;
  loader.start(args("missing.ply"));
  const LoadedModel missing = wait(loader);
  EXPECT_FALSE(missing.scene.has_value());
  EXPECT_TRUE(missing.input_error);
  EXPECT_NE(missing.error.find(args("missing.ply").model), std::string::npos) << missing.error;
  EXPECT_EQ(missing.error.find('\n'), std::string::npos) << missing.error;

  {
    std::ofstream bad(*dir_ / "bad.ply");
    bad << "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n";
  }
  loader.start(args("bad.ply"));
  const LoadedModel bad = wait(loader);
  EXPECT_FALSE(bad.scene.has_value());
  EXPECT_TRUE(bad.input_error);
  EXPECT_NE(bad.error.find(args("bad.ply").model), std::string::npos) << bad.error;
}

TEST_F(ViewerLoader, ANewerLoadReplacesARunningOne) {
  ModelLoader loader;
  loader.start(args("large.ply"));
  loader.start(args("small.ply"));
  EXPECT_EQ(loader.progress()->file, args("small.ply").model);
  const LoadedModel m = wait(loader);
  EXPECT_EQ(m.file, args("small.ply").model) << "only the newest load is handed over";
  ASSERT_TRUE(m.scene.has_value()) << m.error;
  EXPECT_EQ(m.scene->label, "small.ply");
  EXPECT_FALSE(loader.take().has_value());
  // The replaced load never comes back, however long it ran.
  loader.start(args("small.ply"));
  EXPECT_EQ(wait(loader).file, args("small.ply").model);
}

TEST_F(ViewerLoader, DestroyedMidLoadItStopsAndLeavesNoPartialCache) {
  fs::remove_all(*dir_ / "cache");
  {
    ModelLoader loader;
    loader.start(args("large.ply"));
  }  // stops the load (at its next progress report) and joins it
  // Either the load was stopped before its cache was written, or it finished
  // and the cache is whole: never a temporary beside it.
  if (fs::exists(*dir_ / "cache")) {
    for (const auto& e : fs::recursive_directory_iterator(*dir_ / "cache")) {
      if (e.is_regular_file()) {
        EXPECT_EQ(e.path().extension(), ".tch") << e.path();
      }
    }
  }
}

}  // namespace
}  // namespace treecut::cli
