// A text cloud read in batches (TextCloudReader, issue 44 item 1): the file
// read a few MiB at a time gives the points one read gives, whatever the
// batch size and wherever a line or its CR LF falls on a block's border; the
// file's checks come with the batch that reads its last line.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/text_cloud.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;

// Every point of a reader's batches, in the first batch's frame (each
// batch is in it: the first batch's origin stays), with its colour and
// its first attribute.
struct Points {
  std::vector<glm::dvec3> at;
  std::vector<glm::u8vec4> colors;
  std::vector<float> values;
  glm::dvec3 origin{0.0};
  std::size_t batches = 0;
};

Points read_all_batches(TextCloudReader reader, std::size_t batch) {
  Points out;
  for (;;) {
    const PointSet b = reader.next(batch);
    if (b.size() == 0) break;
    EXPECT_LE(b.size(), batch);
    if (out.batches++ == 0) out.origin = b.frame.origin;
    EXPECT_EQ(b.frame.origin, out.origin) << "every batch in the first's frame";
    for (std::size_t i = 0; i < b.size(); ++i) {
      out.at.push_back(b.frame.origin + glm::dvec3(b.positions[i]));
      if (b.has_colors()) out.colors.push_back(b.colors[i]);
      if (!b.attributes.empty()) out.values.push_back(b.attributes[0].value(i));
    }
  }
  EXPECT_EQ(reader.next(batch).size(), 0u) << "the end stays the end";
  return out;
}

// A survey export: map coordinates (an origin is needed), colours, an
// intensity, CR LF line ends, a byte order mark, comments, a point
// without a position.
std::string survey_text(int lines) {
  std::string text = "\xEF\xBB\xBFx,y,z,intensity,red,green,blue\r\n# exported\r\n";
  char line[160];
  for (int i = 0; i < lines; ++i) {
    if (i == 5) {
      text += "nan,nan,nan,1,0,0,0\r\n";
      continue;
    }
    std::snprintf(line, sizeof line, "%.3f,%.3f,%.3f,%d,%d,%d,%d\r\n", 500000.0 + (i % 1000) * 0.25,
                  5400000.0 + (i / 1000) * 0.25, 300.0 + (i % 7) * 0.125, i % 4096, i % 256,
                  (i / 256) % 256, 7);
    text += line;
  }
  return text;
}

TEST(TextStream, BatchesOfAFileGiveThePointsOfOneRead) {
  const fs::path dir = test::scratch_dir("text_stream");
  // Past two of the reader's 4 MiB blocks: lines cross their borders.
  const std::string text = survey_text(300000);
  ASSERT_GT(text.size(), std::size_t{9} << 20);
  test::write_text(dir / "s.csv", text);
  std::vector<std::string> warnings;
  const WarningSink warn = [&](const std::string& w) { warnings.push_back(w); };

  const PointSet whole = load_text_cloud(dir / "s.csv", warn);
  ASSERT_EQ(whole.size(), 299999u) << "the nan point is dropped";
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("dropped 1 points without a finite position"), std::string::npos);
  const Points memory = read_all_batches(TextCloudReader(text, "s.csv"), 1u << 30);
  for (const std::size_t batch : {std::size_t{7}, std::size_t{65536}}) {
    warnings.clear();
    const Points b = read_all_batches(TextCloudReader(dir / "s.csv", warn), batch);
    EXPECT_EQ(warnings.size(), 1u) << "said once, at the end";
    ASSERT_EQ(b.at.size(), whole.size());
    EXPECT_TRUE(b.at == memory.at) << "the positions, exactly (millimetres in double)";
    EXPECT_TRUE(b.colors == memory.colors);
    EXPECT_TRUE(b.values == memory.values);
    EXPECT_EQ(b.batches, (300000 + batch - 1) / batch) << "BATCH lines a batch";
  }
  EXPECT_EQ(memory.batches, 1u);
  EXPECT_EQ(memory.origin, whole.frame.origin);
}

TEST(TextStream, ACrLfOnABlocksBorderIsOneLineEnd) {
  const fs::path dir = test::scratch_dir("text_stream_border");
  // A comment line long enough that the next line's CR is the block's last
  // byte and its LF the next block's first (the reader's blocks: 4 MiB).
  constexpr std::size_t kBlock = std::size_t{4} << 20;
  const std::string first = "1 2 3\r\n";
  std::string text = first + "#" + std::string(kBlock - first.size() - 1 - 7 - 1, 'c') + "\r\n";
  text += "4 5 6\r\n7 8 9\r\n";
  ASSERT_EQ(text[kBlock - 1], '\r');
  ASSERT_EQ(text[kBlock], '\n');
  test::write_text(dir / "b.xyz", text);
  const Points p = read_all_batches(TextCloudReader(dir / "b.xyz"), 1);
  ASSERT_EQ(p.at.size(), 3u) << "no empty line between the CR and the LF";
  EXPECT_EQ(p.at[1], glm::dvec3(4, 5, 6));
  EXPECT_EQ(p.at[2], glm::dvec3(7, 8, 9));
}

TEST(TextStream, AFileOfOneLineWithoutALineEndIsOnePoint) {
  // The layout's look ahead starts past the end there (found by points_fuzz).
  for (const std::string text : {"1 2 3", "1 2 3 4 5 6", "0 0 0 0  0 1 0 "}) {
    const PointSet p = load_text_cloud_from_memory(text, "one.xyz");
    EXPECT_EQ(p.size(), 1u) << text;
  }
  const fs::path dir = test::scratch_dir("text_stream_one");
  test::write_text(dir / "one.xyz", "4 5 6");
  EXPECT_EQ(load_text_cloud(dir / "one.xyz").size(), 1u);
}

TEST(TextStream, TheLastBatchMakesTheFilesChecks) {
  const fs::path dir = test::scratch_dir("text_stream_checks");
  // A PTS count that says more than the lines: the batch that reads the
  // last line is refused, naming the count line; earlier ones are read.
  std::string pts = "5\n";
  for (int i = 0; i < 4; ++i) pts += std::to_string(i) + " 0 0 1 2 3 4\n";
  test::write_text(dir / "p.pts", pts);
  TextCloudReader reader(dir / "p.pts");
  EXPECT_EQ(reader.next(2).size(), 2u);
  try {
    (void)reader.next(2);
    FAIL() << "the count is checked";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("p.pts:1: the PTS count line says 5 points, the file "
                                         "has 4"),
              std::string::npos)
        << e.what();
  }
  // A bad line in a later batch names its line number in the file.
  test::write_text(dir / "l.xyz", "1 2 3\n4 5 6\n7 8 x\n");
  TextCloudReader lines(dir / "l.xyz");
  EXPECT_EQ(lines.next(2).size(), 2u);
  EXPECT_THROW(
      {
        try {
          (void)lines.next(2);
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("l.xyz:3: 'x' is not a number"), std::string::npos)
              << e.what();
          throw;
        }
      },
      InputError);
  // No line end for longer than the reader takes a line to be: refused,
  // its buffer bounded.
  test::write_text(dir / "long.xyz", "1 2 3\n" + std::string(std::size_t{68} << 20, '7'));
  TextCloudReader long_line(dir / "long.xyz");
  try {
    (void)long_line.next(1000);
    FAIL() << "a line past 64 MiB is refused";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("long.xyz:2: a line longer than 64 MiB"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace treecut
