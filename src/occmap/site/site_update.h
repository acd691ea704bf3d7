// Editing a site file in place: one camera's `calibration:` entry replaced (what `occmap
// calibrate --update-site` and, later, the web UI's setup do). Only the entry's text changes
// (comments and layout elsewhere are kept); the new text must load with LoadSite's own parser
// before anything is written; the previous file is kept as SITE.bak, and the new one is written
// atomically.
//
//   OCCMAP_ASSIGN_OR_RETURN(SiteUpdate u, UpdateSiteCameraCalibration(
//       "site.yaml", "C1", "{format: opencv, intrinsic: calib/intr_C1.xml, ...}", {}));
//   // u.backup == "site.yaml.bak"
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include "occmap/site/site.h"
#include "occmap/util/status.h"

namespace occmap {

// The folder the site file's relative paths resolve against: options.data_root, else the
// file's data_root (relative to the file), else the file's folder.
Result<std::filesystem::path> SiteDataRoot(const std::filesystem::path& site_path, const SiteLoadOptions& options = {});

// `path` as the site file should name it: relative to the file's own data root when it lies
// below it, else absolute.
Result<std::string> SitePathFor(const std::filesystem::path& site_path, const std::filesystem::path& path);

// The site text with camera `camera_id`'s calibration replaced by `calibration_flow_yaml` (a
// YAML flow map); checked by ParseSite with `options`. Error when the id is not in the site.
Result<std::string> ReplaceCameraCalibration(std::string_view site_text, const std::filesystem::path& site_path,
                                             std::string_view camera_id, std::string_view calibration_flow_yaml,
                                             const SiteLoadOptions& options = {});

// Generalised edits of the site text, each keeping the rest of the file (comments, layout):
// `key`'s value in camera `camera_id`'s entry, or in the `tracking:` section (created when
// missing), set to `flow_yaml` (a YAML flow value: a map, a list or a scalar), added when the
// key is missing; an empty `flow_yaml` removes the key. Not validated: validate the whole edit
// with WriteSiteText.
Result<std::string> SetCameraValue(std::string_view site_text, const std::filesystem::path& site_path,
                                   std::string_view camera_id, std::string_view key, std::string_view flow_yaml);
Result<std::string> SetTrackingValue(std::string_view site_text, const std::filesystem::path& site_path,
                                     std::string_view key, std::string_view flow_yaml);

struct SiteUpdate {
  std::filesystem::path backup;  // the previous file's copy
  std::string text;              // the new file's text
};

// Reads the site, replaces the entry, validates, writes SITE.bak then SITE (atomically each).
Result<SiteUpdate> UpdateSiteCameraCalibration(const std::filesystem::path& site_path, std::string_view camera_id,
                                               std::string_view calibration_flow_yaml,
                                               const SiteLoadOptions& options = {});

// Validates `new_text` with ParseSite (nothing written on error; the message is the loader's),
// then writes SITE.bak (the `old_text`) and SITE atomically.
Result<SiteUpdate> WriteSiteText(const std::filesystem::path& site_path, std::string_view old_text,
                                 std::string new_text, const SiteLoadOptions& options = {});

}  // namespace occmap
