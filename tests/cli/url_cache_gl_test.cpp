// A cache drawn from a URL (issue 45, item 2): its pages read by HTTP range
// requests from a server the test starts on 127.0.0.1 (support/
// range_server.py: python's http.server does not speak ranges), drawn as
// the file is; a slow server slows the pages and never a frame; a server
// that fails, stalls, ignores ranges or lies about them is one line naming
// the URL (at open: exit 2, nothing written; a page: the rest drawn).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/model_io.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/tools/generate.hpp"

namespace fs = std::filesystem;
using treecut::test::quote;
using treecut::test::run_treecut;

namespace {

// support/range_server.py serving ROOT, for the test's life.
class RangeServer {
 public:
  explicit RangeServer(const fs::path& root) {
    int out[2];
    if (::pipe(out) != 0) throw std::runtime_error("pipe");
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], 1);
      ::close(out[0]);
      const std::string script = std::string(TREECUT_SOURCE_DIR) + "/tests/support/range_server.py";
      ::execlp("python3", "python3", script.c_str(), root.c_str(), nullptr);
      ::_exit(127);
    }
    ::close(out[1]);
    std::FILE* f = ::fdopen(out[0], "r");
    if (f == nullptr || std::fscanf(f, "%d", &port_) != 1) port_ = 0;
    if (f != nullptr) std::fclose(f);
  }
  ~RangeServer() {
    ::kill(pid_, SIGTERM);
    ::waitpid(pid_, nullptr, 0);
  }
  RangeServer(const RangeServer&) = delete;
  RangeServer& operator=(const RangeServer&) = delete;
  [[nodiscard]] bool up() const { return port_ > 0; }
  // "http://127.0.0.1:PORT/MODE/NAME".
  [[nodiscard]] std::string url(const std::string& mode, const std::string& name) const {
    return "http://127.0.0.1:" + std::to_string(port_) + "/" + mode + "/" + name;
  }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
};

// A terrain of 100,000 points as DIR/terrain.tch (some twenty pages).
fs::path terrain_cache(const fs::path& dir) {
  const fs::path cache = dir / "terrain.tch";
  treecut::save_cache(treecut::build_from_points(treecut::tools::generate_model(
                          treecut::tools::ModelKind::Terrain, 100000, 1)),
                      {1, 2, 3}, cache);
  return cache;
}

std::string slurp(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// Column NAME of DIR/stats.csv.
std::vector<std::string> column(const fs::path& dir, const std::string& name) {
  std::ifstream in(dir / "stats.csv");
  std::string line;
  std::vector<std::string> values;
  int at = -1;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    for (std::string cell; std::getline(s, cell, ',');) cells.push_back(cell);
    if (at < 0) {
      for (std::size_t i = 0; i < cells.size(); ++i)
        if (cells[i] == name) at = static_cast<int>(i);
      if (at < 0) return values;
      continue;
    }
    values.push_back(static_cast<std::size_t>(at) < cells.size() ? cells[at] : "");
  }
  return values;
}

const std::string kRun = "--width 160 --height 96 --sync -s recursive ";

class UrlCache : public ::testing::Test {
 protected:
  void SetUp() override {
    // One folder a test: CTest runs them as parallel processes (one test
    // shrinks its file).
    dir_ =
        treecut::test::scratch_dir(std::string("url_cache_") +
                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    cache_ = terrain_cache(dir_);
    server_ = std::make_unique<RangeServer>(dir_);
    ASSERT_TRUE(server_->up()) << "no range server (python3 " << TREECUT_SOURCE_DIR
                               << "/tests/support/range_server.py)";
  }
  // Ranges from the middle of the file on: its later pages (the meta part
  // and the first page lie before them).
  [[nodiscard]] std::string later_pages() const {
    return std::to_string(fs::file_size(cache_) / 2);
  }
  fs::path dir_, cache_;
  std::unique_ptr<RangeServer> server_;
};

}  // namespace

TEST_F(UrlCache, AUrlIsDrawnAsTheFileIs) {
  const std::string frames = "--memory 2M --frames 12 --warmup 2 " + kRun;
  const auto file =
      run_treecut("render " + quote(cache_) + " " + frames + "-o " + quote(dir_ / "file"));
  ASSERT_EQ(file.code, 0) << file.out;
  const auto url = run_treecut("render " + server_->url("ok", "terrain.tch") + " " + frames +
                               "-o " + quote(dir_ / "url"));
  ASSERT_EQ(url.code, 0) << url.out;
  EXPECT_NE(url.out.find("(paged)"), std::string::npos) << url.out;
  const std::vector<std::string> loaded = column(dir_ / "url", "pages_loaded");
  ASSERT_EQ(loaded.size(), 12u);
  EXPECT_NE(loaded.back(), "0") << "no page read from the server";
  EXPECT_EQ(column(dir_ / "file", "pages_loaded"), loaded);
  EXPECT_EQ(column(dir_ / "file", "splats_drawn"), column(dir_ / "url", "splats_drawn"));
  for (const char* png : {"frame_00000.png", "frame_00011.png"}) {
    const std::string a = slurp(dir_ / "file" / png), b = slurp(dir_ / "url" / png);
    EXPECT_FALSE(a.empty()) << png;
    EXPECT_TRUE(a == b) << png << " differs between the file and its URL";
  }
}

// A scene file may name caches by URL: drawn from their pages as the same
// files beside it are; without a memory budget, refused in one line.
TEST_F(UrlCache, ASceneOfCachesByUrlIsDrawnAsItsFiles) {
  const std::string objects = "object t\nobject t translate 2.2 0 0\n";
  std::ofstream(dir_ / "file.scene") << "treecut-scene 1\nmodel t terrain.tch\n" << objects;
  std::ofstream(dir_ / "url.scene")
      << "treecut-scene 1\nmodel t " << server_->url("ok", "terrain.tch") << "\n"
      << objects;
  const std::string frames =
      "--memory 4M --frames 12 --warmup 2 --width 160 --height 96 --sync "
      "-s budget ";
  const auto file = run_treecut("render " + quote(dir_ / "file.scene") + " " + frames + "-o " +
                                quote(dir_ / "file"));
  ASSERT_EQ(file.code, 0) << file.out;
  const auto url = run_treecut("render " + quote(dir_ / "url.scene") + " " + frames + "-o " +
                               quote(dir_ / "url"));
  ASSERT_EQ(url.code, 0) << url.out;
  EXPECT_NE(url.out.find("pages     1 of 1 models drawn from their pages"), std::string::npos)
      << url.out;
  const std::vector<std::string> loaded = column(dir_ / "url", "pages_loaded");
  ASSERT_EQ(loaded.size(), 12u);
  EXPECT_NE(loaded.back(), "0") << "no page read from the server";
  EXPECT_EQ(column(dir_ / "file", "splats_drawn"), column(dir_ / "url", "splats_drawn"));
  const std::string a = slurp(dir_ / "file" / "frame_00011.png"),
                    b = slurp(dir_ / "url" / "frame_00011.png");
  EXPECT_FALSE(a.empty());
  EXPECT_TRUE(a == b) << "the scene by URL differs from its files";
  const auto refused = run_treecut("render " + quote(dir_ / "url.scene") +
                                   " --frames 2 --no-png -o " + quote(dir_ / "refused"));
  treecut::test::expect_failure(refused, 2, "a cache by URL is drawn from its pages");
  EXPECT_NE(refused.out.find("url.scene:2: model 't'"), std::string::npos) << refused.out;
  EXPECT_FALSE(fs::exists(dir_ / "refused"));
}

TEST_F(UrlCache, ASlowServerDelaysPagesNeverTheCaller) {
  treecut::PagingOptions o;
  o.memory_bytes = 8 << 20;
  const auto paged = treecut::PagedHierarchy::open(server_->url("slow", "terrain.tch"), o);
  std::vector<treecut::NodeId> hidden;
  for (const treecut::NodeId n : treecut::test::reachable(paged->hierarchy()))
    if (paged->hidden(n)) hidden.push_back(n);
  ASSERT_FALSE(hidden.empty());
  paged->request(std::span(hidden).first(1));
  // Each reply is 0.2 s late: what a frame does next finds nothing yet,
  // and does not wait for it.
  EXPECT_EQ(paged->publish(), 0u);
  EXPECT_GE(paged->stats().in_flight + paged->stats().requested, 1u);
  ASSERT_TRUE(paged->wait_idle(60000));
  EXPECT_GT(paged->publish(), 0u);
  EXPECT_TRUE(paged->take_problems().empty());
}

TEST_F(UrlCache, AServerThatFailsOrLiesIsRefusedInOneLine) {
  const struct {
    std::string mode, says;
  } cases[] = {
      {"fail", "reading bytes 0-0: HTTP 500"},
      {"no-ranges", "the server ignored the range (HTTP 200)"},
      {"wrong-range", "the server answered bytes 1-1"},
      {"shifted", "not a treecut cache"},
      {"ok/missing", "HTTP 404"},
  };
  for (const auto& c : cases) {
    const fs::path out = dir_ / ("out-" + c.mode.substr(0, c.mode.find('/')));
    const auto r = run_treecut("render " + server_->url(c.mode, "terrain.tch") + " --frames 2 " +
                               kRun + "--no-png -o " + quote(out));
    treecut::test::expect_failure(r, 2, c.says);
    EXPECT_NE(r.out.find(server_->url(c.mode, "terrain.tch")), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(out)) << c.mode;
  }
}

TEST_F(UrlCache, PagesAServerFailsOnAreNamedAndTheRestIsDrawn) {
  const std::string url = server_->url("fail-from/" + later_pages(), "terrain.tch");
  const fs::path out = dir_ / "fail-from";
  const auto r = run_treecut("render " + url + " --memory 2M --frames 4 " + kRun + "--no-png -o " +
                             quote(out));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning: " + url + ": page "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(": HTTP 500"), std::string::npos) << r.out;
  EXPECT_EQ(column(out, "splats_drawn").size(), 4u);
  const std::vector<std::string> loaded = column(out, "pages_loaded");
  ASSERT_FALSE(loaded.empty());
  EXPECT_NE(loaded.back(), "0") << "the pages before the middle were read";
}

TEST_F(UrlCache, APageTheServerStallsOnFailsAfterTheStallTimeout) {
  treecut::PagingOptions o;
  o.memory_bytes = 8 << 20;
  o.stall_ms = 1000;
  const auto paged =
      treecut::PagedHierarchy::open(server_->url("stall-from/" + later_pages(), "terrain.tch"), o);
  // The last hidden node's group: its pages lie in the file's second half.
  std::vector<treecut::NodeId> hidden;
  for (const treecut::NodeId n : treecut::test::reachable(paged->hierarchy()))
    if (paged->hidden(n)) hidden.push_back(n);
  ASSERT_FALSE(hidden.empty());
  paged->request(std::span(hidden).last(1));
  ASSERT_TRUE(paged->wait_idle(60000));
  const std::vector<std::string> problems = paged->take_problems();
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("nothing received for 1 s (the server stalled)"), std::string::npos)
      << problems[0];
  EXPECT_EQ(paged->stats().failed, 1u);
}

TEST_F(UrlCache, AFileChangedOnTheServerIsNamedNotACrash) {
  treecut::PagingOptions o;
  o.memory_bytes = 8 << 20;
  const auto paged = treecut::PagedHierarchy::open(server_->url("ok", "terrain.tch"), o);
  fs::resize_file(cache_, fs::file_size(cache_) / 2);
  treecut::test::load_every_page(*paged);
  const std::vector<std::string> problems = paged->take_problems();
  ASSERT_FALSE(problems.empty());
  for (const std::string& p : problems)
    EXPECT_TRUE(p.find("changed on the server") != std::string::npos ||
                p.find("past the end (HTTP 416)") != std::string::npos)
        << p;
  EXPECT_EQ(treecut::TreeCut::leaf_cut(paged->hierarchy()).validate(paged->hierarchy()), "");
}
