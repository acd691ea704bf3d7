#include "suggest.h"

#include <algorithm>
#include <numeric>

namespace occmap {

int EditDistance(std::string_view a, std::string_view b) {
  std::vector<int> row(b.size() + 1);
  std::iota(row.begin(), row.end(), 0);
  for (size_t i = 1; i <= a.size(); ++i) {
    int diagonal = row[0];
    row[0] = static_cast<int>(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

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
