#include "test_support.hpp"

#include <gtest/gtest.h>

namespace treecut::test {

std::optional<std::filesystem::path> shared_dir() {
  std::filesystem::path p = TREECUT_SHARED_DIR;
  if (const char* env = std::getenv("TREECUT_SHARED_DIR")) p = env;
  std::error_code ec;
  if (std::filesystem::is_directory(p, ec)) return p;
  return std::nullopt;
}

std::optional<std::filesystem::path> shared_asset(const std::string& name) {
  auto dir = shared_dir();
  if (!dir) return std::nullopt;
  auto p = *dir / "assets" / name;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(p, ec)) return std::nullopt;
  return p;
}

std::filesystem::path scratch_dir(const std::string& name) {
  auto p = std::filesystem::path(TREECUT_BINARY_DIR) / "test-scratch" / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

}  // namespace treecut::test
