// Where in the site file a camera's field is: "site.yaml:13: cameras[0].background", for the
// errors found after the site was loaded (a source with no frames, a background of the wrong
// size, --start past the end), so that they too name the file and line.
//
//   return status.WithContext(SiteCameraLocation(site, n, "background"));
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "occmap/site/site.h"

namespace occmap {

// "<file>:<line>: cameras[<index>].<field>" (the camera's line when the field is absent);
// "cameras[<index>].<field>" for a site built in code or a file that cannot be read again.
// Reads the file again: for error paths only.
std::string SiteCameraLocation(const Site& site, size_t camera_index, std::string_view field);

}  // namespace occmap
