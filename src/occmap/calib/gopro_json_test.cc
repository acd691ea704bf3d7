#include "occmap/calib/gopro_json.h"

#include <gtest/gtest.h>

#include "occmap/geometry/rotation.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

const std::string kIntr = R"({"K": [[972.66, 0.0, 960.5], [0.0, 973.9, 552.8], [0.0, 0.0, 1.0]],
  "distCoeffs": [[-0.254, 0.084, 4.6e-05, -4.6e-05, -0.0145]], "image_shape": [1080, 1920]})";
const std::string kExtr = R"({"unit": "cm", "t": [141.1, 0.38, 458.5],
  "R": [[-0.7453703270164741, 0.6662165431418967, 0.0240539653158439],
        [0.26241398737336435, 0.3263782880352468, -0.9080837584331047],
        [-0.6128311144468481, -0.670546591030961, -0.4180972308238732]], "Hr": [[1,0,0],[0,1,0],[0,0,1]]})";

TEST(GoProJson, ReadsIntrinsicsAndCentimetreExtrinsics) {
  testing::TempDir dir;
  testing::WriteText(dir / "i.json", kIntr);
  testing::WriteText(dir / "e.json", kExtr);
  auto p = ReadGoProCalibration(dir / "i.json", dir / "e.json", std::nullopt);
  ASSERT_TRUE(p.ok()) << p.status().message();
  EXPECT_EQ(p->image_size, (ImageSize{1920, 1080}));
  EXPECT_DOUBLE_EQ(p->fx_px, 972.66);
  EXPECT_DOUBLE_EQ(p->distortion[0], -0.254);
  EXPECT_NEAR(p->cam_from_world_translation_m.z(), 4.585, 1e-12);
}

TEST(GoProJson, WriteThenReadRoundTrips) {
  testing::TempDir dir;
  PinholeParameters p;
  p.image_size = {1920, 1080};
  p.fx_px = 972.6625775080124;
  p.fy_px = 973.9468185764242;
  p.cx_px = 960.5066158383668;
  p.cy_px = 552.8441880220289;
  p.distortion = {-0.254334663148494, 0.08432305932840313, 4.6383753255566895e-05, -4.6569715360610884e-05,
                  -0.014552111617071255};
  p.cam_from_world_rotation = RotationFromRodrigues({0.4, 2.1, -0.3});
  p.cam_from_world_translation_m = {1.4109886169433594, 0.0038261789083480835, 4.585462646484375};
  ASSERT_TRUE(WriteGoProCalibration(p, dir / "i.json", dir / "e.json").ok());
  auto back = ReadGoProCalibration(dir / "i.json", dir / "e.json", std::nullopt);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->fx_px, p.fx_px);
  EXPECT_EQ(back->distortion, p.distortion);
  EXPECT_EQ(back->cam_from_world_rotation, p.cam_from_world_rotation);
  EXPECT_EQ(back->cam_from_world_translation_m, p.cam_from_world_translation_m);
}

struct BadJson {
  const char* name;
  std::string intrinsic;
  std::string extrinsic;
  const char* expected;
};

class GoProJsonBadInput : public ::testing::TestWithParam<BadJson> {};

TEST_P(GoProJsonBadInput, IsRejectedWithAClearMessage) {
  testing::TempDir dir;
  testing::WriteText(dir / "i.json", GetParam().intrinsic);
  testing::WriteText(dir / "e.json", GetParam().extrinsic);
  auto p = ReadGoProCalibration(dir / "i.json", dir / "e.json", std::nullopt);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(ExitCodeFor(p.status()), 2);
  EXPECT_NE(p.status().message().find(GetParam().expected), std::string::npos) << p.status().message();
}

INSTANTIATE_TEST_SUITE_P(
    Table, GoProJsonBadInput,
    ::testing::Values(
        BadJson{"syntax", "{\"K\": [", kExtr, "JSON syntax error"},
        BadJson{"missing_k", R"({"image_shape": [1080, 1920]})", kExtr, "K: missing"},
        BadJson{"k_2x3", R"({"K": [[1,0,0],[0,1,0]], "image_shape": [1080, 1920]})", kExtr,
                "K: expected a 3x3 matrix, found 2 rows"},
        BadJson{"k_text", R"({"K": [[1,0,"x"],[0,1,0],[0,0,1]], "image_shape": [1080, 1920]})", kExtr,
                "K: expected numbers, found \"x\""},
        BadJson{"zero_focal", R"({"K": [[0,0,960],[0,900,540],[0,0,1]], "image_shape": [1080, 1920]})", kExtr,
                "expected positive focal lengths"},
        BadJson{"bad_shape", R"({"K": [[900,0,960],[0,900,540],[0,0,1]], "image_shape": [1080.5, 1920]})",
                kExtr, "image_shape: expected whole numbers 1..65535 [height, width], found [1080.5, 1920]"},
        // Past an int: undefined behaviour in the conversion (found by the gopro_calibration fuzzer).
        BadJson{"huge_shape", R"({"K": [[900,0,960],[0,900,540],[0,0,1]], "image_shape": [1080, 1.921e11]})",
                kExtr, "image_shape: expected whole numbers 1..65535 [height, width], found [1080, 192100000000]"},
        BadJson{"bad_unit", kIntr, R"({"unit": "furlong", "t": [1,2,3], "R": [[1,0,0],[0,1,0],[0,0,1]]})",
                "unit: expected m, cm or mm, found 'furlong'"},
        BadJson{"no_unit", kIntr, R"({"t": [1,2,3], "R": [[1,0,0],[0,1,0],[0,0,1]]})",
                "no `unit` field; declare the calibration's unit in the site file"},
        BadJson{"not_rotation", kIntr, R"({"unit": "m", "t": [1,2,3], "R": [[2,0,0],[0,1,0],[0,0,1]]})",
                "e.json': R/t: rotation: expected an orthonormal matrix"},
        BadJson{"short_t", kIntr, R"({"unit": "m", "t": [1,2], "R": [[1,0,0],[0,1,0],[0,0,1]]})",
                "t: expected 3 numbers, found 2"}),
    [](const ::testing::TestParamInfo<BadJson>& param_info) { return std::string(param_info.param.name); });

}  // namespace
}  // namespace occmap
