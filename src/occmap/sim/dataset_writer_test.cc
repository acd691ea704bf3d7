#include "occmap/sim/dataset_writer.h"

#include <gtest/gtest.h>

#include <fmt/core.h>

#include <cmath>

#include "occmap/io/frame_source.h"
#include "occmap/sim/builtin_scenes.h"
#include "occmap/sim/renderer.h"
#include "occmap/sim/scene_yaml.h"
#include "occmap/sim/sim_test_util.h"
#include "occmap/site/site.h"
#include "occmap/util/file_util.h"
#include "occmap/util/image_io.h"
#include "occmap/util/testing.h"

namespace occmap::sim {
namespace {

void ExpectSiteMatchesScene(const Scene& scene, const Site& site) {
  ASSERT_EQ(site.cameras.size(), scene.num_cameras());
  EXPECT_EQ(site.grid, scene.grid());
  for (size_t c = 0; c < scene.num_cameras(); ++c) {
    EXPECT_EQ(site.cameras[c].id, scene.camera_id(c));
    EXPECT_EQ(site.cameras[c].camera->kind(), scene.camera(c).kind());
    EXPECT_EQ(site.cameras[c].camera->image_size(), scene.camera(c).image_size());
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(2.5, 2, 0), Eigen::Vector3d(3, 1, 1.5)}) {
      const auto a = scene.camera(c).Project(p), b = site.cameras[c].camera->Project(p);
      ASSERT_TRUE(a && b);
      EXPECT_NEAR((*a - *b).norm(), 0, 1e-6) << site.cameras[c].id;
    }
  }
}

TEST(DatasetWriter, WritesASiteThatLoadsAndProjectsLikeTheScene) {
  const Scene lab = sim_testing::SmallLab(0.25, 4);
  occmap::testing::TempDir dir;
  Context ctx(2);
  DatasetOptions options;
  options.out_dir = dir / "lab";
  int64_t last_done = -1, total = 0;
  auto summary = WriteDataset(lab, options, ctx, [&](const DatasetProgress& p) {
    EXPECT_GE(p.done, last_done);
    last_done = p.done;
    total = p.total;
  });
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  EXPECT_EQ(last_done, total);
  EXPECT_EQ(total, 4 * 4 + 4);
  auto site = LoadSite(summary->site_file);
  ASSERT_TRUE(site.ok()) << site.status().message();
  ExpectSiteMatchesScene(lab, *site);
  // Masks, backgrounds and frames are those of the renderer.
  const CameraRenderer r(lab, 2, ctx);
  EXPECT_TRUE(site->cameras[2].mask == r.floor_mask());
  auto bg = ReadRgbImage(*site->cameras[2].background);
  ASSERT_TRUE(bg.ok());
  EXPECT_TRUE(*bg == r.Background());
  RenderedView view;
  r.Render(lab.StateAt(3), ctx, &view);
  auto frame = ReadRgbImage(options.out_dir / "frames" / "cam3" / "000003.png");
  ASSERT_TRUE(frame.ok()) << frame.status().message();
  EXPECT_TRUE(*frame == view.rgb);
  auto changes = ReadGrayImage(options.out_dir / "gt" / "changes" / "cam3" / "000003.png");
  ASSERT_TRUE(changes.ok());
  EXPECT_TRUE(*changes == ChangeMask(view.ids));
  // The pipeline's frame source reads the sequence.
  auto source = OpenFrameSource(site->cameras[0].source, {});
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame frame_read;
  for (int i = 0; i < 4; ++i) {
    auto got = (*source)->Read(frame_read);
    ASSERT_TRUE(got.ok() && *got) << i;
  }
  auto end = (*source)->Read(frame_read);
  ASSERT_TRUE(end.ok());
  EXPECT_FALSE(*end);
  // Ground truth: one line per frame, every object present.
  auto gt = ReadGroundTruth(options.out_dir / "ground_truth.jsonl");
  ASSERT_TRUE(gt.ok()) << gt.status().message();
  ASSERT_EQ(gt->size(), 4u);
  EXPECT_EQ((*gt)[3].objects.size(), 5u);
  EXPECT_DOUBLE_EQ((*gt)[3].time_s, 0.3);
  auto hull = ReadGrayImage(options.out_dir / "gt" / "hull" / "000002.png");
  ASSERT_TRUE(hull.ok());
  EXPECT_EQ(hull->width(), lab.grid().cells_x);
  EXPECT_EQ(hull->height(), lab.grid().cells_y);
  EXPECT_TRUE(std::filesystem::exists(options.out_dir / "gt" / "footprint" / "000003.png"));
  EXPECT_TRUE(std::filesystem::exists(options.out_dir / "scene.json"));
  EXPECT_TRUE(std::filesystem::exists(options.out_dir / "README.txt"));
}

TEST(DatasetWriter, TsaiCamerasAndVideoFramesLoadToo) {
  BuiltinSceneOptions o;
  o.image_scale = 0.25;
  o.num_frames = 3;
  const Scene clemson = Scene::Create(MakeClemsonSceneSpec(o)).value();
  occmap::testing::TempDir dir;
  Context ctx(2);
  DatasetOptions options;
  options.out_dir = dir / "clemson";
  options.frame_format = DatasetOptions::FrameFormat::kVideo;
  options.gt_rasters = false;
  auto summary = WriteDataset(clemson, options, ctx);
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  auto site = LoadSite(summary->site_file);
  ASSERT_TRUE(site.ok()) << site.status().message();
  ExpectSiteMatchesScene(clemson, *site);
  EXPECT_EQ(site->cameras[0].source.kind, FrameSourceSpec::Kind::kVideo);
  auto source = OpenFrameSource(site->cameras[0].source, {});
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame f;
  auto got = (*source)->Read(f);
  ASSERT_TRUE(got.ok() && *got);
  EXPECT_EQ(f.gray.width(), 160);
}

TEST(DatasetWriter, RejectsAnEmptyOutputFolder) {
  const Scene lab = sim_testing::SmallLab(0.25, 1);
  Context ctx(1);
  EXPECT_EQ(WriteDataset(lab, DatasetOptions{}, ctx).status().message(),
            "output folder: expected a path, found an empty one");
}


TEST(DatasetWriter, ShadowMasksAndASiteWithoutBackgroundsOrWithItsOwnDetection) {
  SceneSpec spec = sim_testing::OneObjectSpec(ObjectClass::kBox);
  spec.objects[0].appearance.height_m = 0.5;
  spec.photometry.lighting.direction_to_light = Eigen::Vector3d(1, 0.3, 1).normalized();
  spec.photometry.shadows = true;
  MovingObjectSpec outside = spec.objects[0];  // beyond the grid's east edge (x >= 4 m)
  outside.id = 8;
  outside.path = {{0.0, {4.25, 1.5}, false}, {10.0, {4.25, 1.5}, false}};
  spec.objects.push_back(outside);
  const Scene scene = Scene::Create(spec).value();
  occmap::testing::TempDir dir;
  Context ctx(2);
  DatasetOptions options;
  options.out_dir = dir / "one";
  options.site_backgrounds = false;
  options.site_detection_yaml = "detection:\n  threshold: 31\n  tolerance_px: 2";
  auto summary = WriteDataset(scene, options, ctx);
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  auto site = LoadSite(summary->site_file);
  ASSERT_TRUE(site.ok()) << site.status().message();
  for (const SiteCamera& c : site->cameras) EXPECT_FALSE(c.background.has_value()) << c.id;
  EXPECT_TRUE(std::filesystem::exists(options.out_dir / "backgrounds" / "top.png"));
  auto text = ReadFileToString(summary->site_file);
  ASSERT_TRUE(text.ok());
  EXPECT_NE(text->find("\ndetection:\n  threshold: 31\n  tolerance_px: 2\n#"), std::string::npos) << *text;
  EXPECT_EQ(text->find("threshold: 20"), std::string::npos);
  // The shadow masks are the renderer's.
  const CameraRenderer r(scene, 1, ctx);
  RenderedView view;
  r.Render(scene.StateAt(2), ctx, &view, /*noise=*/true, /*shadow_mask=*/true);
  auto shadow = ReadGrayImage(options.out_dir / "gt" / "shadows" / "side" / "000002.png");
  ASSERT_TRUE(shadow.ok()) << shadow.status().message();
  EXPECT_TRUE(*shadow == view.shadow);
  int64_t marked = 0;
  for (int y = 0; y < shadow->height(); ++y) {
    for (int x = 0; x < shadow->width(); ++x) marked += (*shadow)(x, y) == 255;
  }
  EXPECT_GT(marked, 30);
  // Ground truth lists the object inside the area only.
  auto gt = ReadGroundTruth(options.out_dir / "ground_truth.jsonl");
  ASSERT_TRUE(gt.ok()) << gt.status().message();
  ASSERT_EQ((*gt)[0].objects.size(), 1u);
  EXPECT_EQ((*gt)[0].objects[0].id, 7);
  // Without shadows, no shadow masks.
  spec.photometry.shadows = false;
  options.out_dir = dir / "no-shadows";
  ASSERT_TRUE(WriteDataset(Scene::Create(spec).value(), options, ctx).ok());
  EXPECT_FALSE(std::filesystem::exists(options.out_dir / "gt" / "shadows"));
}

// Root mean square difference of the luma of two images (JPEG halves the chroma's resolution:
// its error on the lab's thin, coloured book spines says little about the quality).
double LumaRmsDifference(const Image<Rgb8>& a, const Image<Rgb8>& b) {
  double sum = 0;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      const Rgb8 p = a(x, y), q = b(x, y);
      const double d = 0.299 * (p.r - q.r) + 0.587 * (p.g - q.g) + 0.114 * (p.b - q.b);
      sum += d * d;
    }
  }
  return std::sqrt(sum / (static_cast<double>(a.width()) * a.height()));
}

// Mean absolute step between horizontal neighbours of the green channel, across the 8-pixel
// block boundaries of JPEG and inside the blocks.
void BlockSteps(const Image<Rgb8>& image, double* across, double* inside) {
  double a = 0, na = 0, i = 0, ni = 0;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 1; x < image.width(); ++x) {
      const double d = std::abs(double(image(x, y).g) - image(x - 1, y).g);
      if (x % 8 == 0) {
        a += d;
        na += 1;
      } else {
        i += d;
        ni += 1;
      }
    }
  }
  *across = a / na;
  *inside = i / ni;
}

TEST(DatasetWriter, JpegArtefactsGrowAsTheQualityFalls) {
  // A lab frame through the real camera, stored at falling JPEG qualities: the error against
  // the rendered frame grows, is a few grey levels at the preset's 75, and at a low quality
  // the 8 x 8 blocks show (steps across their edges larger than inside them).
  BuiltinSceneOptions o;
  o.image_scale = 0.5;
  o.num_frames = 4;
  o.real_camera = true;
  o.supersample = 1;
  const Scene lab = Scene::Create(MakeLabSceneSpec(o)).value();
  Context ctx(2);
  const CameraRenderer r(lab, 1, ctx);
  RenderedView view;
  r.Render(lab.StateAt(3), ctx, &view);
  occmap::testing::TempDir dir;
  double previous = 0;
  for (int quality : {95, 75, 40, 10}) {
    const auto path = dir / fmt::format("q{}.jpg", quality);
    ASSERT_TRUE(WriteJpeg(path, view.rgb.view(), quality).ok());
    auto back = ReadRgbImage(path);
    ASSERT_TRUE(back.ok()) << back.status().message();
    const double rms = LumaRmsDifference(*back, view.rgb);
    double across = 0, inside = 0;
    BlockSteps(*back, &across, &inside);
    EXPECT_GT(rms, previous) << "quality " << quality;
    if (quality == 75) {
      EXPECT_GT(rms, 1.0);
      EXPECT_LT(rms, 6.0);
    }
    if (quality == 10) {
      EXPECT_GT(across, 1.3 * inside) << "blocks";
    }
    previous = rms;
  }
  // The rendered frame itself has no blocks.
  double across = 0, inside = 0;
  BlockSteps(view.rgb, &across, &inside);
  EXPECT_LT(across, 1.1 * inside);
  EXPECT_EQ(WriteJpeg(dir / "bad.jpg", view.rgb.view(), 0).message(),
            fmt::format("'{}': JPEG quality: expected 1..100, found 0", (dir / "bad.jpg").string()));
}

TEST(DatasetWriter, RealCameraWritesJpegFramesTheRunReadsWithGainsCarriedInOrder) {
  BuiltinSceneOptions o;
  o.image_scale = 0.25;
  o.num_frames = 6;
  o.real_camera = true;
  const Scene lab = Scene::Create(MakeLabSceneSpec(o)).value();
  ASSERT_EQ(lab.spec().photometry.camera.jpeg_quality, 75);
  occmap::testing::TempDir dir;
  Context ctx(2);
  DatasetOptions options;
  options.out_dir = dir / "lab";
  auto summary = WriteDataset(lab, options, ctx);
  ASSERT_TRUE(summary.ok()) << summary.status().message();
  auto site = LoadSite(summary->site_file);
  ASSERT_TRUE(site.ok()) << site.status().message();
  ExpectSiteMatchesScene(lab, *site);
  EXPECT_FALSE(std::filesystem::exists(options.out_dir / "frames" / "cam2" / "000005.png"));
  // Frame 5 of camera 2 is the renderer's, its gains carried over frames 0-4, JPEG-compressed.
  const CameraRenderer r(lab, 1, ctx);
  CameraResponse response = r.NewResponse();
  RenderedView view;
  for (int64_t f = 0; f <= 5; ++f) r.Render(lab.StateAt(f), ctx, &view, /*noise=*/true, /*shadow_mask=*/true, &response);
  auto source = OpenFrameSource(site->cameras[1].source, {.colour = true});
  ASSERT_TRUE(source.ok()) << source.status().message();
  Frame frame;
  for (int f = 0; f <= 5; ++f) ASSERT_TRUE((*source)->Read(frame).value());
  const double rms = LumaRmsDifference(frame.rgb, view.rgb);
  EXPECT_GT(rms, 0.5);
  EXPECT_LT(rms, 6.0);
  // Contact shadows: shadow masks, the renderer's.
  auto shadow = ReadGrayImage(options.out_dir / "gt" / "shadows" / "cam2" / "000005.png");
  ASSERT_TRUE(shadow.ok()) << shadow.status().message();
  EXPECT_TRUE(*shadow == view.shadow);
  // The scene file keeps the camera: it renders the same dataset again.
  auto again = LoadSceneYaml(options.out_dir / "scene.yaml");
  ASSERT_TRUE(again.ok()) << again.status().message();
  EXPECT_EQ(again->photometry.camera, lab.spec().photometry.camera);
  EXPECT_EQ(again->photometry.contact_shadows.strength, 0.5);
  auto json = ReadFileToString(options.out_dir / "scene.json");
  ASSERT_TRUE(json.ok());
  EXPECT_NE(json->find("\"frames_format\": \"jpeg\""), std::string::npos);
}

TEST(DatasetWriter, RejectsADetectionSectionThatIsNotOne) {
  const Scene lab = sim_testing::SmallLab(0.25, 1);
  Context ctx(1);
  occmap::testing::TempDir dir;
  DatasetOptions options;
  options.out_dir = dir / "x";
  options.site_detection_yaml = "threshold: 3";
  EXPECT_EQ(WriteDataset(lab, options, ctx).status().message(),
            "site detection YAML: expected a section starting with 'detection:', found 'threshold: 3'");
}

}  // namespace
}  // namespace occmap::sim
