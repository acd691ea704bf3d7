#include "occmap/publish/ros_map.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "occmap/util/file_util.h"

namespace occmap {
namespace {

namespace fs = std::filesystem;

class RosMapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("occmap-ros-map-" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  void Write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name, std::ios::binary) << text; }
  fs::path dir_;
};

// A 4 x 3 grid of 0.25 m cells from (-1, 2): cell (i, j) covers x in [-1 + i/4, ...), y in
// [2 + j/4, ...).
FloorGrid SmallGrid() { return FloorGrid{-1.0, 2.0, 4, 3, 0.25}; }

TEST_F(RosMapTest, TheFirstRowIsTheTopAndValuesAreMapSaversOnes) {
  OccupancyMap map(SmallGrid());
  map.states().assign(12, CellState::kFree);
  // Occupied: the cell holding (-0.9, 2.1) (i 0, j 0: bottom left) and (-0.1, 2.6) (i 3, j 2:
  // top right); unseen: (i 1, j 2).
  map.states()[static_cast<size_t>(map.grid().CellAt(-0.9, 2.1))] = CellState::kOccupied;
  map.states()[static_cast<size_t>(map.grid().CellAt(-0.1, 2.6))] = CellState::kOccupied;
  map.states()[2 * 4 + 1] = CellState::kUnseen;
  ASSERT_TRUE(WriteRosMap(dir_ / "frame.yaml", RosMapFromOccupancy(map)).ok());

  const Result<std::string> pgm = ReadFileToString(dir_ / "frame.pgm");
  ASSERT_TRUE(pgm.ok());
  const std::string header = "P5\n# occmap map, 0.25 m/pixel\n4 3\n255\n";
  ASSERT_EQ(pgm->substr(0, header.size()), header);
  const std::string pixels = pgm->substr(header.size());
  // Row 0 = j 2 (top, largest y), row 2 = j 0.
  const std::string expected = {char(254), char(205), char(254), char(0),   //
                                char(254), char(254), char(254), char(254),  //
                                char(0),   char(254), char(254), char(254)};
  EXPECT_EQ(pixels, expected);
  EXPECT_EQ(*ReadFileToString(dir_ / "frame.yaml"),
            "image: frame.pgm\nmode: trinary\nresolution: 0.25\norigin: [-1, 2, 0]\nnegate: 0\noccupied_thresh: 0.65\n"
            "free_thresh: 0.196\n");
}

TEST_F(RosMapTest, RoundTripsThroughMapServersReadingRules) {
  std::mt19937 rng(7);
  RosMap map;
  map.grid = FloorGrid{-3.125, 0.5, 37, 23, 0.05};
  map.cells.resize(37 * 23);
  for (RosCell& c : map.cells) c = static_cast<RosCell>(rng() % 3);
  ASSERT_TRUE(WriteRosMap(dir_ / "m.yaml", map).ok());
  const Result<RosMap> back = ReadRosMap(dir_ / "m.yaml");
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(*back, map);
}

TEST_F(RosMapTest, ReaderAppliesNegateAndThresholdsAsMapServer) {
  // 3 x 1 pixels 0, 100, 255; with negate 1 p = v / 255: free, unknown (0.39), occupied.
  Write("n.pgm", std::string("P5 3 1 255\n") + char(0) + char(100) + char(255));
  Write("n.yaml", "image: n.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\noccupied_thresh: 0.65\nfree_thresh: 0.25\n");
  const Result<RosMap> m = ReadRosMap(dir_ / "n.yaml");
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_EQ(m->cells, (std::vector<RosCell>{RosCell::kFree, RosCell::kUnknown, RosCell::kOccupied}));
}

TEST_F(RosMapTest, MalformedMapsGiveLocatedMessages) {
  const std::string good_pgm = std::string("P5\n2 2\n255\n") + std::string(4, char(254));
  const std::string yaml = "image: a.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  const struct {
    std::string yaml, pgm, message;
  } cases[] = {
      {"image: a.pgm\nresolution: 0\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", good_pgm,
       "{dir}/m.yaml:2: resolution: expected a number > 0, found 0"},
      {"image: a.pgm\nresolution: 0.1\norigin: [0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", good_pgm,
       "{dir}/m.yaml:3: origin: expected a list of 3 numbers, found 2"},
      {"image: a.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: scale\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", good_pgm,
       "{dir}/m.yaml:4: mode: expected 'trinary' (the only mode read), found 'scale'"},
      {"image: a.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 2\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", good_pgm,
       "{dir}/m.yaml:4: negate: expected 0 or 1, found 2"},
      {"image: a.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.7\n", good_pgm,
       "{dir}/m.yaml:5: free_thresh: expected a number in [0, occupied_thresh = 0.65], found 0.7"},
      {"image: b.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", good_pgm,
       "{dir}/m.yaml:1: image: file not found: '{dir}/b.pgm'"},
      {"resolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", good_pgm,
       "{dir}/m.yaml:1: missing required field 'image'"},
      {yaml, "P2\n2 2\n255\n1 2 3 4\n", "{dir}/a.pgm: expected a binary PGM (P5), found 'P2'"},
      {yaml, "P5\n2 2\n", "{dir}/a.pgm: truncated header: no maximum value"},
      {yaml, "P5\n2 x\n255\n", "{dir}/a.pgm: expected a positive height, found 'x'"},
      {yaml, "P5\n2 2\n65535\n", "{dir}/a.pgm: expected 8-bit pixels (maximum value 255), found 65535"},
      {yaml, "P5\n2 2\n255\n\x01\x02\x03", "{dir}/a.pgm: truncated: expected 2 x 2 = 4 pixels, found 3"},
  };
  for (const auto& c : cases) {
    Write("m.yaml", c.yaml);
    Write("a.pgm", c.pgm);
    const Result<RosMap> r = ReadRosMap(dir_ / "m.yaml");
    ASSERT_FALSE(r.ok()) << c.message;
    std::string expected = c.message;
    for (size_t at; (at = expected.find("{dir}")) != std::string::npos;) expected.replace(at, 5, dir_.string());
    EXPECT_EQ(r.status().message(), expected);
  }
}

TEST(StaticMapAccumulator, CellsOccupiedMoreThanTheFractionOfTheFramesThatSawThem) {
  const FloorGrid grid{0, 0, 4, 1, 0.1};
  StaticMapAccumulator acc(grid);
  // Cell 0: occupied 3 of 4 frames; cell 1: 2 of 4 (not more than half); cell 2: occupied in
  // the one frame that saw it; cell 3: never seen.
  const CellState F = CellState::kFree, O = CellState::kOccupied, U = CellState::kUnseen;
  const std::vector<std::vector<CellState>> frames = {{O, O, U, U}, {O, F, U, U}, {O, O, O, U}, {F, F, U, U}};
  for (const auto& states : frames) {
    OccupancyMap map(grid);
    map.states() = states;
    acc.Add(map);
  }
  EXPECT_EQ(acc.frames(), 4);
  EXPECT_EQ(acc.StaticMap(0.5).cells, (std::vector<RosCell>{RosCell::kOccupied, RosCell::kFree, RosCell::kOccupied, RosCell::kUnknown}));
  EXPECT_EQ(acc.StaticMap(0.25).cells, (std::vector<RosCell>{RosCell::kOccupied, RosCell::kOccupied, RosCell::kOccupied, RosCell::kUnknown}));
  EXPECT_EQ(acc.StaticMap(0.75).cells, (std::vector<RosCell>{RosCell::kFree, RosCell::kFree, RosCell::kOccupied, RosCell::kUnknown}));
}

}  // namespace
}  // namespace occmap
