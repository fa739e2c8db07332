// Error attribution of the Feedback Stage: whatever a strategy throws on the
// stage thread (also `throw 42`) becomes one StrategyError that names the
// strategy and where it came from (built in, or the plugin file), so the
// render thread can report it in one line and go on. See
// treecut/feedback_stage.hpp and docs/plugin-guide.md.
#include <cxxabi.h>

#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <typeinfo>
#include <utility>

#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"

namespace treecut {
namespace {

// The name of the type of the exception being handled ("int", "std::string").
std::string current_exception_type() {
  const std::type_info* t = abi::__cxa_current_exception_type();
  if (t == nullptr) return "unknown";
  int status = 0;
  char* demangled = abi::__cxa_demangle(t->name(), nullptr, nullptr, &status);
  std::string name = status == 0 && demangled != nullptr ? demangled : t->name();
  std::free(demangled);
  return name;
}

}  // namespace

std::string describe_strategy(std::string_view name, std::string_view origin) {
  std::string d = "strategy '" + std::string(name) + "'";
  if (origin == "built-in") {
    d += " (built-in)";
  } else if (!origin.empty()) {
    d += " (plugin " + std::string(origin) + ")";
  }
  return d;
}

StrategyError::StrategyError(std::string strategy, std::string origin, const std::string& problem)
    : std::runtime_error(describe_strategy(strategy, origin) + ": " + problem),
      strategy_(std::move(strategy)),
      origin_(std::move(origin)) {}

// Stage thread, inside a catch handler: whatever the strategy threw (also
// `throw 42`) becomes one StrategyError naming it and its plugin; nothing
// escapes this thread (no terminate).
void FeedbackStage::Impl::fail(Outbox& out) {
  std::string problem;
  try {
    throw;
  } catch (const std::exception& e) {
    problem = out.invalid_cut ? e.what() : "threw " + current_exception_type() + ": " + e.what();
  } catch (...) {
    problem = "threw an exception of type " + current_exception_type();
  }
  const Strategy* s = scene_ ? (object_strategies_.empty() ? nullptr : object_strategies_[0].get())
                             : strategy_.get();
  const std::string_view name = s != nullptr ? s->name() : std::string_view("?");
  const std::string origin = s != nullptr ? s->origin() : std::string();
  try {
    out.error = std::make_exception_ptr(StrategyError(std::string(name), origin, problem));
  } catch (...) {
    out.error = std::current_exception();  // bad_alloc while describing it
  }
  out.ready = false;
  // An Evolve strategy may have left its cut half-changed: the next
  // iteration starts again from the front list.
  cut_stale_ = true;
}

}  // namespace treecut
