// PLY import against the shared files: every entry of ply-corpus/MANIFEST.tsv
// is one test named after its file, and the four real models in assets/ load
// with their published counts. The project's own corpus (tests/ply-corpus)
// runs the same way, through load_ply and through `treecut build`.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/ply.hpp"

namespace {

using treecut::InputError;
using treecut::load_ply;
using treecut::PlyLoadReport;
using treecut::PointSet;

struct CorpusEntry {
  std::string file;
  std::string expect;  // ok | error | nocrash
  std::size_t points = 0;
  std::string what;
};

// The rows of a MANIFEST.tsv below its column names, each split into COLUMNS
// fields at tabs (the last field keeps the rest of the line; missing ones stay
// empty). Both corpora's manifests share this layout.
std::vector<std::vector<std::string>> manifest_rows(const std::filesystem::path& manifest,
                                                    std::size_t columns) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(manifest);
  std::string line;
  std::getline(in, line);  // column names
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::istringstream fields(line);
    std::vector<std::string> row(columns);
    for (std::size_t i = 0; i < columns; ++i)
      std::getline(fields, row[i], i + 1 < columns ? '\t' : '\n');
    rows.push_back(std::move(row));
  }
  return rows;
}

// A test's name from its file's: anything but a letter or digit becomes '_'.
std::string name_of_file(const std::string& file) {
  std::string name;
  for (char c : file) name += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return name;
}

// The InputError loading PATH gives; a test failure and nothing when it loads.
std::optional<std::string> load_error(const std::filesystem::path& path,
                                      const treecut::WarningSink& warn) {
  try {
    load_ply(path, nullptr, warn);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "loaded without an error";
  return std::nullopt;
}

std::vector<CorpusEntry> read_manifest() {
  std::vector<CorpusEntry> entries;
  auto dir = treecut::test::shared_dir();
  if (!dir) return entries;
  for (const auto& row : manifest_rows(*dir / "ply-corpus" / "MANIFEST.tsv", 4)) {
    CorpusEntry entry{row[0], row[1], 0, row[3]};
    if (entry.expect == "ok") entry.points = std::stoul(row[2]);
    entries.push_back(entry);
  }
  return entries;
}

std::string test_name(const testing::TestParamInfo<CorpusEntry>& info) {
  return name_of_file(info.param.file);
}

class PlyCorpus : public testing::TestWithParam<CorpusEntry> {};

TEST_P(PlyCorpus, BehavesAsTheManifestSays) {
  const CorpusEntry& entry = GetParam();
  const auto path = *treecut::test::shared_dir() / "ply-corpus" / entry.file;
  SCOPED_TRACE(entry.file + ": " + entry.what);
  std::vector<std::string> warnings;
  auto warn = [&](const std::string& w) { warnings.push_back(w); };

  if (entry.expect == "ok") {
    PlyLoadReport report;
    PointSet points = load_ply(path, &report, warn);
    EXPECT_EQ(points.size(), entry.points);
    EXPECT_EQ(points.size() + report.dropped_nonfinite, report.vertices_in_file);
    for (const std::string& w : warnings) {
      EXPECT_EQ(w.rfind(path.string() + ": ", 0), 0u) << w;
      EXPECT_EQ(w.find('\n'), std::string::npos) << w;
    }
  } else if (entry.expect == "error") {
    if (const auto message = load_error(path, warn)) {
      EXPECT_EQ(message->rfind(path.string() + ": ", 0), 0u) << *message;
      EXPECT_NE(message->find(entry.file), std::string::npos) << *message;
      EXPECT_EQ(message->find('\n'), std::string::npos) << *message;
    }
  } else {
    ASSERT_EQ(entry.expect, "nocrash");
    try {
      PointSet points = load_ply(path, nullptr, warn);
      EXPECT_GT(points.size(), 0u);
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(entry.file), std::string::npos) << e.what();
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Manifest, PlyCorpus, testing::ValuesIn(read_manifest()), test_name);
// Without ../shared there are no parameters; PlyCorpusManifest says why.
GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(PlyCorpus);

TEST(PlyCorpusManifest, ListsEveryCorpusFile) {
  auto dir = treecut::test::shared_dir();
  if (!dir) GTEST_SKIP() << "../shared is absent: the corpus tests do not run";
  const auto entries = read_manifest();
  ASSERT_FALSE(entries.empty()) << "MANIFEST.tsv is missing or empty";
  std::size_t files = 0;
  for (const auto& f : std::filesystem::directory_iterator(*dir / "ply-corpus")) {
    if (f.path().extension() != ".ply") continue;
    ++files;
    const auto name = f.path().filename().string();
    EXPECT_TRUE(std::any_of(entries.begin(), entries.end(),
                            [&](const CorpusEntry& e) { return e.file == name; }))
        << name << " is not in MANIFEST.tsv";
  }
  EXPECT_EQ(files, entries.size());
}

// ---- the project's own corpus: tests/ply-corpus ----------------------------
//
// Files written for this project (real-world ways a PLY fails to match its
// header). MANIFEST.tsv has the shared corpus's columns plus `message`: the
// one warning an `ok` file gives (empty: none), or the text of an error.

struct ProjectEntry {
  std::string file;
  std::string expect;  // ok | error
  std::size_t points = 0;
  std::string what;
  std::string message;
};

std::filesystem::path project_corpus() {
  return std::filesystem::path(TREECUT_SOURCE_DIR) / "tests" / "ply-corpus";
}

std::vector<ProjectEntry> read_project_manifest() {
  std::vector<ProjectEntry> entries;
  for (const auto& row : manifest_rows(project_corpus() / "MANIFEST.tsv", 5)) {
    ProjectEntry entry{row[0], row[1], 0, row[3], row[4]};
    if (entry.expect == "ok") entry.points = std::stoul(row[2]);
    entries.push_back(entry);
  }
  return entries;
}

std::string project_test_name(const testing::TestParamInfo<ProjectEntry>& info) {
  return name_of_file(info.param.file);
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

class ProjectPlyCorpus : public testing::TestWithParam<ProjectEntry> {};

TEST_P(ProjectPlyCorpus, LoadsAsTheManifestSays) {
  const ProjectEntry& entry = GetParam();
  const auto path = project_corpus() / entry.file;
  SCOPED_TRACE(entry.file + ": " + entry.what);
  std::vector<std::string> warnings;
  auto warn = [&](const std::string& w) { warnings.push_back(w); };
  if (entry.expect == "ok") {
    PlyLoadReport report;
    const PointSet points = load_ply(path, &report, warn);
    EXPECT_EQ(points.size(), entry.points);
    if (entry.message.empty()) {
      EXPECT_TRUE(warnings.empty()) << warnings.front();
    } else {
      ASSERT_EQ(warnings.size(), 1u);
      EXPECT_EQ(warnings[0].rfind(path.string() + ": ", 0), 0u) << warnings[0];
      EXPECT_NE(warnings[0].find(entry.message), std::string::npos) << warnings[0];
    }
    // "without faces" in the warning is what the report and the points say.
    const bool lost = entry.message.find("without faces") != std::string::npos;
    EXPECT_EQ(report.faces_lost, lost);
    if (lost) {
      EXPECT_TRUE(points.triangles.empty());
    }
  } else {
    ASSERT_EQ(entry.expect, "error");
    if (const auto message = load_error(path, warn)) {
      EXPECT_EQ(message->rfind(path.string() + ": ", 0), 0u) << *message;
      EXPECT_NE(message->find(entry.message), std::string::npos) << *message;
      EXPECT_EQ(message->find('\n'), std::string::npos) << *message;
    }
    EXPECT_TRUE(warnings.empty()) << warnings.front();
  }
}

// The same files through `treecut build`: exit 0 with exactly one warning line,
// or exit 2 with exactly one line and no cache written.
TEST_P(ProjectPlyCorpus, BuildCommandReportsItOnOneLine) {
  const ProjectEntry& entry = GetParam();
  const auto path = project_corpus() / entry.file;
  const auto cache = treecut::test::scratch_dir("ply_corpus_cli_" + entry.file) / "out.tch";
  const auto r = treecut::test::run_treecut("build " + treecut::test::quote(path) + " -o " +
                                            treecut::test::quote(cache));
  const std::vector<std::string> lines = lines_of(r.out);
  if (entry.expect == "ok") {
    EXPECT_EQ(r.code, 0) << r.out;
    std::size_t warning_lines = 0;
    for (const std::string& line : lines) {
      if (line.rfind("warning: ", 0) != 0) continue;
      ++warning_lines;
      EXPECT_NE(line.find(entry.message), std::string::npos) << line;
    }
    EXPECT_EQ(warning_lines, entry.message.empty() ? 0u : 1u) << r.out;
    EXPECT_NE(r.out.find("points      " + std::to_string(entry.points) + "\n"), std::string::npos)
        << r.out;
    EXPECT_TRUE(std::filesystem::exists(cache));
  } else {
    EXPECT_EQ(r.code, 2) << r.out;
    ASSERT_EQ(lines.size(), 1u) << r.out;
    EXPECT_EQ(lines[0].rfind("treecut: " + path.string() + ": ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find(entry.message), std::string::npos) << lines[0];
    EXPECT_FALSE(std::filesystem::exists(cache));
  }
}

INSTANTIATE_TEST_SUITE_P(Manifest, ProjectPlyCorpus, testing::ValuesIn(read_project_manifest()),
                         project_test_name);

TEST(ProjectPlyCorpusManifest, ListsEveryCorpusFile) {
  const auto entries = read_project_manifest();
  ASSERT_FALSE(entries.empty()) << "tests/ply-corpus/MANIFEST.tsv is missing or empty";
  std::size_t files = 0;
  for (const auto& f : std::filesystem::directory_iterator(project_corpus())) {
    if (f.path().extension() != ".ply") continue;
    ++files;
    const auto name = f.path().filename().string();
    EXPECT_TRUE(std::any_of(entries.begin(), entries.end(),
                            [&](const ProjectEntry& e) { return e.file == name; }))
        << name << " is not in MANIFEST.tsv";
  }
  EXPECT_EQ(files, entries.size());
  for (const ProjectEntry& e : entries) {
    EXPECT_TRUE(e.expect == "ok" || e.expect == "error") << e.file << ": " << e.expect;
    if (e.expect == "error") {
      EXPECT_FALSE(e.message.empty()) << e.file;
    }
  }
}

TEST(PlySharedAssets, BunnyLoadsWithExactCounts) {
  TREECUT_REQUIRE_ASSET(path, "bun_zipper.ply");
  PlyLoadReport report;
  PointSet points = load_ply(path, &report);
  EXPECT_EQ(points.size(), 35947u);
  EXPECT_EQ(points.triangles.size(), 69451u);
  EXPECT_EQ(report.faces_in_file, 69451u);
  EXPECT_FALSE(points.has_normals());
  EXPECT_FALSE(points.has_colors());
}

TEST(PlySharedAssets, AsciiDragonLoadsWithExactCounts) {
  TREECUT_REQUIRE_ASSET(path, "dragon_vrip.ply");
  PointSet points = load_ply(path);
  EXPECT_EQ(points.size(), 437645u);
  EXPECT_EQ(points.triangles.size(), 871414u);
  EXPECT_FALSE(points.has_normals());
}

TEST(PlySharedAssets, BinaryDragonLoadsWithExactCountsAndNormals) {
  TREECUT_REQUIRE_ASSET(path, "dragon_vrip_normals.ply");
  PlyLoadReport report;
  PointSet points = load_ply(path, &report);
  EXPECT_EQ(points.size(), 437645u);
  EXPECT_EQ(points.triangles.size(), 871414u);
  ASSERT_TRUE(points.has_normals());
  EXPECT_TRUE(report.had_normals);
  for (const glm::vec3& n : points.normals) {
    const float length = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    // Unit, or zero for the isolated vertices the asset README mentions.
    ASSERT_TRUE(length == 0.0f || std::abs(length - 1.0f) < 1e-5f) << length;
  }
}

TEST(PlySharedAssets, LionLoadsWithColorsAndNormals) {
  TREECUT_REQUIRE_ASSET(path, "lion_takanawa.ply");
  PlyLoadReport report;
  PointSet points = load_ply(path, &report);
  EXPECT_EQ(points.size(), 341989u);
  EXPECT_TRUE(points.triangles.empty());
  ASSERT_TRUE(points.has_colors());
  ASSERT_TRUE(points.has_normals());
  EXPECT_TRUE(report.had_colors);
  // A photogrammetry cloud is not one flat colour.
  const bool varied = std::any_of(points.colors.begin(), points.colors.end(),
                                  [&](const glm::u8vec4& c) { return c != points.colors[0]; });
  EXPECT_TRUE(varied);
}

TEST(PlySharedAssets, AsciiAndBinaryDragonHaveTheSamePositionsAndFaces) {
  TREECUT_REQUIRE_ASSET(ascii_path, "dragon_vrip.ply");
  TREECUT_REQUIRE_ASSET(binary_path, "dragon_vrip_normals.ply");
  PointSet ascii = load_ply(ascii_path);
  PointSet binary = load_ply(binary_path);
  ASSERT_EQ(ascii.size(), binary.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < ascii.size(); ++i)
    differing += ascii.positions[i] != binary.positions[i];
  EXPECT_EQ(differing, 0u);
  EXPECT_EQ(ascii.triangles, binary.triangles);
}

}  // namespace
