// feature_frontend: NAVCAM_STEREO + ROVER_SITE + SITE_POSE_DR -> TIE_POINTS,
// FRONTEND_STATUS (Wan et al. 2.1-2.2: region prediction, Wallis, ASIFT,
// ZNCC + LSM stereo, distance-consistency check).
//   feature_frontend --config config/procs/feature_frontend.yaml [--lcm-url URL] [--site-cache DIR]
//     --site-cache DIR: overrides site_cache_dir (earlier sites' images kept there for revisits)
#include <opencv2/core.hpp>
#include <iostream>

#include "frontend_adapter.h"
#include "vloc/common/allocator.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  vloc::KeepLargeBlocksForReuse();
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"feature_frontend", {"site-cache"}, true,
                                   "--config config/procs/feature_frontend.yaml [--site-cache DIR] [--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::FeatureFrontendProcOptions>(*setup, [&](vloc::FeatureFrontendProcOptions& o) {
    if (setup->args.Has("site-cache")) o.site_cache_dir = setup->args.Get("site-cache");
  });
  if (!loaded) return 1;
  const vloc::FeatureFrontendProcOptions& options = *loaded;
  cv::setNumThreads(options.frontend.num_threads);
  vloc::FeatureFrontendAdapter adapter(options, *setup->transport);
  adapter.Subscribe();
  LOG(INFO) << "feature_frontend: waiting for " << options.stereo_channel << ", " << options.site_channel << " and "
            << options.dr_channel;
  const int rc = vloc::RunUntilSignal(*setup->transport, 100);
  LOG(INFO) << "feature_frontend: " << adapter.StatusLine();
  return rc;
}
