#include "occmap/calib/tsai_yaml.h"

#include <gtest/gtest.h>

#include "occmap/geometry/rotation.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

const std::string kCamera = R"(c0:
  image_width: 720
  image_height: 576
  Ncx: 576
  Nfx: 576
  dx: 0.023
  dy: 0.023
  dpx: 0.023
  dpy: 0.023
  Cx: 366.514507
  Cy: 305.832552
  sx: 1
  f: 20.161920
  kappa1: 5.720865e-04
  Tx: -4.8441913843e+03
  Ty: 5.5109448682e+02
  Tz: 4.9667438357e+03
  Rx: 1.9007833770e+00
  Ry: 4.9730769727e-01
  Rz: 1.8415452559e-01
  r1: 0.86400969361424029
  r7: -0.47706108597586389
)";

TEST(TsaiYaml, ReadsANamedCameraBlockInMillimetres) {
  testing::TempDir dir;
  testing::WriteText(dir / "t.yaml", kCamera);
  auto p = ReadTsaiYaml(dir / "t.yaml", "c0");
  ASSERT_TRUE(p.ok()) << p.status().message();
  EXPECT_EQ(p->image_size, (ImageSize{720, 576}));
  EXPECT_DOUBLE_EQ(p->f_mm, 20.16192);
  EXPECT_NEAR(p->cam_from_world_translation_m.x(), -4.8441913843, 1e-12);
  EXPECT_NEAR(p->cam_from_world_rotation(0, 0), 0.86400969361424029, 1e-15);
}

TEST(TsaiYaml, AConsistentCameraCentreIsAccepted) {
  testing::TempDir dir;
  std::string text = kCamera;
  text.replace(text.find("  r1:"), 0, "  camera_centre_world: [6466.178309700, -1562.848552079, 2045.600669980]\n");
  testing::WriteText(dir / "t.yaml", text);
  auto p = ReadTsaiYaml(dir / "t.yaml", "c0");
  EXPECT_TRUE(p.ok()) << p.status().message();
}

TEST(TsaiYaml, WriteThenReadRoundTrips) {
  testing::TempDir dir;
  testing::WriteText(dir / "t.yaml", kCamera);
  const TsaiParameters p = *ReadTsaiYaml(dir / "t.yaml", "c0");
  ASSERT_TRUE(WriteTsaiYaml(p, 1.9007833770, 0.49730769727, 0.18415452559, "", dir / "single.yaml").ok());
  auto back = ReadTsaiYaml(dir / "single.yaml", "");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->f_mm, p.f_mm);
  EXPECT_EQ(back->kappa1_per_mm2, p.kappa1_per_mm2);
  EXPECT_EQ(back->Cx_px, p.Cx_px);
  EXPECT_TRUE(back->cam_from_world_rotation.isApprox(p.cam_from_world_rotation, 1e-15));
  EXPECT_TRUE(back->cam_from_world_translation_m.isApprox(p.cam_from_world_translation_m, 1e-15));
}

struct BadTsai {
  const char* name;
  std::string from;
  std::string to;
  const char* expected;
};

class TsaiYamlBadInput : public ::testing::TestWithParam<BadTsai> {};

TEST_P(TsaiYamlBadInput, IsRejectedWithFileLineAndField) {
  testing::TempDir dir;
  std::string text = kCamera;
  const auto pos = text.find(GetParam().from);
  ASSERT_NE(pos, std::string::npos);
  text.replace(pos, GetParam().from.size(), GetParam().to);
  testing::WriteText(dir / "t.yaml", text);
  auto p = ReadTsaiYaml(dir / "t.yaml", "c0");
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(ExitCodeFor(p.status()), 2);
  EXPECT_NE(p.status().message().find(GetParam().expected), std::string::npos) << p.status().message();
}

INSTANTIATE_TEST_SUITE_P(
    Table, TsaiYamlBadInput,
    ::testing::Values(
        BadTsai{"nan_focal", "f: 20.161920", "f: .nan", "t.yaml:13: c0.f: expected a finite number, found '.nan'"},
        BadTsai{"zero_focal", "f: 20.161920", "f: 0", "t.yaml:13: c0.f: expected a positive value, found 0"},
        BadTsai{"negative_dx", "dx: 0.023", "dx: -0.023", "t.yaml:6: c0.dx: expected a positive value"},
        BadTsai{"missing_kappa", "  kappa1: 5.720865e-04\n", "", "t.yaml:2: c0: missing required field 'kappa1'"},
        BadTsai{"typo", "kappa1:", "kapa1:", "unknown field 'kapa1' (did you mean 'kappa1'?)"},
        BadTsai{"inconsistent_r1", "r1: 0.86400969361424029", "r1: 0.5",
                "t.yaml:21: c0.r1: expected 0.86400969361424029 from Rx, Ry, Rz, found 0.5"},
        BadTsai{"inconsistent_dpx", "dpx: 0.023", "dpx: 0.03", "c0.dpx: expected dx * Ncx / Nfx = 0.023, found 0.03"},
        BadTsai{"wrong_camera", "c0:", "c9:", "no camera 'c0' (found: c9)"},
        // The terrace file's c0 centre is [6466.178..., -1562.848..., 2045.600...] mm.
        BadTsai{"inconsistent_centre", "  r1:", "  camera_centre_world: [6466.18, -1562.85, 2045.7]\n  r1:",
                "t.yaml:21: c0.camera_centre_world: expected -R^T T = [6466.178309"},
        BadTsai{"centre_not_three", "  r1:", "  camera_centre_world: [1, 2]\n  r1:", "c0.camera_centre_world"},
        BadTsai{"bad_size", "image_width: 720", "image_width: 0", "image size: expected 1..65535, found 0x576"}),
    [](const ::testing::TestParamInfo<BadTsai>& param_info) { return std::string(param_info.param.name); });

TEST(TsaiYaml, ReadsEveryTerraceCamera) {
  OCCMAP_REQUIRE_DATASETS(root);
  for (const char* cam : {"c0", "c1", "c2", "c3"}) {
    auto p = ReadTsaiYaml(root / "tsai-terrace" / "terrace_cameras.yaml", cam);
    ASSERT_TRUE(p.ok()) << p.status().message();
    EXPECT_EQ(p->image_size, (ImageSize{720, 576}));
  }
}

}  // namespace
}  // namespace occmap
