// dead_reckoning: wheel odometry + IMU attitude -> DR_POSE and SITE_POSE_DR.
//   dead_reckoning --config config/procs/dead_reckoning.yaml [--lcm-url URL]
#include <iostream>

#include "dead_reckoning_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"dead_reckoning", {}, true, "--config config/procs/dead_reckoning.yaml [--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::DeadReckoningProcOptions>(*setup);
  if (!loaded) return 1;
  const vloc::DeadReckoningProcOptions& options = *loaded;
  vloc::DeadReckoningAdapter adapter(*setup->transport, options);
  const int rc = vloc::RunUntilSignal(*setup->transport, 200);
  LOG(INFO) << "dead_reckoning: " << adapter.StatusLine();
  return rc;
}
