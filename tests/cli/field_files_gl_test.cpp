// Files from the field, round two (issue 43), through the program as a user
// runs it: exports that keep what a file holds and replace nothing of the
// user's, the list of views, colours from the first frame, the legend's
// shares, options that refuse what they cannot mean, and a warm cache that
// says what the first read said; the HUD's summary and status line. The
// library-level cases are in
// tests/core/field_files_test.cpp.
#include <gtest/gtest.h>
#include <imgui.h>
#include <imgui_internal.h>
#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "hud_summary.hpp"
#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/coloring.hpp"
#include "treecut/tools/generate.hpp"
#include "views_file.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;
using test::quote;
using test::read_all;
using test::run_treecut;
using test::scratch_dir;
using test::write_text;

const auto expect_refused = test::expect_failure;

// A LAS tile of every class in CLASSES' proportions (class, points), with a
// varying intensity and GPS week times; no colours unless ZERO_RGB (every
// point 0 0 0).
fs::path tile(const fs::path& dir, const std::string& name,
              const std::vector<std::pair<int, int>>& classes, bool zero_rgb = false) {
  PointSet p;
  PointAttribute cls{
      .name = "classification", .kind = AttributeKind::category, .type = ValueType::u8};
  PointAttribute intensity{.name = "intensity", .type = ValueType::u16};
  PointAttribute time{.name = "gps_time", .type = ValueType::f64};
  int total = 0;
  for (const auto& entry : classes) total += entry.second;
  int i = 0;
  for (const auto& [c, count] : classes) {
    for (int k = 0; k < count; ++k, ++i) {
      p.positions.push_back({0.1f * float(i % 100), 0.1f * float(i / 100), 0.01f * float(i % 7)});
      cls.values.push_back(float(c));
      intensity.values.push_back(float(100 + i % 50));
      // From 245379.3984 to 245385.9111 s, the last point exactly.
      time.wide.push_back(i == total - 1 ? 245385.9111 : 245379.3984 + 0.0001 * double(i % 60000));
    }
  }
  if (zero_rgb) p.colors.assign(p.size(), glm::u8vec4(0, 0, 0, 255));
  p.frame.origin = glm::dvec3(500000.0, 5000000.0, 100.0);
  p.attributes = {cls, intensity, time};
  const fs::path file = dir / name;
  save_las(file, p);
  return file;
}

// Items 1 and 2: an all-ground tile keeps its class for --classes and
// --color; info shows the GPS week times to their last digit.
TEST(FieldFilesCli, AnAllGroundTileKeepsItsClassAndItsTimes) {
  const fs::path dir = scratch_dir("cli_field_ground");
  const fs::path ground = tile(dir, "ground.las", {{2, 800}});
  CommandResult r = run_treecut("info " + quote(ground));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("  classification         category 2 at every point"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("  gps_time               measure  245379.3984 .. 245385.9111"),
            std::string::npos)
      << r.out;
  r = run_treecut("export " + quote(ground) + " --classes 2 -o " + quote(dir / "g2.las"));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("(800 of 800 points"), std::string::npos) << r.out;
  r = run_treecut("render " + quote(ground) +
                  " --color classification --frames 1 --width 64 --height 48 --gl osmesa "
                  "--no-png -o " +
                  quote(dir / "out"));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("colour    classification: 2 ground 100.0 %"), std::string::npos) << r.out;
}

// Item 4: export replaces only a file treecut wrote whose header checks
// out: not a note that starts with LASF, not a LAZ file, not a read-only
// file (its mode stays), not a symbolic link (it stays a link).
TEST(FieldFilesCli, AnExportReplacesOnlyAFileItWrote) {
  const fs::path dir = scratch_dir("cli_field_own");
  const fs::path source = tile(dir, "source.las", {{2, 100}, {6, 100}});
  const auto export_to = [&](const fs::path& out) {
    return run_treecut("export " + quote(source) + " -o " + quote(out));
  };
  write_text(dir / "note.las", "LASF is how my notes begin\n");
  expect_refused(export_to(dir / "note.las"), 2,
                 "note.las: exists and is not a LAS file treecut wrote");
  EXPECT_EQ(read_all(dir / "note.las"), "LASF is how my notes begin\n");
  if (const auto shared = test::shared_dir();
      shared && fs::exists(*shared / "laz-pairs/laspy_simple.laz")) {
    fs::copy_file(*shared / "laz-pairs/laspy_simple.laz", dir / "survey.las");
    fs::permissions(dir / "survey.las", fs::perms::owner_read | fs::perms::owner_write);
    const std::string laz = read_all(dir / "survey.las");
    expect_refused(export_to(dir / "survey.las"), 2, "is not a LAS file treecut wrote");
    EXPECT_EQ(read_all(dir / "survey.las"), laz);
  }
  ASSERT_EQ(export_to(dir / "mine.las").code, 0);
  ASSERT_EQ(export_to(dir / "mine.las").code, 0) << "its own file: replaced";
  fs::permissions(dir / "mine.las",
                  fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  expect_refused(export_to(dir / "mine.las"), 2, "mine.las: is read-only");
  EXPECT_EQ(fs::status(dir / "mine.las").permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  fs::permissions(dir / "mine.las", fs::perms::owner_all);
  fs::create_symlink(dir / "mine.las", dir / "link.las");
  expect_refused(export_to(dir / "link.las"), 2, "link.las: is a symbolic link");
  EXPECT_TRUE(fs::is_symlink(dir / "link.las"));
  // A truncated file of treecut's is no longer one whose header checks out.
  fs::resize_file(dir / "mine.las", fs::file_size(dir / "mine.las") - 1);
  expect_refused(export_to(dir / "mine.las"), 2, "is not a LAS file treecut wrote");
  // PLY and PCD alike.
  write_text(dir / "note.ply", "ply\nmy notes\n");
  expect_refused(export_to(dir / "note.ply"), 2, "is not a PLY file treecut wrote");
  write_text(dir / "note.pcd", "# .PCD v0.7 - my notes\n");
  expect_refused(export_to(dir / "note.pcd"), 2, "is not a PCD file treecut wrote");
}

// Hostile round: a text cloud's intensity of -2048 or 0.5, a class of 256,
// do not fit LAS's fields: refused naming them (they were clamped without a
// word); PLY keeps them. A hand-written camera path is the user's.
TEST(FieldFilesCli, AnExportRefusesWhatLasCannotHoldAndReplacesNoHandWrittenPath) {
  const fs::path dir = scratch_dir("cli_field_fit");
  write_text(dir / "s.pts", "3\n0 0 0 -2048 10 20 30\n1 0 0 -5 10 20 30\n2 0 0 100 10 20 30\n");
  expect_refused(
      run_treecut("export " + quote(dir / "s.pts") + " -o " + quote(dir / "s.las")), 2,
      "s.las: intensity -2048 does not fit LAS's intensity (whole numbers from 0 to 65535)");
  EXPECT_FALSE(fs::exists(dir / "s.las"));
  write_text(dir / "a.csv", "x,y,z,classification\n0,0,0,256\n1,0,0,3\n2,0,0,3\n");
  expect_refused(run_treecut("export " + quote(dir / "a.csv") + " -o " + quote(dir / "a.las")), 2,
                 "classification 256 does not fit LAS's classification");
  EXPECT_EQ(run_treecut("export " + quote(dir / "s.pts") + " -o " + quote(dir / "s.ply")).code, 0);
  write_text(dir / "mine.campath",
             "treecut-camera-path 1\n# my hand-tuned path\n0 0 -3 1 0 0 0 0 0 1 45\n");
  expect_refused(run_treecut("gen city -n 300 -o " + quote(dir / "c.ply") + " --walk " +
                             quote(dir / "mine.campath")),
                 2, "is not a camera path treecut wrote");
}

// Item 4: cache --clear removes only caches whose header checks out: a
// 25-byte file that starts with the cache's signature is the user's.
TEST(FieldFilesCli, CacheClearRemovesOnlyWholeCaches) {
  const fs::path dir = scratch_dir("cli_field_cache");
  const fs::path folder = dir / "caches";
  fs::create_directories(folder);
  write_text(folder / "mine.tch", "TCUTHIER and then my own");
  // One that claims an older version (1) with a header of 64 bytes: its
  // header cannot be verified, so it is the user's (hostile round).
  std::string old = "TCUTHIER";
  for (const std::uint32_t v : {1u, 0x01020304u, 64u})
    old.append(reinterpret_cast<const char*>(&v), 4);
  old.resize(72, '\0');
  write_text(folder / "old.tch", old);
  const fs::path model = tile(dir, "m.las", {{2, 50}});
  ASSERT_EQ(run_treecut("build " + quote(model) + " -o " + quote(folder / "m.tch")).code, 0);
  const CommandResult r = run_treecut("cache --folder " + quote(folder) + " --clear");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(fs::exists(folder / "m.tch"));
  EXPECT_EQ(read_all(folder / "mine.tch"), "TCUTHIER and then my own");
  EXPECT_EQ(read_all(folder / "old.tch"), old);
  // --older-than of 60,000 days keeps a cache used two days ago (the cut-off
  // overflowed the clock and every cache went).
  ASSERT_EQ(run_treecut("build " + quote(model) + " -o " + quote(folder / "m.tch")).code, 0);
  fs::last_write_time(folder / "m.tch", fs::file_time_type::clock::now() - std::chrono::hours(48));
  for (const char* days : {"60000", "1e6", "3"}) {
    const CommandResult older =
        run_treecut("cache --folder " + quote(folder) + " --older-than " + days);
    EXPECT_EQ(older.code, 0) << older.out;
    EXPECT_TRUE(fs::exists(folder / "m.tch")) << days;
  }
  EXPECT_EQ(run_treecut("cache --folder " + quote(folder) + " --older-than 1").code, 0);
  EXPECT_FALSE(fs::exists(folder / "m.tch")) << "two days old: past one";
  // build -o refuses to replace it as well.
  expect_refused(run_treecut("build " + quote(model) + " -o " + quote(folder / "mine.tch")), 2,
                 "is not a treecut cache treecut wrote");
}

// Item 5: the list of views is written only when missing or read whole.
TEST(FieldFilesCli, AViewsFileIsWrittenOnlyWhenMissingOrReadWhole) {
  using cli::read_views;
  EXPECT_EQ(cli::views_file_for("m.las"), fs::path("m.las.views"));
  // A folder of tiles keeps its views beside it, however it was named.
  EXPECT_EQ(cli::views_file_for("d/tiles/"), fs::path("d/tiles.views"));
  EXPECT_EQ(cli::views_file_for("d/tiles"), fs::path("d/tiles.views"));
  using cli::save_view;
  const fs::path dir = scratch_dir("cli_field_views");
  splat::Camera cam;
  cam.eye = {0, 0, 5};
  cam.target = {0, 0, 0};
  // Missing: written; then kept and added to.
  (void)save_view(dir / "m.views", 2, cam);
  cam.eye = {1, 0, 5};
  const cli::ViewSlots slots = save_view(dir / "m.views", 5, cam);
  EXPECT_TRUE(slots[1] && slots[4]);
  EXPECT_EQ(read_views(dir / "m.views")[1]->eye, glm::vec3(0, 0, 5)) << "slot 2 kept";
  // Another viewer's slot 7, saved meanwhile, stays when this one saves 3.
  splat::CameraPath other = splat::load_camera_path(dir / "m.views");
  other.keys.push_back({7.0, cam});
  splat::save_camera_path(dir / "m.views", other);
  (void)save_view(dir / "m.views", 3, cam);
  EXPECT_TRUE(read_views(dir / "m.views")[6]) << "slot 7 kept";
  // A file that does not read whole (one line of 11 malformed), a camera
  // path of the user's (keys that are not slots), one past the text limit,
  // a link: refused, each left as it was.
  std::string text = read_all(dir / "m.views");
  text.insert(text.find("\n", text.find("\n") + 1) + 1, "key 4 not a number\n");
  write_text(dir / "broken.views", text);
  splat::CameraPath user;
  for (const double t : {0.0, 1.5, 3.0}) user.keys.push_back({t, cam});
  splat::save_camera_path(dir / "path.views", user);
  write_text(dir / "huge.views", read_all(dir / "m.views") + std::string(17 << 20, '#'));
  fs::create_symlink(dir / "m.views", dir / "link.views");
  fs::copy_file(dir / "m.views", dir / "locked.views");
  fs::permissions(dir / "locked.views", fs::perms::owner_read);
  std::string twice = read_all(dir / "m.views");
  twice += twice.substr(twice.rfind('\n', twice.size() - 2) + 1);  // the last slot again
  write_text(dir / "twice.views", twice);
  for (const char* name :
       {"broken.views", "path.views", "huge.views", "link.views", "locked.views", "twice.views"}) {
    const std::string before = read_all(dir / name);
    EXPECT_THROW((void)save_view(dir / name, 1, cam), InputError) << name;
    EXPECT_EQ(read_all(dir / name), before) << name;
  }
  EXPECT_TRUE(fs::is_symlink(dir / "link.views"));
  EXPECT_EQ(fs::status(dir / "locked.views").permissions() & fs::perms::all, fs::perms::owner_read);
  // Each named as what it is.
  fs::create_directories(dir / "folder.views");
  const auto reason = [&](const char* name) {
    try {
      (void)read_views(dir / name);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(read)");
  };
  EXPECT_NE(reason("folder.views").find("is a directory, not treecut's list of views"),
            std::string::npos);
  EXPECT_NE(reason("twice.views").find(": slot 7 twice"), std::string::npos)
      << reason("twice.views");
}

// Item 11: no usable RGB (none, or 0 0 0 everywhere) is coloured by the
// intensity where it varies, else the elevation, said once.
TEST(FieldFilesCli, NoUsableRgbIsColouredByIntensityOrElevation) {
  const fs::path dir = scratch_dir("cli_field_colour");
  const fs::path black = tile(dir, "black.las", {{2, 300}}, /*zero_rgb=*/true);
  CommandResult r = run_treecut("render " + quote(black) +
                                " --frames 1 --width 64 --height 48 --gl osmesa --no-png -o " +
                                quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("colour    no usable RGB (every point 0 0 0): coloured by intensity\n"),
            std::string::npos)
      << r.out;
  // The rule itself: RGB where it varies, else intensity, else elevation.
  OpenOptions o;
  o.use_cache = false;
  const Hierarchy h = open_model(black, o).hierarchy;
  splat::ColorBy by;
  by.source = "auto";
  std::string note;
  EXPECT_EQ(splat::resolve_auto_color(h, by, &note).source, "intensity");
  PointSet plain = tools::generate_model(tools::ModelKind::Sphere, 500, 1);
  plain.colors.clear();
  const Hierarchy grey = build_from_points(plain);
  EXPECT_EQ(splat::resolve_auto_color(grey, by, &note).source, "elevation");
  EXPECT_EQ(note, "no usable RGB (none in the file): coloured by elevation");
  PointSet coloured = tools::generate_model(tools::ModelKind::Terrain, 500, 1);
  ASSERT_TRUE(coloured.has_colors());
  EXPECT_EQ(splat::resolve_auto_color(build_from_points(coloured), by, &note).source, "rgb");
  EXPECT_TRUE(note.empty());
}

// Item 13: the legend's shares are the file's, exact (every second node id
// sampled gave 77.1 / 22.9 % for 76.27 / 23.73).
TEST(FieldFilesCli, TheLegendCountsEveryPoint) {
  const fs::path dir = scratch_dir("cli_field_legend");
  // Past 65,536 nodes, where a sample of every n-th node id stood in for the
  // leaves (the legend said 77.1 / 22.9 % for 76.27 / 23.73).
  const fs::path file = tile(dir, "split.las", {{2, 76270}, {6, 23730}});
  CommandResult r = run_treecut("render " + quote(file) +
                                " --color classification --frames 1 --width 64 --height 48 --gl "
                                "osmesa --no-png -o " +
                                quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("2 ground 76.3 %, 6 building 23.7 %"), std::string::npos) << r.out;
  OpenOptions o;
  o.use_cache = false;
  const Hierarchy h = open_model(file, o).hierarchy;
  splat::ColorBy by;
  by.source = "classification";
  const splat::Coloring c = splat::color_nodes(h, by, {0, 0, 1});
  ASSERT_EQ(c.legend.entries.size(), 2u);
  EXPECT_DOUBLE_EQ(c.legend.entries[0].share, 0.7627);
  EXPECT_DOUBLE_EQ(c.legend.entries[1].share, 0.2373);
}

// Item 14: options that cannot mean anything are refused before any work,
// exit 2 and one line; TREECUT_CACHE_LIMIT=0x1 is not one byte.
TEST(FieldFilesCli, OptionsRefuseWhatTheyCannotMean) {
  const fs::path dir = scratch_dir("cli_field_options");
  const fs::path model = tile(dir, "m.las", {{2, 100}});
  fs::create_directories(dir / "caches");
  const std::string folder = " --folder " + quote(dir / "caches");
  for (const auto& [args, text] : std::vector<std::pair<std::string, std::string>>{
           {"gen sphere -n 100 --origin nan 0 0 -o " + quote(dir / "s.ply"), "nan"},
           {"cache" + folder + " --older-than nan", "nan"},
           {"cache" + folder + " --max-size 0x10", "'0x10' is not a size"},
           {"cache" + folder + " --max-size ''", "'' is not a size"},
           {"cache --folder " + quote(model), "is a regular file, not a cache folder"},
           {"render " + quote(model) + " --clip 1 1 1 0 0 0 --frames 1 --no-png -o " +
                quote(dir / "out"),
            "--clip: the first corner's x (1) is past the second's (0)"}}) {
    expect_refused(run_treecut(args), 2, text);
  }
  EXPECT_FALSE(fs::exists(dir / "s.ply"));
  EXPECT_FALSE(fs::exists(dir / "out"));
  // A limit that is not a size is a warning, and nothing is removed (0x1
  // was read as one byte: every cache evicted).
  ::setenv("XDG_CACHE_HOME", (dir / "xdg").c_str(), 1);
  ASSERT_EQ(run_treecut("build " + quote(tile(dir, "other.las", {{6, 50}}))).code, 0);
  ::setenv("TREECUT_CACHE_LIMIT", "0x1", 1);
  const CommandResult limited = run_treecut("build -f " + quote(model));
  ::unsetenv("TREECUT_CACHE_LIMIT");
  ::unsetenv("XDG_CACHE_HOME");
  EXPECT_EQ(limited.code, 0) << limited.out;
  EXPECT_NE(limited.out.find("TREECUT_CACHE_LIMIT: '0x1' is not a size"), std::string::npos)
      << limited.out;
  EXPECT_EQ(limited.out.find("removed"), std::string::npos) << limited.out;
  std::size_t caches = 0;
  for (const auto& e : fs::directory_iterator(dir / "xdg" / "treecut"))
    caches += e.path().extension() == ".tch";
  EXPECT_EQ(caches, 2u) << "both caches stay";
  // A negative axis is a value, not an option.
  const CommandResult up = run_treecut("render " + quote(model) +
                                       " --up -y --frames 1 --width 32 --height 24 --gl osmesa "
                                       "--no-png -o " +
                                       quote(dir / "up"));
  EXPECT_EQ(up.code, 0) << up.out;
}

// Item 18: a warm cache says what the first read said (the format line and
// its warnings); cache names are quoted; help texts name every format; an
// orbit's frames look from distinct places.
TEST(FieldFilesCli, AWarmCacheSaysWhatTheFirstReadSaid) {
  const fs::path dir = scratch_dir("cli_field_notes");
  write_text(dir / "c.pcd",
             "VERSION 0.7\nFIELDS x y z normal_x\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
             "WIDTH 4\nHEIGHT 1\nPOINTS 4\nDATA ascii\n0 0 0 1\n1 0 0 1\n0 1 0 1\nnan 0 0 1\n");
  ::setenv("XDG_CACHE_HOME", (dir / "xdg").c_str(), 1);
  const CommandResult cold = run_treecut("build " + quote(dir / "c.pcd"));
  const CommandResult warm = run_treecut("info " + quote(dir / "c.pcd"));
  ::unsetenv("XDG_CACHE_HOME");
  ASSERT_EQ(cold.code, 0) << cold.out;
  ASSERT_EQ(warm.code, 0) << warm.out;
  EXPECT_NE(warm.out.find("loaded      from cache"), std::string::npos) << warm.out;
  for (const std::string said :
       {"format      PCD\n", "dropped 1 points without a finite position"}) {
    EXPECT_NE(cold.out.find(said), std::string::npos) << cold.out;
    EXPECT_NE(warm.out.find(said), std::string::npos) << warm.out;
  }
  // A cache named with a newline and an escape is listed quoted, a line each.
  const fs::path folder = dir / "caches";
  fs::create_directories(folder);
  ASSERT_EQ(
      run_treecut("build " + quote(dir / "c.pcd") + " -o " + quote(folder / "a\nb\x1b[2J.tch"))
          .code,
      0);
  const CommandResult list = run_treecut("cache --folder " + quote(folder));
  ASSERT_EQ(list.code, 0) << list.out;
  EXPECT_NE(list.out.find("'a\\nb\\x1b[2J.tch'"), std::string::npos) << list.out;
  EXPECT_EQ(list.out.find('\x1b'), std::string::npos) << list.out;
  for (const char* command : {"build", "info", "render", "view"}) {
    const CommandResult help = run_treecut(std::string(command) + " --help");
    EXPECT_NE(help.out.find("LAS, PCD"), std::string::npos) << command << "\n" << help.out;
  }
  const splat::CameraPath orbit = splat::orbit_path({0, 0, 0}, {1, 1, 1}, 1.0f, 8.0, 73);
  EXPECT_TRUE(orbit.loops());
  EXPECT_NE(orbit.at(orbit.frame_time(0, 3)).eye, orbit.at(orbit.frame_time(2, 3)).eye);
  splat::CameraPath line = orbit;
  line.keys.resize(10);
  EXPECT_FALSE(line.loops());
  EXPECT_EQ(line.frame_time(2, 3), line.duration());
}

// Item 18, the HUD: its summary's lines wrap within its width (they were cut
// at it: "20.0 k splats for 110.0 k of 110.0 k poin"), drawn here in a
// headless Dear ImGui frame; a status line goes away once stale ("saved
// first_hud.png" stayed until the next message), timed by its own clock.
TEST(HudSummaryLines, WrapWithinTheHudsWidth) {
  ImGuiContext* context = ImGui::CreateContext();
  ImGuiIO& io = ImGui::GetIO();
  io.DisplaySize = ImVec2(1280, 720);
  io.DeltaTime = 1.0f / 60.0f;
  io.IniFilename = nullptr;
  unsigned char* pixels = nullptr;
  int width = 0, height = 0;
  io.Fonts->GetTexDataAsRGBA32(&pixels, &width, &height);  // the built-in font
  cli::HudSummary s;
  s.label = "tile.las";
  s.frame_ms = 33.0;
  s.splats = 20000;
  s.points = 110000;
  s.total = 110000;
  s.iteration_ms = 12.5;
  s.holding_fps = 30;
  s.budget = 20000;
  s.budget_param = "max_nodes";
  float reach = 0.0f, hud = 0.0f, lines = 0.0f;
  for (int frame = 0; frame < 3; ++frame) {  // an auto-sized window settles
    ImGui::NewFrame();
    cli::begin_hud_window(false);
    const float top = ImGui::GetCursorPosY();
    cli::draw_hud_summary(s);
    const ImGuiWindow* window = ImGui::GetCurrentWindow();
    reach = window->DC.CursorMaxPos.x - window->Pos.x;
    hud = window->Size.x;
    lines = (ImGui::GetCursorPosY() - top) / ImGui::GetTextLineHeightWithSpacing();
    ImGui::End();
    ImGui::Render();
  }
  ImGui::DestroyContext(context);
  EXPECT_EQ(hud, cli::kHudWidth);
  EXPECT_LE(reach, hud) << "a line runs past the HUD's edge";
  EXPECT_GE(lines, 5.0f) << "the long lines wrap onto more lines";
}

TEST(HudSummaryLines, AStatusLineShowsWhileFreshAndAgainWhenSaidAgain) {
  cli::StatusLine status;
  EXPECT_EQ(status.shown(0.0), "");
  status.say("saved first_hud.png", 100.0);
  EXPECT_EQ(status.shown(100.0), "saved first_hud.png");
  EXPECT_EQ(status.shown(100.0 + cli::StatusLine::kSeconds * 0.99), "saved first_hud.png");
  EXPECT_EQ(status.shown(100.0 + cli::StatusLine::kSeconds), "");
  EXPECT_EQ(status.shown(1000.0), "");
  status.say("saved first_hud.png", 1000.0);  // the same words, news again
  EXPECT_EQ(status.shown(1000.5), "saved first_hud.png");
  status.clear();
  EXPECT_EQ(status.shown(1000.5), "");
}

}  // namespace
}  // namespace treecut
