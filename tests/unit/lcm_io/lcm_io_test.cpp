#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/traverse_t.hpp"
#include "vloc/uav_gps_t.hpp"
#include "vloc/uav_state_t.hpp"

namespace vloc {
namespace {

// ---- every message type survives encode/decode bit for bit --------------

pose_t SomePose(double k) {
  PoseWithCovariance p;
  p.utime = static_cast<int64_t>(k * 1000);
  p.pose = MakePose(k, -k, 0.5 * k, 0.1, -0.2, 0.3 * k);
  for (int i = 0; i < 6; ++i) p.covariance(i, i) = 0.01 * (i + 1) * k;
  p.covariance(0, 1) = p.covariance(1, 0) = 0.001;
  return PoseToMessage(p, "world", "body");
}

image_t SomeImage() {
  cv::Mat m(4, 5, CV_8UC1);
  cv::randu(m, 0, 255);
  return ImageToMessage(m, ImageEncoding::kGray8, 42, "cam");
}

template <class Msg>
void ExpectRoundTrip(const Msg& msg) {
  const int n = msg.getEncodedSize();
  std::vector<uint8_t> a(n), b(n);
  ASSERT_EQ(msg.encode(a.data(), 0, n), n);
  Msg decoded;
  ASSERT_EQ(decoded.decode(a.data(), 0, n), n) << Msg::getTypeName();
  ASSERT_EQ(decoded.getEncodedSize(), n);
  ASSERT_EQ(decoded.encode(b.data(), 0, n), n);
  EXPECT_EQ(a, b) << Msg::getTypeName();
}

TEST(MessageRoundTrip, EveryType) {
  ExpectRoundTrip(SomeImage());
  ExpectRoundTrip(SomePose(2.0));

  StereoPair pair;
  pair.utime = 7;
  pair.site_id = 3;
  pair.pair_index = 2;
  pair.num_pairs = 7;
  pair.mast_pan = 0.4;
  pair.mast_tilt = 0.5;
  pair.left = cv::Mat(8, 8, CV_8UC1, cv::Scalar(10));
  pair.right = cv::Mat(8, 8, CV_8UC1, cv::Scalar(20));
  ExpectRoundTrip(StereoPairToMessage(pair, ImageEncoding::kPng));

  ExpectRoundTrip(SiteEventToMessage({5, 3, SiteEventType::kImagingDone, 7}));
  ImuSample imu;
  imu.utime = 9;
  imu.angular_velocity = {0.01, -0.02, 0.03};
  imu.linear_acceleration = {0.1, 0.2, 1.62};
  ExpectRoundTrip(ImuToMessage(imu));
  ExpectRoundTrip(WheelOdometryToMessage({10, 12.5, 0.05}));
  ExpectRoundTrip(SitePoseToMessage(4, site_pose_t::SOURCE_VISUAL, PoseFromMessage(SomePose(1.0))));

  TiePointSet set;
  set.utime = 11;
  set.previous_site_id = 1;
  set.current_site_id = 2;
  set.previous_site_pose = PoseFromMessage(SomePose(1.0));
  set.current_site_pose_dr = PoseFromMessage(SomePose(3.0));
  set.previous_pointing = {{0.1, 0.5}, {0.2, 0.5}};
  set.current_pointing = {{-0.1, 0.5}};
  TiePoint tp;
  tp.id = 5;
  tp.p_previous = {12, 1, -1.5};
  tp.p_current = {3, 1, -1.4};
  tp.weight = 40;
  tp.observations.push_back({SiteRole::kPrevious, 1, CameraSide::kRight, {100.25, 200.5}, 0.1});
  tp.observations.push_back({SiteRole::kCurrent, 0, CameraSide::kLeft, {300.75, 400.125}, 0.2});
  set.points = {tp, tp};
  const tie_points_t tmsg = TiePointsToMessage(set);
  ExpectRoundTrip(tmsg);
  ExpectRoundTrip(tmsg.points[0]);
  ExpectRoundTrip(tmsg.points[0].observations[0]);
  const TiePointSet back = TiePointsFromMessage(tmsg);
  ASSERT_EQ(back.points.size(), 2u);
  EXPECT_EQ(back.points[1].observations[1].uv, Eigen::Vector2d(300.75, 400.125));
  EXPECT_EQ(back.points[1].observations[0].camera, CameraSide::kRight);
  EXPECT_EQ(back.current_pointing.size(), 1u);
  EXPECT_LT((back.current_site_pose_dr.pose.matrix() - set.current_site_pose_dr.pose.matrix()).norm(), 1e-12);

  frontend_status_t fs{};
  fs.status = frontend_status_t::STATUS_LOW_TEXTURE;
  fs.message = "too little texture";
  fs.num_stages = 2;
  fs.stage_names = {"asift", "stereo"};
  fs.stage_counts = {300, 250};
  fs.stage_seconds = {1.5, 0.5};
  ExpectRoundTrip(fs);

  localization_t loc{};
  loc.site_id = 3;
  loc.pose = SomePose(2);
  loc.relative_pose = SomePose(0.5);
  loc.message = "ok";
  loc.final_rms_px = 0.3;
  ExpectRoundTrip(loc);

  traverse_t tr{};
  tr.num_sites = 2;
  tr.site_ids = {0, 1};
  tr.poses = {SomePose(0), SomePose(1)};
  ExpectRoundTrip(tr);

  uav_gps_t gps{};
  gps.fix = uav_gps_t::FIX_3D;
  gps.latitude = 41.9;
  gps.longitude = 12.5;
  gps.height_above_ground = 30.5;
  ExpectRoundTrip(gps);

  uav_state_t st{};
  st.status = uav_state_t::STATUS_TRACKING;
  st.height = 42;
  st.route_px[0] = 1;
  st.message = "tracking";
  ExpectRoundTrip(st);

  proc_status_t ps{};
  ps.name = "feature_frontend";
  ps.group = "rover_sim";
  ps.state = proc_status_t::STATE_RUNNING;
  ps.rss_bytes = 123456789;
  procman_status_t pm{};
  pm.host = "rover";
  pm.num_procs = 1;
  pm.procs = {ps};
  ExpectRoundTrip(ps);
  ExpectRoundTrip(pm);

  procman_order_t order{};
  order.target = "rover_sim";
  order.target_kind = procman_order_t::TARGET_GROUP;
  order.action = procman_order_t::ACTION_RESTART;
  ExpectRoundTrip(order);
}

// ---- images through every encoding ---------------------------------------

cv::Mat TestImage(int type) {
  cv::Mat m(48, 64, type);
  cv::RNG rng(3);
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(m, m, cv::Size(9, 9), 3.0);  // smooth, photo-like content
  return m;
}

double MaxAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  double mx = 0;
  cv::minMaxLoc(d.reshape(1), nullptr, &mx);
  return mx;
}

TEST(ImageConversion, RawAndPngArePixelExact) {
  for (int type : {CV_8UC1, CV_8UC3}) {
    const cv::Mat img = TestImage(type);
    for (auto enc : {type == CV_8UC1 ? ImageEncoding::kGray8 : ImageEncoding::kRgb8, ImageEncoding::kPng}) {
      const image_t msg = ImageToMessage(img, enc, 5, "cam");
      EXPECT_EQ(msg.width, 64);
      EXPECT_EQ(msg.height, 48);
      const cv::Mat back = ImageFromMessage(msg);
      ASSERT_EQ(back.type(), img.type());
      EXPECT_EQ(MaxAbsDiff(back, img), 0.0);
    }
  }
}

TEST(ImageConversion, Rgb8StoresRgbOrder) {
  cv::Mat bgr(1, 1, CV_8UC3, cv::Scalar(1, 2, 3));  // B=1 G=2 R=3
  const image_t msg = ImageToMessage(bgr, ImageEncoding::kRgb8, 0, "cam");
  ASSERT_EQ(msg.data.size(), 3u);
  EXPECT_EQ(msg.data[0], 3);
  EXPECT_EQ(msg.data[2], 1);
}

TEST(ImageConversion, JpegIsClose) {
  for (int type : {CV_8UC1, CV_8UC3}) {
    const cv::Mat img = TestImage(type);
    const cv::Mat back = ImageFromMessage(ImageToMessage(img, ImageEncoding::kJpeg, 5, "cam", 95));
    ASSERT_EQ(back.type(), img.type());
    EXPECT_LT(cv::norm(back, img, cv::NORM_L1) / img.total() / img.channels(), 3.0);
  }
}

TEST(ImageConversion, BadMessagesNameTheProblem) {
  image_t msg = ImageToMessage(TestImage(CV_8UC1), ImageEncoding::kGray8, 0, "navcam_left");
  msg.width = 10;
  try {
    ImageFromMessage(msg);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("image 'navcam_left'"), std::string::npos) << e.what();
  }
  image_t png = ImageToMessage(TestImage(CV_8UC1), ImageEncoding::kPng, 0, "cam");
  png.data.resize(20);
  png.size = 20;
  EXPECT_THROW(ImageFromMessage(png), std::invalid_argument);
  EXPECT_THROW(ImageToMessage(TestImage(CV_8UC3), ImageEncoding::kGray8, 0, "cam"), std::invalid_argument);
  EXPECT_THROW(ParseImageEncoding("tiff"), std::invalid_argument);
}

TEST(PoseConversion, RoundTripAndValidation) {
  PoseWithCovariance p;
  p.utime = 99;
  p.pose = MakePose(1, 2, 3, 0.1, 0.2, 0.3);
  p.covariance = Matrix6d::Identity() * 0.04;
  p.covariance(2, 4) = p.covariance(4, 2) = 0.001;
  const PoseWithCovariance back = PoseFromMessage(PoseToMessage(p, "world", "body"));
  EXPECT_EQ(back.utime, 99);
  EXPECT_LT((back.pose.matrix() - p.pose.matrix()).norm(), 1e-12);
  EXPECT_EQ(back.covariance, p.covariance);
  pose_t bad = PoseToMessage(p, "world", "body");
  bad.orientation[0] = 2.0;
  EXPECT_THROW(PoseFromMessage(bad), std::invalid_argument);
  bad.orientation[0] = NAN;
  EXPECT_THROW(PoseFromMessage(bad), std::invalid_argument);
}

TEST(RoverConversion, RejectsInconsistentMessages) {
  StereoPair pair;
  pair.num_pairs = 7;
  pair.pair_index = 7;  // out of range
  pair.left = cv::Mat(8, 8, CV_8UC1, cv::Scalar(1));
  pair.right = pair.left;
  EXPECT_THROW(StereoPairFromMessage(StereoPairToMessage(pair, ImageEncoding::kGray8)), std::invalid_argument);
  site_event_t ev = SiteEventToMessage({1, 1, SiteEventType::kArrived, 7});
  ev.event = 9;
  EXPECT_THROW(SiteEventFromMessage(ev), std::invalid_argument);
}

// ---- typed subscriptions are exception safe --------------------------------

TEST(TypedSubscribe, HandlerThatThrowsDoesNotStopLaterMessages) {
  MockTransport t;
  int handled = 0;
  auto stats = Subscribe<wheel_odometry_t>(t, "WHEEL_ODOM", [&](const std::string&, const wheel_odometry_t& m) {
    ++handled;
    if (m.distance < 0) throw std::runtime_error("negative distance");
  });
  Publish(t, "WHEEL_ODOM", WheelOdometryToMessage({1, -1.0, 0}));
  Publish(t, "WHEEL_ODOM", WheelOdometryToMessage({2, 2.0, 0}));
  EXPECT_EQ(t.HandleAll(), 2);
  EXPECT_EQ(handled, 2);
  EXPECT_EQ(stats->handler_failures, 1);
  EXPECT_EQ(stats->received, 2);
}

TEST(TypedSubscribe, WrongTypeIsReportedAndSkipped) {
  MockTransport t;
  int handled = 0;
  auto stats = Subscribe<imu_t>(t, "IMU", [&](const std::string&, const imu_t&) { ++handled; });
  Publish(t, "IMU", WheelOdometryToMessage({1, 1.0, 0}));  // wrong type on the channel
  const uint8_t garbage[3] = {1, 2, 3};
  t.Publish("IMU", garbage, sizeof(garbage));
  Publish(t, "IMU", ImuToMessage({}));
  t.HandleAll();
  EXPECT_EQ(handled, 1);
  EXPECT_EQ(stats->decode_failures, 2);
}

TEST(MockTransport, KeepsLastMessagePerChannelAndMatchesRegex) {
  MockTransport t;
  int n = 0;
  t.Subscribe("SITE_POSE_.*", [&](const std::string&, const uint8_t*, size_t) { ++n; });
  Publish(t, "SITE_POSE_DR", SitePoseToMessage(1, site_pose_t::SOURCE_DEAD_RECKONING, {}));
  Publish(t, "SITE_POSE_GT", SitePoseToMessage(1, site_pose_t::SOURCE_GROUND_TRUTH, {}));
  Publish(t, "OTHER", ImuToMessage({}));
  t.HandleAll();
  EXPECT_EQ(n, 2);
  EXPECT_EQ(t.Count("SITE_POSE_DR"), 1);
  site_pose_t last;
  ASSERT_NE(t.Last("SITE_POSE_GT"), nullptr);
  ASSERT_TRUE(Decode(t.Last("SITE_POSE_GT")->data(), t.Last("SITE_POSE_GT")->size(), &last));
  EXPECT_EQ(int(last.source), int(site_pose_t::SOURCE_GROUND_TRUTH));
}

TEST(LcmUrl, ConfigThenEnvironmentThenDefault) {
  unsetenv("LCM_DEFAULT_URL");
  EXPECT_EQ(ResolveLcmUrl(""), kDefaultLcmUrl);
  EXPECT_NE(std::string(kDefaultLcmUrl).find("recv_buf_size="), std::string::npos);
  setenv("LCM_DEFAULT_URL", "udpm://239.255.76.67:7711?ttl=0", 1);
  EXPECT_EQ(ResolveLcmUrl(""), "udpm://239.255.76.67:7711?ttl=0");
  EXPECT_EQ(ResolveLcmUrl("memq://"), "memq://");
  unsetenv("LCM_DEFAULT_URL");
}

TEST(LcmTransport, MemqDeliversTypedMessages) {
  std::string error;
  auto t = MakeLcmTransport("memq://", &error);
  ASSERT_TRUE(t) << error;
  double got = 0;
  auto stats = Subscribe<wheel_odometry_t>(*t, "WHEEL_ODOM", [&](const std::string&, const wheel_odometry_t& m) {
    got = m.distance;
  });
  ASSERT_TRUE(Publish(*t, "WHEEL_ODOM", WheelOdometryToMessage({1, 3.25, 0})));
  EXPECT_GT(t->Handle(1000), 0);
  EXPECT_EQ(got, 3.25);
}

TEST(LcmTransport, BadUrlIsOneClearLine) {
  std::string error;
  auto t = MakeLcmTransport("nosuchprovider://", &error);
  EXPECT_FALSE(t);
  EXPECT_NE(error.find("LCM could not start on 'nosuchprovider://'"), std::string::npos) << error;
  EXPECT_EQ(error.find('\n'), std::string::npos);
}

}  // namespace
}  // namespace vloc
