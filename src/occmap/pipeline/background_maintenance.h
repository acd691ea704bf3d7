// What only a multi-camera system knows when it updates a background: where the fused map says
// something stands, and whether that something is a person.
//
// From each frame's map (after the fusion), every group of occupied cells of at least
// min_area_m2 is an object; its cells' bounding box, widened by margin_m, is lifted to a box
// of height_m and projected into every camera: the pixels inside the projection are protected
// (BackgroundModel::kObject) and do not follow the frame. An object is a person when the
// cameras that see it see change at person_height_m above its centroid (a majority of them,
// read in a window of 2 pixels around the projection): its pixels are kPerson, and a person
// is never absorbed into the background however long it stands. The rest of the image is
// kFree: what changes there is not an object on the floor, and becomes background.
//
//   BackgroundProtection protection(cameras, options);
//   protection.Compute(map, changes, active);      // after the fusion of a frame
//   model.Update(frame, protection.image(n).view(), frame_index);
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "occmap/fusion/blobs.h"
#include "occmap/fusion/occupancy_map.h"
#include "occmap/geometry/camera_model.h"
#include "occmap/lut/ground_lut.h"
#include "occmap/util/image.h"

namespace occmap {

struct ProtectionOptions {
  double min_area_m2 = 0.01;     // smaller specks of occupied cells protect nothing
  double margin_m = 0.25;        // around an object's cells
  double height_m = 2.1;         // of the protected box
  double person_height_m = 1.2;  // change seen here above the centroid: a person
};

class BackgroundModel;

// One protected box: the upright box of radius_m around (x_m, y_m) (metres, floor frame),
// height ProtectionOptions::height_m, marked `value` (BackgroundModel::kObject, kPerson or
// kWalkedPerson) in every camera's protection image. What the fuse sends the edges
// (pipeline/protection_message.h): they draw the boxes into their own cameras.
struct ProtectedBox {
  double x_m = 0, y_m = 0, radius_m = 0;
  uint8_t value = 1;
  friend bool operator==(const ProtectedBox&, const ProtectedBox&) = default;
};

// Learned backgrounds checked against each other through the floor (after learning, before
// the run): a floor cell looks alike from every camera, while a person who stood through the
// learning window covers different cells in different views. Per block of 4 x 4 cells, the
// consensus is the median over the cameras that see it (at least three) of their backgrounds'
// mean luma there, each camera brought to a reference camera's exposure by the median ratio
// over the blocks both see. A pixel takes its alternative (BackgroundLearner's second cluster)
// when that is closer to its block's consensus than its background by more than threshold; when
// either is that much closer, the pixel is settled and drops its alternative (the other cluster
// is someone who stood there: swapping it back in would hide them when they stand there again).
// Given the cameras, the blocks go on beyond the grid by the grid's size on every side, over the
// plane each pixel's ray meets: a low camera sees most of a standing person against floor far
// behind them. It cannot fix the person's own footprint (every camera saw the feet there),
// pixels whose ray meets no plane seen by three cameras (sky, walls), nor pixels without an
// alternative (covered for over 90 % of the window).
struct ConsensusResult {
  int64_t pixels_checked = 0;  // floor pixels whose block has a consensus
  int64_t pixels_swapped = 0;  // took their alternative
  int64_t pixels_settled = 0;  // decided either way: their alternative is dropped
};
// cameras: at the models' image size, to carry the check beyond the grid (empty: the grid only).
// chroma_threshold (0: luma alone; the models' chroma otherwise, each camera's white balance
// matched to the reference camera's): a pixel keeps its background for good only when its Cb
// and Cr are also within it of the block's consensus.
// keep (empty: none): cameras whose models vote but are left as they are (backgrounds and
// alternatives), their pixels not counted: a background reused from an entry its running model
// wrote (CameraState::background_from_model) was checked when first learned, and holds what
// the model has taken in since, a change one camera sees alone among them.
// drop_kept: a pixel that keeps its background drops its alternative. Before settling
// (pipeline/settle_backgrounds.h, drop_kept false) not on a block something stood on (most of
// the cameras that see it have two looks over a quarter of its pixels): at a person's feet every
// camera saw the person, so the check keeps them there; the pass takes the floor when they walk
// away, and drops every alternative at its end.
ConsensusResult ResolveLearnedBackgrounds(const GroundLut& lut, const std::vector<const CameraModel*>& cameras,
                                          double plane_height_m, const std::vector<BackgroundModel*>& models,
                                          int threshold, int chroma_threshold, bool drop_kept = true,
                                          const std::vector<bool>& keep = {});

class BackgroundProtection {
 public:
  // The cameras (at run-time image size) must outlive this.
  BackgroundProtection(std::vector<const CameraModel*> cameras, double plane_height_m, ProtectionOptions options);

  // changes[n]: camera n's change mask of this frame (non-zero = changed), empty when the
  // camera is not active (then its image is all kFree, and it does not vote on persons).
  void Compute(const OccupancyMap& map, const std::vector<ImageView<const uint8_t>>& changes);

  // After Compute: people found by another detector (the views' explanation) are protected as
  // persons, a box of radius_m (plus the margin) around each; walked[k] (when given) marks
  // person k kWalkedPerson (WalkedPeople below).
  void AddPeople(const std::vector<Eigen::Vector2d>& positions_m, double radius_m, const std::vector<bool>& walked = {});
  // After AddPeople: people the detector missed (WalkedPeople::missed_m), protected as objects
  // where they were last seen: a standing person missed for a while is not free floor.
  void AddMissedPeople(const std::vector<Eigen::Vector2d>& positions_m, double radius_m);

  // Instead of Compute (+ AddPeople): the images from boxes another process computed (occmap
  // edge: the fuse's, for its own cameras), persons_m the persons' positions it found.
  void Draw(const std::vector<ProtectedBox>& boxes, const std::vector<Eigen::Vector2d>& persons_m);
  // Instead of Compute, without a map (an edge before the fuse's first protection, or while the
  // fuse is away): every changed pixel is kPerson (never absorbed, whatever stands there), the
  // rest kFree. changes[n] empty: camera n all kFree.
  void ProtectChanges(const std::vector<ImageView<const uint8_t>>& changes);

  const Image<uint8_t>& image(size_t camera) const { return images_[camera]; }
  // The boxes of the last Compute and AddPeople (or Draw), in the order they were drawn.
  const std::vector<ProtectedBox>& boxes() const { return boxes_; }
  int objects() const { return objects_; }
  int persons() const { return persons_; }
  // Where the persons stand (the groups' centroids, and the people added), metres.
  const std::vector<Eigen::Vector2d>& person_positions() const { return person_positions_; }

 private:
  // Marks the image of the upright box of `radius` around (cx, cy) with value in every camera
  // (and keeps the box in boxes_).
  void Protect(double cx, double cy, double radius, uint8_t value);
  void Clear();

  std::vector<const CameraModel*> cameras_;
  double plane_height_m_;
  ProtectionOptions options_;
  std::vector<Image<uint8_t>> images_;
  std::vector<ProtectedBox> boxes_;
  BlobFinder finder_;
  int objects_ = 0, persons_ = 0;
  std::vector<Eigen::Vector2d> person_positions_;
  std::vector<cv::Point2f> points_, hull_f_;  // a box's projected points, their outline
  std::vector<cv::Point> hull_;
  cv::Mat outline_;                            // the outline filled, at a camera's image size
};

// Which of the frame's people the run has seen walk. A learned background takes a person who
// stood through much of the learning window for the floor, with the floor as the pixel's
// alternative; the same pixels show the alternative again when that person leaves (their ghost
// must go) and when they come back to stand there (they must stay). Only the past tells the two
// apart: a ghost never moves, while a person who walked in is real wherever they stop. People
// are followed from frame to frame by nearest position within gate_m (greedy, closest pairs
// first); one who has been farther than walked_m from where they were first seen has walked,
// for as long as they are followed; one missed for forget_frames frames is forgotten.
// A person who walked in, stood, and whom the detector then misses (in a crowd, behind
// another) is remembered for hold_frames: missed_m() gives where they were last seen, to be
// protected as an object (absorbed after absorb_s steady), not as free floor, where a standing
// person would become background in relight_s. A ghost never walked, so it is not held.
//
//   WalkedPeople walked;
//   protection.AddPeople(positions, radius_m, walked.Update(positions));   // every frame
struct WalkedPeopleOptions {
  double gate_m = 0.6;      // farthest a person moves between two frames
  double walked_m = 1.0;    // from the first position: has walked
  int forget_frames = 20;   // missed in a row: forgotten
  double still_m = 0.3;     // moves less than this: stands
  int still_frames = 20;    // stood this long when last seen: held where they stood
  int hold_frames = 300;    // missed in a row: no longer remembered where last seen
};

class WalkedPeople {
 public:
  explicit WalkedPeople(WalkedPeopleOptions options = {}) : options_(options) {}
  // This frame's people (metres); the result has one flag per position: has walked.
  const std::vector<bool>& Update(const std::vector<Eigen::Vector2d>& positions_m);
  int followed() const;
  // After Update: where the walkers who stood, and are missed this frame, were last seen.
  const std::vector<Eigen::Vector2d>& missed_m() const { return missed_m_; }

 private:
  struct Person {
    Eigen::Vector2d first_m, last_m;
    bool walked = false;
    int missed = 0;
    Eigen::Vector2d still_at_m;  // where they have stood since still_for frames
    int still_for = 0;
  };
  WalkedPeopleOptions options_;
  std::vector<Person> people_;
  std::vector<bool> walked_;
  std::vector<Eigen::Vector2d> missed_m_;
  std::vector<std::pair<double, std::pair<int, int>>> pairs_;  // (distance, (person, position))
  std::vector<int> person_of_;                                 // per position: matched person or -1
  std::vector<uint8_t> matched_;                               // per person
};

// Which pixels teach each camera its shadow look (BackgroundModel::LearnShadows). A cast
// shadow lies on the floor: every camera that sees a shadowed cell sees it darkened (changed,
// or already called a shadow), while clothing that one camera takes for a shadow stands above
// the floor, whose cell the other cameras see unchanged beyond it. A teacher is a changed or
// shadow pixel whose floor cell (L1) has every pixel that views it (L2, the cameras that are
// active) darker within the shadows' range and by one ratio (within 0.15: a matte floor looks
// alike from every side, an object's sides are each lit their own way), away from where people
// stand and from what the fused map holds (feet, and the dark base of a robot or a box, meet
// that test too). Without cast shadows in a scene little teaches, and no look is learned.
//
//   ShadowTeachers teachers(lut);
//   teachers.Compute(classes, ratios, map, protection.person_positions(), 0.3);   // after the fusion
//   model.LearnShadows(frame, teachers.image(n));
class ShadowTeachers {
 public:
  explicit ShadowTeachers(const GroundLut& lut);  // lut must outlive this

  // classes[n]: camera n's BackgroundModel::pixel_classes(), empty when the camera is not active
  // (it abstains). Cells within radius_m of people_m, and within kObjectMarginM of the map's
  // occupied cells, never teach.
  void Compute(const std::vector<ImageView<const uint8_t>>& classes, const std::vector<ImageView<const uint8_t>>& ratios,
               const OccupancyMap& map, const std::vector<Eigen::Vector2d>& people_m, double radius_m);
  static constexpr double kObjectMarginM = 0.1;
  // Around a person's position, cells are their feet: the radius_m the pipeline passes.
  static constexpr double kPersonRadiusM = 0.35;

  const Image<uint8_t>& image(size_t camera) const { return images_[camera]; }
  int64_t teachers() const { return teachers_; }  // of the last Compute, over the cameras

 private:
  const GroundLut& lut_;
  std::vector<uint8_t> pixels_;     // per global pixel id: its class, kAbstain when inactive
  std::vector<uint8_t> ratios_;     // per global pixel id: its ratio (BackgroundModel::pixel_ratios)
  std::vector<uint8_t> cell_state_;  // per cell: kUnknown, kDark or kNotDark
  std::vector<uint32_t> touched_;    // cells whose state was set this frame
  std::vector<uint8_t> near_person_;  // per cell: within the radius of a person or near an object
  std::vector<uint32_t> near_person_cells_;
  std::vector<Image<uint8_t>> images_;
  int64_t teachers_ = 0;
};

// Cast shadows checked through the floor, before the fusion. A cast shadow lies on the floor:
// every camera that sees its floor cell sees it darkened. A person's side turned from the sun,
// which one camera takes for a shadow (darker by about the shadows' ratio, in their colour),
// stands above the floor: the ray of its pixel meets the floor behind the person, and the other
// cameras see that cell lit. A shadow pixel whose floor cell (L1) is seen unchanged by at least
// half of the other active cameras that view it (L2; a camera sees the cell unchanged when most
// of its pixels there are kBackground), and by two at least, is a change after all. Pixels whose
// ray leaves the grid, and cells only their own camera sees, keep their class. A soft shadow
// (BackgroundModel::kSoftShadow: no learned look vouches for it) needs the reverse: it stays a
// shadow only where another camera sees its cell shadowed too, and no fewer see it shadowed
// than lit; grey trousers on grey paving pass the soft test, and their ray meets the floor
// behind the person, lit or hidden by their legs. It fails where a static structure hides the floor from the other cameras and
// looks like the background there (the cell seems lit behind it), and for clothing in front of
// someone else's cast shadow.
//
//   ShadowCheck check(lut);
//   check.Apply(classes, changes);   // after each camera's DetectChanges, before dilation
class ShadowCheck {
 public:
  explicit ShadowCheck(const GroundLut& lut);  // lut must outlive this

  // classes[n]: camera n's BackgroundModel::pixel_classes(), empty when the camera is not active
  // or has no shadow test; changes[n]: its change mask (same size), set to 1 where a shadow
  // pixel's floor is seen lit. Returns the pixels turned into changes.
  int64_t Apply(const std::vector<ImageView<const uint8_t>>& classes, const std::vector<ImageView<uint8_t>>& changes);

 private:
  const GroundLut& lut_;
  std::vector<uint8_t> pixels_;       // per global pixel id: its class, kAbstain when inactive
  std::vector<uint8_t> camera_of_;    // per global pixel id
  std::vector<uint8_t> cell_state_;   // per cell: unknown, lit or not
  std::vector<uint32_t> touched_;     // cells whose state was set this frame
  std::vector<int> lit_, dark_;       // per camera, pixels of the cell being asked
  std::vector<int> shaded_;           // of the dark ones, those a shadow class
};

}  // namespace occmap
