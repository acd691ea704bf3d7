// Test scenes for the people's fusions: the small room's cameras at 320 x 240, their column
// tables, and change masks painted with perfect silhouettes (the model's image, wider).
#pragma once

#include <vector>

#include "occmap/fusion/column_fusion.h"
#include "occmap/lut/column_lut.h"
#include "occmap/lut/test_scene.h"
#include "occmap/util/image.h"

namespace occmap::testing {

struct PeopleRoom {
  SmallRoom room{320, 240};
  ColumnLut columns;
  std::vector<Image<uint8_t>> changes;  // per camera, 1 changed
  std::vector<ChangeRowSums> sums;
  explicit PeopleRoom(std::span<const Occluder> occluders = {}) {
    std::vector<LutCameraInput> in;
    for (const auto& c : room.cameras) in.push_back({&c, {}});
    Context ctx(1);
    columns = BuildColumnLut(in, room.grid, 0.0, ColumnLutOptions{}, occluders, ctx).value();
    for (size_t c = 0; c < room.cameras.size(); ++c) changes.emplace_back(320, 240);
    Clear();
  }
  void Clear() {
    for (auto& im : changes)
      for (int y = 0; y < im.height(); ++y) std::fill_n(im.row(y), im.width(), uint8_t{0});
  }
  // A person of radius_m standing at (x, y): their model's image painted in every camera (but
  // those whose view `hidden_by`, a table of the same cameras with statics, says a static hides).
  void Paint(double x_m, double y_m, double radius_m = 0.2, const ColumnLut* hidden_by = nullptr) {
    const int64_t k = columns.candidates().CellAt(x_m, y_m);
    for (int c = 0; c < columns.num_cameras(); ++c) {
      const ColumnView& v = columns.view(c, k);
      if (!v.projected || (hidden_by != nullptr && hidden_by->view(c, k).blocked)) continue;
      const ColumnSpans s = MakeColumnSpans(v, radius_m, 0.0, 1.0, columns.image_size(c));
      for (int y = s.first_row; y <= s.last_row; ++y) {
        int x0, x1;
        if (!s.Span(y, x0, x1)) continue;
        for (int x = x0; x <= x1; ++x) changes[c](x, y) = 1;
      }
    }
  }
  std::vector<ImageView<const uint8_t>> Views() const {
    std::vector<ImageView<const uint8_t>> v;
    for (const auto& im : changes) v.push_back(im.view());
    return v;
  }
  const std::vector<ChangeRowSums>& Sums() {
    sums.resize(changes.size());
    for (size_t c = 0; c < changes.size(); ++c) sums[c].Build(changes[c].view());
    return sums;
  }
};

}  // namespace occmap::testing
