// The UAV mosaicker's adapter in-process over MockTransport, fed the
// simulated flight (libs/sim UavWorld, config/procs/sim_uav.yaml) for two
// seconds: one UAV_STATE per frame whatever the frame, a preview at most
// once per preview_period of message time, a frame that is no image counted
// as lost (not a crash, not a silent skip).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "uav_mosaicker_adapter.h"
#include "vloc/common/options.h"
#include "vloc/image_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/sim/uav_world.h"
#include "vloc/uav_gps_t.hpp"

namespace vloc {
namespace {

// The simulated world, built once (its orthomap takes 1-3 s).
const UavWorld& SharedWorld() {
  static const UavWorld world(LoadOptionsFile<UavWorldOptions>("config/procs/sim_uav.yaml", "world"));
  return world;
}

struct Flight {
  const UavWorld& world = SharedWorld();
  MockTransport bus;
  UavMosaickerAdapter adapter;
  std::vector<uav_state_t> states;
  std::vector<int64_t> preview_utimes;
  int next_gps = 0;

  explicit Flight(UavMosaickerProcOptions options) : adapter(options, bus) {
    adapter.Subscribe();
    Subscribe<uav_state_t>(bus, "UAV_STATE", [this](const std::string&, const uav_state_t& m) { states.push_back(m); });
    Subscribe<image_t>(bus, "UAV_MOSAIC",
                       [this](const std::string&, const image_t& m) { preview_utimes.push_back(m.utime); });
  }
  static UavMosaickerProcOptions Options() {
    UavMosaickerProcOptions o = LoadOptionsFile<UavMosaickerProcOptions>("config/procs/uav_mosaicker.yaml");
    o.output = "";  // nothing written
    o.write_every_s = 0;
    return o;
  }
  // Frame i of the flight, with the GPS fixes up to its time first.
  void Frame(int i) {
    const double t = world.FrameTime(i);
    while (next_gps < world.gps().NumSamples() && world.gps().SampleTime(next_gps) <= t) {
      const UavGpsSample& s = world.gps().Sample(next_gps++);
      uav_gps_t g;
      g.utime = s.utime;
      g.fix = s.has_fix ? uav_gps_t::FIX_3D : uav_gps_t::FIX_NONE;
      g.latitude = s.latitude;
      g.longitude = s.longitude;
      g.altitude = s.altitude;
      g.height_above_ground = s.height_above_ground;
      g.horizontal_sigma = s.horizontal_sigma;
      g.vertical_sigma = s.vertical_sigma;
      Publish(bus, "UAV_GPS", g);
    }
    Publish(bus, "UAV_CAMERA", ImageToMessage(world.RenderFrame(t), ImageEncoding::kJpeg, world.FrameUtime(i), "uav"));
    bus.HandleAll();
  }
};

TEST(UavMosaickerAdapter, OneStatePerFrameAndPreviewsByMessageTime) {
  UavMosaickerProcOptions o = Flight::Options();
  o.preview_period = 0.5;
  Flight f(o);
  const int n = 60;  // 2 s at 30 frames/s
  for (int i = 0; i < n; ++i) f.Frame(i);
  ASSERT_EQ(static_cast<int>(f.states.size()), n);
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(f.states[i].frame_index, i);
    EXPECT_EQ(f.states[i].utime, f.world.FrameUtime(i));
  }
  EXPECT_EQ(int(f.states.back().status), int(mosaic::TrackStatus::kTracking)) << f.states.back().message;
  EXPECT_GT(f.states.back().height, 0);
  // 2 s of flight, a preview every 0.5 s of message time once the mosaic has begun: 3 or 4.
  ASSERT_GE(f.preview_utimes.size(), 3u);
  EXPECT_LE(f.preview_utimes.size(), 4u);
  for (size_t k = 1; k < f.preview_utimes.size(); ++k)
    EXPECT_GE(f.preview_utimes[k] - f.preview_utimes[k - 1], 500000);
  EXPECT_EQ(f.adapter.frames(), n);
}

TEST(UavMosaickerAdapter, FrameThatIsNoImageIsALostFrameAndTrackingResumes) {
  UavMosaickerProcOptions o = Flight::Options();
  o.preview_period = 0;  // none
  Flight f(o);
  for (int i = 0; i < 30; ++i) f.Frame(i);
  ASSERT_EQ(int(f.states.back().status), int(mosaic::TrackStatus::kTracking)) << f.states.back().message;
  image_t garbage = ImageToMessage(f.world.RenderFrame(f.world.FrameTime(30)), ImageEncoding::kJpeg,
                                   f.world.FrameUtime(30), "uav");
  for (size_t k = 0; k < garbage.data.size(); k += 7) garbage.data[k] = 0;  // no longer a JPEG
  Publish(f.bus, "UAV_CAMERA", garbage);
  f.bus.HandleAll();
  ASSERT_EQ(f.states.size(), 31u) << "a frame that is no image still gets its UAV_STATE";
  EXPECT_EQ(int(f.states.back().status), int(mosaic::TrackStatus::kLost));
  EXPECT_EQ(f.adapter.frames(), 31);
  for (int i = 31; i < 45; ++i) f.Frame(i);
  const auto status = mosaic::TrackStatus(f.states.back().status);
  EXPECT_TRUE(status == mosaic::TrackStatus::kTracking || status == mosaic::TrackStatus::kRecovered)
      << f.states.back().message;
  EXPECT_EQ(f.bus.Count("UAV_MOSAIC"), 0) << "previews are off";
}

}  // namespace
}  // namespace vloc
