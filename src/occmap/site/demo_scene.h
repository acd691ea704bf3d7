// A site built in code, for `occmap demo` and tests: the paper's UCSD lab, a 9 x 6.5 m room
// with four 640x480 cameras at 2.7 m on the walls looking across (no files needed).
//
//   Site lab = MakeDemoLabSite();
#pragma once

#include "occmap/site/site.h"

namespace occmap {

Site MakeDemoLabSite();

}  // namespace occmap
