#include "suggest.h"

#include <algorithm>

#include "occmap/util/yaml_util.h"  // EditDistance

namespace occmap {

std::string NearestName(std::string_view typed, const std::vector<std::string>& names) {
  constexpr int kMaxEdits = 2;
  std::string best;
  int best_distance = kMaxEdits + 1;
  bool tie = false;
  for (const std::string& name : names) {
    int d = EditDistance(typed, name);
    if (typed.size() >= 2 && name.starts_with(typed)) d = std::min(d, 1);
    if (d < best_distance) {
      best = name;
      best_distance = d;
      tie = false;
    } else if (d == best_distance) {
      tie = true;
    }
  }
  return best_distance <= kMaxEdits && !tie ? best : std::string();
}

}  // namespace occmap
