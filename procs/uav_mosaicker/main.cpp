// uav_mosaicker: flight height, route and mosaic from a nadir UAV camera
// (seeds/004, Avola et al.).
//   uav_mosaicker --config config/procs/uav_mosaicker.yaml [--lcm-url URL] [--output FILE.png]
// In: UAV_CAMERA (image_t), UAV_GPS (uav_gps_t). Out: UAV_STATE (uav_state_t,
// every frame), UAV_MOSAIC (image_t JPEG preview, ~1 Hz). `kill -USR1 <pid>`
// writes the full mosaic (PNG + .pgw when tied to GPS) to `output`; it is
// also written at SIGINT/SIGTERM and, with write_every_s, periodically once
// tied to GPS (atomic replacement: a live map for map_localizer).
#include <glog/logging.h>
#include <signal.h>

#include <ctime>
#include <iostream>

#include "uav_mosaicker_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  // SIGUSR1 (write the mosaic) is blocked here and polled in the idle loop.
  sigset_t usr1;
  sigemptyset(&usr1);
  sigaddset(&usr1, SIGUSR1);
  pthread_sigmask(SIG_BLOCK, &usr1, nullptr);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"uav_mosaicker", {"output"}, true,
                                   "--config config/procs/uav_mosaicker.yaml [--lcm-url URL] [--output FILE.png]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::UavMosaickerProcOptions>(*setup, [&](vloc::UavMosaickerProcOptions& o) {
    if (setup->args.Has("output")) o.output = setup->args.Get("output");
  });
  if (!loaded) return 1;
  const vloc::UavMosaickerProcOptions& options = *loaded;
  vloc::UavMosaickerAdapter adapter(options, *setup->transport);
  adapter.Subscribe();
  const int code = vloc::RunUntilSignal(*setup->transport, 100, [&] {
    const timespec zero{0, 0};
    if (sigtimedwait(&usr1, nullptr, &zero) == SIGUSR1) adapter.WriteMosaic();
  });
  adapter.WriteMosaic();
  LOG(INFO) << "uav_mosaicker: " << adapter.frames() << " frames; " << adapter.mosaicker().summary().BriefReport()
            << "; " << adapter.SubscriptionLine();
  return code;
}
