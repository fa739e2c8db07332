#include "viewer_loader.hpp"

#include <exception>
#include <filesystem>
#include <utility>

#include "treecut/error.hpp"

namespace treecut::cli {

namespace {

// Thrown from the progress callback of a load that was asked to stop: it
// unwinds open_model (whose outputs are atomic: an unfinished cache is removed).
struct Stopped {};

}  // namespace

ModelLoader::~ModelLoader() {
  for (Worker& w : workers_) w.thread.request_stop();
  // The jthreads join as workers_ is destroyed.
}

void ModelLoader::run(std::stop_token stop, const SceneArgs& args, Job& job) {
  LoadedModel out;
  out.file = args.model;
  try {
    out.scene = load_scene(args, [&](std::string_view stage, std::size_t done, std::size_t total) {
      if (stop.stop_requested()) throw Stopped{};
      std::lock_guard lock(job.mutex);
      job.progress.stage = stage;
      job.progress.done = done;
      job.progress.total = total;
    });
  } catch (const Stopped&) {
    out.error = "stopped";
  } catch (const InputError& e) {
    out.error = e.what();
    out.input_error = true;
  } catch (const std::exception& e) {
    const std::string what = e.what();
    // Name the file when the reason does not (an allocation failure, say).
    out.error = what.find(args.model) == std::string::npos && !args.model.empty()
                    ? args.model + ": " + what
                    : what;
  }
  {
    std::lock_guard lock(job.mutex);
    job.result = std::move(out);
  }
  job.finished.store(true, std::memory_order_release);
}

void ModelLoader::start(const SceneArgs& args) {
  for (Worker& w : workers_) w.thread.request_stop();
  job_ = std::make_shared<Job>();
  job_->progress.file = args.model;
  Worker w;
  w.job = job_;
  // The thread gets its own copies: the arguments and a share of the job.
  w.thread = std::jthread([args, job = job_](std::stop_token stop) { run(stop, args, *job); });
  workers_.push_back(std::move(w));
  reap();
}

void ModelLoader::reap() {
  // Join what has finished (instant); a stopped load still running stays.
  for (std::size_t i = 0; i < workers_.size();) {
    if (workers_[i].job->finished.load(std::memory_order_acquire) && workers_[i].job != job_) {
      workers_[i].thread.join();
      workers_.erase(workers_.begin() + static_cast<std::ptrdiff_t>(i));
    } else {
      ++i;
    }
  }
}

std::optional<LoadedModel> ModelLoader::take() {
  if (job_ == nullptr || !job_->finished.load(std::memory_order_acquire)) {
    if (!workers_.empty()) reap();
    return std::nullopt;
  }
  std::optional<LoadedModel> out;
  {
    std::lock_guard lock(job_->mutex);
    out = std::move(job_->result);
  }
  job_.reset();
  reap();
  return out;
}

std::optional<LoadProgress> ModelLoader::progress() const {
  if (job_ == nullptr) return std::nullopt;
  std::lock_guard lock(job_->mutex);
  return job_->progress;
}

}  // namespace treecut::cli
