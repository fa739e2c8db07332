// The viewer's model loading (drag and drop, the O key, the HUD field and the
// script's `open`): a model is opened (its cache, or a PLY and the build) on a
// background thread while the window keeps drawing the old one. One load at
// a time: a newer one asks the older to stop (at its next progress report)
// and the older one's result is discarded.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "viewer.hpp"

namespace treecut::cli {

/// What a finished load hands to the render thread.
struct LoadedModel {
  std::string file;            ///< as asked for ("" = the generated default model)
  std::optional<Scene> scene;  ///< the model, or empty after a failure
  std::string error;           ///< one line naming the file and the reason
  bool input_error = false;    ///< a bad or missing file (exit 2 in a script), else 1
};

/// Where a running load is, for the HUD.
struct LoadProgress {
  std::string file;
  std::string stage;  ///< "read", "attributes", "hierarchy", "cache" or "" (not yet known)
  std::size_t done = 0, total = 0;
};

class ModelLoader {
 public:
  ModelLoader() = default;
  ModelLoader(const ModelLoader&) = delete;
  ModelLoader& operator=(const ModelLoader&) = delete;
  /// Asks every load to stop and waits for them (std::jthread).
  ~ModelLoader();

  /// Render thread: starts opening `args.model` on a background thread; a
  /// load still running is asked to stop and its result will never be taken.
  void start(const SceneArgs& args);
  /// Render thread: the result of the latest load once it finished (once).
  std::optional<LoadedModel> take();
  /// Render thread: the latest load while it runs.
  [[nodiscard]] std::optional<LoadProgress> progress() const;
  [[nodiscard]] bool busy() const { return job_ != nullptr; }

 private:
  struct Job {
    std::mutex mutex;
    LoadProgress progress;              // under mutex
    std::optional<LoadedModel> result;  // under mutex, set once
    std::atomic<bool> finished{false};
  };
  static void run(std::stop_token stop, const SceneArgs& args, Job& job);
  void reap();

  std::shared_ptr<Job> job_;  // the latest load, until taken
  // Threads of every load not yet joined, the latest last; a stopped one is
  // joined once it has finished (never blocking the window).
  struct Worker {
    std::shared_ptr<Job> job;
    std::jthread thread;
  };
  std::vector<Worker> workers_;
};

}  // namespace treecut::cli
