#include "occmap/pipeline/fusion_stage.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

namespace occmap {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

FusionStage::FusionStage(const Site& site, const RunOptions& options, const FusionPlan& plan, const GroundLut& lut,
                         std::vector<CameraState>& cams, double fps)
    : site_(site),
      options_(options),
      plan_(plan),
      cams_(cams),
      fps_(fps),
      changes_(site, cams, plan.colour, options.change_pngs),
      fusion_(lut),
      frame_views_(cams.size()),
      background_views_(cams.size()),
      change_counts_(cams.size()),
      change_views_(cams.size()),
      protection_changes_(cams.size()),
      check_classes_(cams.size()),
      check_changes_(cams.size()),
      walked_people_(WalkedPeopleOptions{.hold_frames = std::max(1, static_cast<int>(std::lround(site.backgrounds.absorb_s * fps)))}),
      teacher_classes_(cams.size()),
      teacher_ratios_(cams.size()),
      last_frame_index_(options.start_frame),
      background_age_s_(cams.size()),
      refresh_(site.backgrounds, fps, options.warning) {
  for (auto& a : background_age_s_) a.Set(std::numeric_limits<double>::quiet_NaN());
}

Result<std::unique_ptr<FusionStage>> FusionStage::Create(const Site& site, const RunOptions& options,
                                                         const FusionPlan& plan, const GroundLut& lut,
                                                         std::vector<CameraState>& cams, double fps, Context& ctx) {
  std::unique_ptr<FusionStage> s(new FusionStage(site, options, plan, lut, cams, fps));
  for (size_t n = 0; n <= cams.size(); ++n) {
    const uint32_t expected = n < cams.size() ? lut.pixel_offset(static_cast<int>(n)) : lut.total_pixels();
    if (s->changes_.offset(n) != expected) return Internal("the change buffer and the tables order pixels apart");
  }
  if (plan.paper_and) s->fast_.emplace(lut);
  if (plan.people_detector) {
    OCCMAP_ASSIGN_OR_RETURN(ColumnLut columns, BuildColumnLut(site.LutInputs(), site.grid, site.plane_height_m,
                                                              site.people.columns, site.statics, ctx));
    s->column_lut_ = std::move(columns);
    s->column_fusion_.emplace(*s->column_lut_);
    if (site.people.detector == PeopleDetector::kExplain) s->explainer_.emplace(*s->column_lut_);
    if (site.people.occluders.learn) {  // from the cache's file for these tables, when there is one
      s->occluders_.emplace(*s->column_lut_, site.people.column, site.people.occluders);
      if (!options.cache_dir.empty()) {
        s->occluders_cache_ = options.cache_dir / "occluders" /
                              fmt::format("{}-{:016x}.txt", site.name, OccluderLearner::Fingerprint(*s->column_lut_));
        (void)s->occluders_->Load(s->occluders_cache_);  // missing, stale or corrupt: learned afresh
      }
    }
  }
  const BackgroundOptions& bo = site.backgrounds;
  if (plan.adaptive && bo.shadows.enabled && bo.shadows.floor_check) s->shadow_check_.emplace(lut);
  if (plan.adaptive) {
    std::vector<const CameraModel*> models;
    for (const auto& c : cams) models.push_back(c.cam->camera.get());
    ProtectionOptions po;
    po.person_height_m = bo.person_height_m;
    s->protection_.emplace(std::move(models), site.plane_height_m, po);
    if (bo.shadows.enabled && bo.shadows.learn) s->teachers_.emplace(lut);
  }
  return s;
}

void FusionStage::Process(FrameSet& set, Context& ctx) {
  // Fully fused (FastFusion::Fuse, FuseTolerant) only with every camera active.
  const bool all_active = std::all_of(set.active.begin(), set.active.end(), [](bool a) { return a; });
  const bool fused_now = (plan_.path == FusionPath::kFused || plan_.path == FusionPath::kFusedTolerant) &&
                         all_active && !set.changes_given;
  auto t0 = Clock::now();
  set.bits_ready = false;
  if (set.changes_given) {  // the edges' changes (occmap fuse): fused from the buffer as they are
    set.changes_ready = true;
  } else {
    set.changes_ready = false;
    if (!fused_now) DetectChanges(set, ctx);
  }
  detect_s_.Add(Since(t0));
  t0 = Clock::now();
  Fuse(set, fused_now, ctx);
  fuse_s_.Add(Since(t0));
  if (column_fusion_) FindPeople(set, ctx);
  if (plan_.adaptive) UpdateBackgrounds(set, ctx);
}

// Change detection, cameras in parallel, into the set's change buffer; with the adaptive
// model's shadows, the floor check before the tolerance; --change-pngs' pictures.
void FusionStage::DetectChanges(FrameSet& set, Context& ctx) {
  const std::vector<bool>& active = set.active;
  const size_t n_cams = cams_.size();
  changes_.EnsureBuffer(set);
  const bool shadow_check = shadow_check_.has_value();
  ParallelFor(ctx, 0, static_cast<int64_t>(n_cams), [&](int64_t b, int64_t e, int) {
    for (int64_t n = b; n < e; ++n) {
      if (active[n]) changes_.Compute(set, n, cams_[n].raw_changes, cams_[n].dilate_scratch, !shadow_check);
    }
  });
  const int r = site_.detection.tolerance_px;
  if (shadow_check) {  // shadows whose floor the other cameras see lit are changes; then the tolerance
    for (size_t n = 0; n < n_cams; ++n) {
      const bool checked = active[n] && cams_[n].model;
      check_classes_[n] = checked ? cams_[n].model->pixel_classes() : ImageView<const uint8_t>();
      check_changes_[n] = !checked ? ImageView<uint8_t>() : r > 0 ? cams_[n].raw_changes.view() : changes_.Slice(set, n);
    }
    shadow_check_->Apply(check_classes_, check_changes_);
    if (r > 0) {
      ParallelFor(ctx, 0, static_cast<int64_t>(n_cams), [&](int64_t b, int64_t e, int) {
        for (int64_t n = b; n < e; ++n) {
          if (active[n]) changes_.Widen(static_cast<size_t>(n), cams_[n].raw_changes.view(), changes_.Slice(set, n), cams_[n].dilate_scratch);
        }
      });
    }
  }
  if (site_.detection.blocks()) {
    ParallelFor(ctx, 0, static_cast<int64_t>(n_cams), [&](int64_t b, int64_t e, int) {
      for (int64_t n = b; n < e; ++n) {
        if (active[n]) changes_.Quantise(set, static_cast<size_t>(n));
      }
    });
  }
  set.changes_ready = true;
  if (options_.change_pngs) {
    set.change_pictures.resize(n_cams);
    for (size_t n = 0; n < n_cams; ++n) {
      if (!active[n]) continue;
      const ImageSize size = cams_[n].cam->camera->image_size();
      // Before the tolerance: the raw image when there is one, else the change buffer.
      const ImageView<const uint8_t> src = r > 0 ? ImageView<const uint8_t>(cams_[n].raw_changes.view())
                                                 : std::as_const(changes_).Slice(std::as_const(set), n);
      Image<uint8_t>& pic = set.change_pictures[n];
      if (pic.width() != size.width || pic.height() != size.height) pic = Image<uint8_t>(size.width, size.height);
      for (int y = 0; y < size.height; ++y) {
        const uint8_t* a = src.row(y);
        uint8_t* b = pic.row(y);
        for (int x = 0; x < size.width; ++x) b[x] = a[x] != 0 ? 255 : 0;
      }
    }
  }
}

void FusionStage::Fuse(FrameSet& set, bool fused_now, Context& ctx) {
  const bool all_active = std::all_of(set.active.begin(), set.active.end(), [](bool a) { return a; });
  if (fused_now) {
    for (size_t n = 0; n < cams_.size(); ++n) {
      frame_views_[n] = set.frames[n].gray.view();
      background_views_[n] = cams_[n].background_gray.view();
    }
    if (plan_.path == FusionPath::kFusedTolerant) {
      fast_->FuseTolerant(frame_views_, background_views_, site_.detection.threshold, site_.detection.tolerance_px, ctx,
                          set.map, set.change_bits);
      set.bits_ready = true;
    } else {
      fast_->Fuse(frame_views_, background_views_, site_.detection.threshold, ctx, set.map);
    }
  } else if (plan_.paper_and && all_active) {
    fast_->FuseChanges(set.changes, ctx, set.map);
  } else {
    fusion_.Fuse(set.changes, set.active, site_.fusion, set.map);
  }
}

// The people's column fusion and the explanation of the views, from the change buffer.
void FusionStage::FindPeople(FrameSet& set, Context& ctx) {
  const auto t0 = Clock::now();
  const std::vector<bool>& active = set.active;
  for (size_t n = 0; n < cams_.size(); ++n) change_views_[n] = std::as_const(changes_).Slice(std::as_const(set), n);
  ParallelFor(ctx, 0, static_cast<int64_t>(cams_.size()), [&](int64_t b, int64_t e, int) {
    for (int64_t n = b; n < e; ++n)
      if (active[n]) change_counts_[n].Build(change_views_[n]);
  });
  column_fusion_->Fuse(change_counts_, active, site_.people.column, ctx, set.column_map);
  if (explainer_) explainer_->Explain(change_views_, change_counts_, active, set.column_map, site_.people.explain, ctx, set.people);
  people_s_.Add(Since(t0));
  if (occluders_) {
    const auto t1 = Clock::now();
    occluders_->Observe(change_views_, change_counts_, active, set.people, set.frame_index, ctx);
    occluders_s_.Add(Since(t1));
  }
}

Status FusionStage::SaveLearnedOccluders(const std::filesystem::path& out, std::vector<std::string>& written) const {
  if (!occluders_) return Status::Ok();
  OCCMAP_RETURN_IF_ERROR(occluders_->Save(out / "occluders.txt"));
  written.push_back((out / "occluders.txt").string());
  if (occluders_cache_.empty()) return Status::Ok();
  std::error_code ec;
  std::filesystem::create_directories(occluders_cache_.parent_path(), ec);
  (void)occluders_->Save(occluders_cache_);  // a cache that cannot be written is only not reused
  return Status::Ok();
}

// The adaptive backgrounds follow the frame where the map says nothing stands.
void FusionStage::UpdateBackgrounds(FrameSet& set, Context& ctx) {
  const auto t0 = Clock::now();
  const std::vector<bool>& active = set.active;
  const size_t n_cams = cams_.size();
  for (size_t n = 0; n < n_cams; ++n) {
    protection_changes_[n] = active[n] ? std::as_const(changes_).Slice(std::as_const(set), n) : ImageView<const uint8_t>();
  }
  protection_->Compute(set.map, protection_changes_);
  if (explainer_) {  // the people the views explain, though their feet may leave the floor unchanged
    people_positions_.clear();
    for (const ExplainedPerson& p : set.people) people_positions_.emplace_back(p.x_m, p.y_m);
    protection_->AddPeople(people_positions_, site_.tracking.person_radius_m(), walked_people_.Update(people_positions_));
    protection_->AddMissedPeople(walked_people_.missed_m(), site_.tracking.person_radius_m());
  }
  // Without models (occmap fuse: the edges keep them) only the protection is wanted.
  const bool any_model = std::any_of(cams_.begin(), cams_.end(), [](const CameraState& c) { return c.model != nullptr; });
  if (teachers_ && any_model) {  // the pixels that show the floor darkened, as the cameras agree
    for (size_t n = 0; n < n_cams; ++n) {
      teacher_classes_[n] = active[n] && cams_[n].model ? cams_[n].model->pixel_classes() : ImageView<const uint8_t>();
      teacher_ratios_[n] = active[n] && cams_[n].model ? cams_[n].model->pixel_ratios() : ImageView<const uint8_t>();
    }
    teachers_->Compute(teacher_classes_, teacher_ratios_, set.map, protection_->person_positions(),
                        ShadowTeachers::kPersonRadiusM);
  }
  ParallelFor(ctx, 0, static_cast<int64_t>(n_cams), [&](int64_t b, int64_t e, int) {
    for (int64_t n = b; n < e; ++n) {
      if (active[n] && cams_[n].model) {
        if (teachers_) cams_[n].model->LearnShadows(FrameYuv(set.frames[n]), teachers_->image(static_cast<size_t>(n)).view());
        cams_[n].model->Update(FrameYuv(set.frames[n]), protection_->image(static_cast<size_t>(n)).view(), set.frame_index);
      }
    }
  });
  last_frame_index_ = set.frame_index;
  if (set.frame_index >= next_age_frame_) {  // a pass over the pixels: about once a second
    for (size_t n = 0; n < n_cams; ++n) {
      if (cams_[n].model) background_age_s_[n].Set(cams_[n].model->MeanAgeS(set.frame_index));
    }
    next_age_frame_ = set.frame_index + std::max<int64_t>(1, std::lround(fps_));
  }
  // The cache is a head start for a restart, not an output: a failed write leaves the entry as
  // it was (the planes are swapped in together), is counted and said once, and the next period
  // or the stop tries again.
  refresh_.After(set.frame_index, cams_);
  background_s_.Add(Since(t0));
}

}  // namespace occmap
