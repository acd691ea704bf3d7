#include "occmap/lut/lut_file.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include "occmap/lut/test_scene.h"
#include "occmap/util/file_util.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

std::vector<LutCameraInput> Inputs(const std::vector<PinholeCamera>& cams) {
  std::vector<LutCameraInput> in;
  for (const auto& c : cams) in.push_back({&c, {}});
  return in;
}

TEST(LutFile, SaveThenLoadRoundTripsExactly) {
  testing::SmallRoom room;
  testing::TempDir dir;
  Context ctx(2);
  const GroundLut lut = BuildGroundLut(Inputs(room.cameras), room.grid, {}, ctx).value();
  ASSERT_TRUE(SaveGroundLut(dir / "t.lut", lut, 42).ok());
  auto back = LoadGroundLut(dir / "t.lut", 42);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_TRUE(*back == lut);
}

TEST(LutFile, StaleCorruptAndTruncatedFilesAreNeverTrusted) {
  testing::SmallRoom room;
  testing::TempDir dir;
  Context ctx(2);
  const GroundLut lut = BuildGroundLut(Inputs(room.cameras), room.grid, {}, ctx).value();
  ASSERT_TRUE(SaveGroundLut(dir / "t.lut", lut, 42).ok());
  const std::string good = *ReadFileToString(dir / "t.lut");

  bool stale = false;
  auto r = LoadGroundLut(dir / "t.lut", 43, &stale);
  EXPECT_TRUE(stale);
  EXPECT_NE(r.status().message().find("is stale: built for inputs 000000000000002a, current inputs are 000000000000002b"),
            std::string::npos) << r.status().message();

  std::string flipped = good;
  flipped[flipped.size() / 2] ^= 0x10;
  ASSERT_TRUE(WriteFileAtomic(dir / "t.lut", flipped).ok());
  r = LoadGroundLut(dir / "t.lut", 42, &stale);
  EXPECT_FALSE(stale);
  EXPECT_NE(r.status().message().find("fails its checksum (corrupt)"), std::string::npos) << r.status().message();

  ASSERT_TRUE(WriteFileAtomic(dir / "t.lut", std::string_view(good).substr(0, good.size() - 100)).ok());
  r = LoadGroundLut(dir / "t.lut", 42);
  EXPECT_NE(r.status().message().find("is truncated"), std::string::npos) << r.status().message();

  ASSERT_TRUE(WriteFileAtomic(dir / "t.lut", std::string_view(good).substr(0, 20)).ok());
  r = LoadGroundLut(dir / "t.lut", 42);
  EXPECT_NE(r.status().message().find("is truncated (20 bytes, header needs 48)"), std::string::npos);

  ASSERT_TRUE(WriteFileAtomic(dir / "t.lut", "GIF89a" + good.substr(6)).ok());
  r = LoadGroundLut(dir / "t.lut", 42);
  EXPECT_NE(r.status().message().find("has no OCCMLUT magic"), std::string::npos);

  std::string version = good;
  version[8] = 99;
  ASSERT_TRUE(WriteFileAtomic(dir / "t.lut", version).ok());
  r = LoadGroundLut(dir / "t.lut", 42);
  EXPECT_NE(r.status().message().find("has format version 99, expected 2"), std::string::npos);
  EXPECT_EQ(r.status().code(), StatusCode::kDataLoss);
}

TEST(LutFile, LoadOrBuildReusesValidFilesAndRebuildsOthers) {
  testing::SmallRoom room;
  testing::TempDir dir;
  Context ctx(2);
  const auto path = dir / "cache" / "room.lut";
  auto first = LoadOrBuildGroundLut(path, Inputs(room.cameras), room.grid, {}, ctx);
  ASSERT_TRUE(first.ok()) << first.status().message();
  EXPECT_EQ(first->outcome, LutCacheOutcome::kBuiltNoFile);
  auto second = LoadOrBuildGroundLut(path, Inputs(room.cameras), room.grid, {}, ctx);
  EXPECT_EQ(second->outcome, LutCacheOutcome::kLoaded);
  EXPECT_TRUE(second->lut == first->lut);

  LutOptions knee;
  knee.plane_height_m = 0.5;
  auto third = LoadOrBuildGroundLut(path, Inputs(room.cameras), room.grid, knee, ctx);
  EXPECT_EQ(third->outcome, LutCacheOutcome::kRebuiltStale);
  EXPECT_EQ(third->lut.plane_height_m(), 0.5);

  std::string bytes = *ReadFileToString(path);
  bytes[bytes.size() - 1] ^= 1;
  ASSERT_TRUE(WriteFileAtomic(path, bytes).ok());
  auto fourth = LoadOrBuildGroundLut(path, Inputs(room.cameras), room.grid, knee, ctx);
  EXPECT_EQ(fourth->outcome, LutCacheOutcome::kRebuiltCorrupt);
  EXPECT_NE(fourth->reason.find("checksum"), std::string::npos);
  EXPECT_TRUE(fourth->lut == third->lut);
  EXPECT_EQ(LoadOrBuildGroundLut(path, Inputs(room.cameras), room.grid, knee, ctx)->outcome, LutCacheOutcome::kLoaded);
}

// A cache is a head start, never an output: a file that cannot be written (a regular file where
// its folder should be; the tests may run as root, whom no mode stops) gives the tables built,
// with why it was not written.
TEST(LutFile, AFileThatCannotBeWrittenGivesTheTablesAndSaysWhy) {
  testing::SmallRoom room;
  testing::TempDir dir;
  Context ctx(2);
  testing::WriteText(dir / "cache", "not a folder");
  auto built = LoadOrBuildGroundLut(dir / "cache" / "room.lut", Inputs(room.cameras), room.grid, {}, ctx);
  ASSERT_TRUE(built.ok()) << built.status().message();
  EXPECT_EQ(built->outcome, LutCacheOutcome::kBuiltNoFile);
  EXPECT_NE(built->write_error.find(fmt::format("'{}': cannot create folder: ", (dir / "cache").string())),
            std::string::npos)
      << built->write_error;
  auto plain = LoadOrBuildGroundLut({}, Inputs(room.cameras), room.grid, {}, ctx);
  EXPECT_TRUE(built->lut == plain->lut);
  EXPECT_EQ(plain->write_error, "");
  EXPECT_EQ(*ReadFileToString(dir / "cache"), "not a folder");
}

}  // namespace
}  // namespace occmap
