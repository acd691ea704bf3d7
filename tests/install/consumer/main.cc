// count_people SITE [DATA_ROOT]: runs a site through occmap and prints the people per frame.
#include <cstdio>
#include <filesystem>

#include "occmap/pipeline/run.h"
#include "occmap/site/site.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: count_people SITE [DATA_ROOT]\n");
    return 2;
  }
  occmap::SiteLoadOptions load;
  if (argc > 2) load.data_root = argv[2];
  occmap::Result<occmap::Site> site = occmap::LoadSite(argv[1], load);
  if (!site.ok()) {
    std::fprintf(stderr, "%s\n", site.status().message().c_str());
    return occmap::ExitCodeFor(site.status());
  }
  occmap::RunOptions options;
  options.out_dir = std::filesystem::temp_directory_path() / "count_people";
  options.occupancy_video = options.mosaic_video = false;
  occmap::Context ctx(2);
  occmap::Result<occmap::RunSummary> run = occmap::RunSite(*site, options, ctx);
  if (!run.ok()) {
    std::fprintf(stderr, "%s\n", run.status().message().c_str());
    return occmap::ExitCodeFor(run.status());
  }
  std::printf("%lld frames, at most %lld people in a frame\n", static_cast<long long>(run->frames),
              static_cast<long long>(run->blobs_max_per_frame));
  return 0;
}
