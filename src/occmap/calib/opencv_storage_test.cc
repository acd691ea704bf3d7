#include "occmap/calib/opencv_storage.h"

#include <gtest/gtest.h>

#include "occmap/calib/units.h"
#include "occmap/geometry/rotation.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

constexpr char kIntrinsic[] = R"(<?xml version="1.0"?>
<opencv_storage>
<camera_matrix type_id="opencv-matrix">
  <rows>3</rows><cols>3</cols><dt>d</dt>
  <data>1743.4 0.0 934.5 0.0 1735.1 444.4 0.0 0.0 1.0</data></camera_matrix>
<distortion_coefficients type_id="opencv-matrix">
  <rows>5</rows><cols>1</cols><dt>d</dt>
  <data>-0.43 0.61 0.0082 0.0019 -0.69</data></distortion_coefficients>
</opencv_storage>
)";

constexpr char kExtrinsicPlainText[] = R"(<?xml version="1.0"?>
<opencv_storage>
  <rvec>
    1.759099006652832 0.46710100769996643 -0.331699013710022
   </rvec>
  <tvec>
    -525.8941650390625 45.40763473510742 986.7235107421875
  </tvec>
</opencv_storage>
)";

TEST(OpenCvStorage, ReadsWildtrackStylePlainTextExtrinsicsInCentimetres) {
  testing::TempDir dir;
  testing::WriteText(dir / "intr.xml", kIntrinsic);
  testing::WriteText(dir / "extr.xml", kExtrinsicPlainText);
  auto p = ReadOpenCvCalibration(dir / "intr.xml", dir / "extr.xml", 0.01, ImageSize{1920, 1080});
  ASSERT_TRUE(p.ok()) << p.status().message();
  EXPECT_DOUBLE_EQ(p->fx_px, 1743.4);
  EXPECT_DOUBLE_EQ(p->cy_px, 444.4);
  EXPECT_DOUBLE_EQ(p->distortion[4], -0.69);
  EXPECT_NEAR(p->cam_from_world_translation_m.x(), -5.258941650390625, 1e-12);
  EXPECT_TRUE(p->cam_from_world_rotation.isApprox(
      RotationFromRodrigues({1.759099006652832, 0.46710100769996643, -0.331699013710022}), 1e-15));
  EXPECT_EQ(p->image_size, (ImageSize{1920, 1080}));
}

TEST(OpenCvStorage, WriteThenReadRoundTrips) {
  testing::TempDir dir;
  PinholeParameters p;
  p.image_size = {640, 480};
  p.fx_px = 500.25;
  p.fy_px = 501.5;
  p.cx_px = 320.125;
  p.cy_px = 239.75;
  p.distortion = {-0.1, 0.02, 0.001, -0.002, 0.003};
  p.cam_from_world_rotation = RotationFromRodrigues({0.3, -1.2, 2.0});
  p.cam_from_world_translation_m = {1.5, -2.25, 3.0};
  ASSERT_TRUE(WriteOpenCvCalibration(p, 0.001, dir / "i.xml", dir / "e.xml").ok());
  auto back = ReadOpenCvCalibration(dir / "i.xml", dir / "e.xml", 0.001, std::nullopt);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->image_size, p.image_size);
  EXPECT_DOUBLE_EQ(back->fx_px, p.fx_px);
  EXPECT_DOUBLE_EQ(back->cy_px, p.cy_px);
  EXPECT_EQ(back->distortion, p.distortion);
  EXPECT_TRUE(back->cam_from_world_rotation.isApprox(p.cam_from_world_rotation, 1e-14));
  EXPECT_TRUE(back->cam_from_world_translation_m.isApprox(p.cam_from_world_translation_m, 1e-14));
}

TEST(OpenCvStorage, IntrinsicsAloneRoundTrip) {
  testing::TempDir dir;
  OpenCvIntrinsics in;
  in.fx_px = 812.345678901234;
  in.fy_px = 813.5;
  in.cx_px = 639.25;
  in.cy_px = 358.125;
  in.distortion = {-0.21, 0.05, 0.0004, -0.0003, 0};
  in.image_size = ImageSize{1280, 720};
  ASSERT_TRUE(WriteOpenCvIntrinsics(in, dir / "intr.xml").ok());
  auto back = ReadOpenCvIntrinsics(dir / "intr.xml");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->fx_px, in.fx_px);
  EXPECT_EQ(back->fy_px, in.fy_px);
  EXPECT_EQ(back->cx_px, in.cx_px);
  EXPECT_EQ(back->cy_px, in.cy_px);
  EXPECT_EQ(back->distortion, in.distortion);
  EXPECT_EQ(back->image_size, in.image_size);
}

struct BadCalibration {
  const char* name;
  std::string intrinsic;
  std::string extrinsic;
  const char* expected;  // substring of the message after the file name
};

std::string Intrinsic(const std::string& k, const std::string& rows_cols = "<rows>3</rows><cols>3</cols>",
                      const std::string& dist = "<rows>5</rows><cols>1</cols><dt>d</dt><data>0 0 0 0 0</data>") {
  return "<?xml version=\"1.0\"?>\n<opencv_storage>\n<camera_matrix type_id=\"opencv-matrix\">" + rows_cols +
         "<dt>d</dt><data>" + k + "</data></camera_matrix>\n<distortion_coefficients type_id=\"opencv-matrix\">" +
         dist + "</distortion_coefficients>\n</opencv_storage>\n";
}
std::string Extrinsic(const std::string& r, const std::string& t) {
  return "<?xml version=\"1.0\"?>\n<opencv_storage>\n<rvec>" + r + "</rvec>\n<tvec>" + t +
         "</tvec>\n</opencv_storage>\n";
}
const std::string kGoodK = "1000 0 320 0 1000 240 0 0 1";
const std::string kGoodR = "0.1 0.2 0.3";
const std::string kGoodT = "1 2 3";

class OpenCvStorageBadInput : public ::testing::TestWithParam<BadCalibration> {};

TEST_P(OpenCvStorageBadInput, IsRejectedWithAClearMessage) {
  testing::TempDir dir;
  const auto& c = GetParam();
  if (!c.intrinsic.empty() || std::string(c.name) == "empty_intrinsic") testing::WriteText(dir / "i.xml", c.intrinsic);
  testing::WriteText(dir / "e.xml", c.extrinsic);
  auto p = ReadOpenCvCalibration(dir / "i.xml", dir / "e.xml", 0.01, ImageSize{640, 480});
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(ExitCodeFor(p.status()), 2);
  EXPECT_NE(p.status().message().find(c.expected), std::string::npos)
      << "message: " << p.status().message() << "\nexpected to contain: " << c.expected;
}

INSTANTIATE_TEST_SUITE_P(
    Table, OpenCvStorageBadInput,
    ::testing::Values(
        BadCalibration{"missing_intrinsic", "", Extrinsic(kGoodR, kGoodT), "file not found"},
        BadCalibration{"empty_intrinsic", "", Extrinsic(kGoodR, kGoodT),
                       "empty file, expected an OpenCV FileStorage calibration"},
        BadCalibration{"not_xml", "hello world", Extrinsic(kGoodR, kGoodT), "OpenCV FileStorage"},
        BadCalibration{"wrong_matrix_size", Intrinsic("1 2 3 4 5 6", "<rows>2</rows><cols>3</cols>"),
                       Extrinsic(kGoodR, kGoodT), "camera_matrix: expected a 3x3 matrix, found 2x3"},
        BadCalibration{"not_a_camera_matrix", Intrinsic("1000 0 320 0 1000 240 0 1 1"),
                       Extrinsic(kGoodR, kGoodT), "camera_matrix: expected [fx s cx; 0 fy cy; 0 0 1]"},
        BadCalibration{"nan_in_matrix", Intrinsic("1000 0 .Nan 0 1000 240 0 0 1"), Extrinsic(kGoodR, kGoodT),
                       "camera_matrix: expected finite numbers"},
        BadCalibration{"zero_focal_length", Intrinsic("0 0 320 0 1000 240 0 0 1"), Extrinsic(kGoodR, kGoodT),
                       "camera_matrix: expected positive focal lengths, found fx = 0, fy = 1000"},
        BadCalibration{"negative_focal_length", Intrinsic("1000 0 320 0 -5 240 0 0 1"),
                       Extrinsic(kGoodR, kGoodT), "expected positive focal lengths, found fx = 1000, fy = -5"},
        BadCalibration{"three_distortion_terms", Intrinsic(kGoodK, "<rows>3</rows><cols>3</cols>",
                                                           "<rows>3</rows><cols>1</cols><dt>d</dt><data>0 0 0</data>"),
                       Extrinsic(kGoodR, kGoodT), "distortion_coefficients: expected 4, 5, 8, 12 or 14 values, found 3"},
        BadCalibration{"rational_model_term", Intrinsic(kGoodK, "<rows>3</rows><cols>3</cols>",
                                                        "<rows>8</rows><cols>1</cols><dt>d</dt><data>0 0 0 0 0 0.5 0 0</data>"),
                       Extrinsic(kGoodR, kGoodT), "only k1 k2 p1 p2 k3 are supported, found coefficient 6 = 0.5"},
        BadCalibration{"nul_byte", Intrinsic(kGoodK), std::string("<?xml version=\0\0\"1.0\"?>\n<opencv_storage>\n", 41),
                       "e.xml': expected an OpenCV FileStorage text file, found a NUL byte at offset 14"},
        // OpenCV 4.6 dereferenced a null pointer here (found by the opencv_calibration fuzzer).
        BadCalibration{"unquoted_attribute_at_the_end", "<?xml version=", Extrinsic(kGoodR, kGoodT),
                       "i.xml':1: expected a quoted attribute value after '=', found the end of the file"},
        BadCalibration{"unquoted_attribute", Intrinsic(kGoodK), "<?xml version=\"1.0\"?>\n<opencv_storage>\n<rvec a=\n",
                       "e.xml':3: expected a quoted attribute value after '=', found the end of the file"},
        BadCalibration{"short_data", Intrinsic("1000 0 320 0 1000 240 0 0"), Extrinsic(kGoodR, kGoodT),
                       "camera_matrix: expected rows x cols = 3 x 3 = 9 numbers in data, found 8"},
        BadCalibration{"lowercase_nan", Intrinsic("1000 0 nan 0 1000 240 0 0 1"), Extrinsic(kGoodR, kGoodT),
                       "camera_matrix: "},
        BadCalibration{"huge_rvec", Intrinsic(kGoodK), Extrinsic("1e300 1e300 1e300", kGoodT),
                       "e.xml': rvec: expected a rotation vector of at most 1000 rad, found [1e+300, 1e+300, 1e+300]"},
        BadCalibration{"short_rvec", Intrinsic(kGoodK), Extrinsic("0.1 0.2", kGoodT), "rvec: expected 3 numbers, found 2"},
        BadCalibration{"text_in_tvec", Intrinsic(kGoodK), Extrinsic(kGoodR, "1 abc 3"),
                       "tvec: expected a finite number, found 'abc'"},
        // OpenCV 4.6 read these rows as 2^31 + 2 and allocated 51 GB (found by the fuzzer).
        BadCalibration{"rows_not_an_integer", Intrinsic(kGoodK, "<rows>[3</rows><cols>3</cols>"),
                       Extrinsic(kGoodR, kGoodT), "camera_matrix: rows: expected an integer, found '[3'"},
        BadCalibration{"cols_not_an_integer", Intrinsic(kGoodK, "<rows>3</rows><cols>3.5</cols>"),
                       Extrinsic(kGoodR, kGoodT), "camera_matrix: cols: expected an integer, found 3.5"},
        BadCalibration{"matrix_without_data", "<?xml version=\"1.0\"?>\n<opencv_storage>\n<camera_matrix "
                       "type_id=\"opencv-matrix\"><rows>30000</rows><cols>30000</cols><dt>d</dt></camera_matrix>\n"
                       "</opencv_storage>\n", Extrinsic(kGoodR, kGoodT),
                       "camera_matrix: expected an opencv-matrix (rows, cols, data), found no data"},
        BadCalibration{"missing_tvec", Intrinsic(kGoodK), "<?xml version=\"1.0\"?>\n<opencv_storage>\n<rvec>0 0 0</rvec>\n</opencv_storage>\n",
                       "tvec: missing"}),
    [](const ::testing::TestParamInfo<BadCalibration>& param_info) { return std::string(param_info.param.name); });

TEST(OpenCvStorage, MissingImageSizeIsAnError) {
  testing::TempDir dir;
  testing::WriteText(dir / "i.xml", Intrinsic(kGoodK));
  testing::WriteText(dir / "e.xml", Extrinsic(kGoodR, kGoodT));
  auto p = ReadOpenCvCalibration(dir / "i.xml", dir / "e.xml", 1.0, std::nullopt);
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.status().message().find("give the calibrated image size"), std::string::npos);
}

TEST(Units, ConvertsToMetres) {
  EXPECT_EQ(*MetresPerUnit("m"), 1.0);
  EXPECT_EQ(*MetresPerUnit("cm"), 0.01);
  EXPECT_EQ(*MetresPerUnit("mm"), 0.001);
  EXPECT_EQ(MetresPerUnit("inch").status().message(), "unit: expected m, cm or mm, found 'inch'");
}

}  // namespace
}  // namespace occmap
