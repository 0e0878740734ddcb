// The conversions moved from the processes into libs/lcm_io: each message
// built from a library struct carries its fields (and survives an
// encode/decode through typed.h), each struct read from a message is the
// message's content.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_ba.h"
#include "vloc/lcm_io/convert_frontend.h"
#include "vloc/lcm_io/convert_launch.h"
#include "vloc/lcm_io/convert_traverse.h"
#include "vloc/lcm_io/convert_tunnel.h"
#include "vloc/lcm_io/convert_uav.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {
namespace {

// msg through Encode and Decode (the schema check included).
template <class Msg>
Msg RoundTrip(const Msg& msg) {
  std::vector<uint8_t> bytes;
  std::string error;
  EXPECT_TRUE(Encode(msg, &bytes, &error)) << error;
  Msg out;
  EXPECT_TRUE(Decode(bytes.data(), bytes.size(), &out, &error)) << error;
  return out;
}

TEST(ConvertFrontend, StatusCarriesStatusMessageAndStages) {
  FrontendSummary s;
  s.status = FrontendStatus::kTooFewPoints;
  s.message = "7 tie points, 12 needed";
  s.stages = {{"regions", 4, 0.01}, {"asift", 321, 0.5}, {"distance_check", 7, 0.02}};
  s.total_seconds = 0.6;
  const frontend_status_t m = RoundTrip(FrontendStatusToMessage(s, 1234, 3, 4));
  EXPECT_EQ(m.utime, 1234);
  EXPECT_EQ(m.previous_site_id, 3);
  EXPECT_EQ(m.current_site_id, 4);
  EXPECT_EQ(int(m.status), int(frontend_status_t::STATUS_TOO_FEW_POINTS));
  EXPECT_EQ(m.message, s.message);
  ASSERT_EQ(m.num_stages, 3);
  EXPECT_EQ(m.stage_names[1], "asift");
  EXPECT_EQ(m.stage_counts[1], 321);
  EXPECT_DOUBLE_EQ(m.stage_seconds[2], 0.02);
  EXPECT_DOUBLE_EQ(m.total_seconds, 0.6);
  // Every status has its constant.
  const std::pair<FrontendStatus, int8_t> all[] = {
      {FrontendStatus::kOk, frontend_status_t::STATUS_OK},
      {FrontendStatus::kNoOverlap, frontend_status_t::STATUS_NO_OVERLAP},
      {FrontendStatus::kLowTexture, frontend_status_t::STATUS_LOW_TEXTURE},
      {FrontendStatus::kTooFewPoints, frontend_status_t::STATUS_TOO_FEW_POINTS},
      {FrontendStatus::kMissingInput, frontend_status_t::STATUS_MISSING_INPUT},
      {FrontendStatus::kError, frontend_status_t::STATUS_ERROR}};
  for (const auto& [status, constant] : all) {
    s.status = status;
    EXPECT_EQ(FrontendStatusToMessage(s, 0, 0, 1).status, constant);
  }
}

manual_tie_points_t ManualTies(int n) {
  manual_tie_points_t m;
  m.num_points = n;
  for (int i = 0; i < n; ++i) {
    m.previous_pair.push_back(i);
    m.previous_u.push_back(10.5 + i);
    m.previous_v.push_back(20.25 + i);
    m.current_pair.push_back(i + 1);
    m.current_u.push_back(30 + i);
    m.current_v.push_back(40 + i);
  }
  return m;
}

TEST(ConvertFrontend, ManualTiesAreTheClicks) {
  const std::vector<ManualTie> ties = ManualTiesFromMessage(RoundTrip(ManualTies(2)));
  ASSERT_EQ(ties.size(), 2u);
  EXPECT_EQ(ties[1].previous_pair, 1);
  EXPECT_DOUBLE_EQ(ties[1].previous_px.x(), 11.5);
  EXPECT_DOUBLE_EQ(ties[1].previous_px.y(), 21.25);
  EXPECT_EQ(ties[1].current_pair, 2);
  EXPECT_DOUBLE_EQ(ties[1].current_px.x(), 31);
  EXPECT_DOUBLE_EQ(ties[1].current_px.y(), 41);
}

TEST(ConvertFrontend, ManualTieThatIsNotAPixelIsRefused) {
  manual_tie_points_t m = ManualTies(3);
  m.current_v[2] = -1;
  EXPECT_THROW(ManualTiesFromMessage(m), std::invalid_argument);
  m = ManualTies(3);
  m.previous_u[0] = std::numeric_limits<double>::quiet_NaN();
  try {
    ManualTiesFromMessage(m);
    FAIL() << "a NaN click was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("manual tie point 0"), std::string::npos) << e.what();
  }
}

TEST(ConvertBa, LocalizationCarriesPosesCountsAndAFiniteConditionNumber) {
  CrossSiteBaSummary s;
  s.status = CrossSiteBaStatus::kIllConditioned;
  s.message = "condition number too large";
  s.previous_site_id = 6;
  s.current_site_id = 7;
  s.world_from_current.pose = MakePose(60, 1, 0.5, 0, 0, 0.3);
  s.world_from_current.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 0.04;
  s.previous_from_current.pose = MakePose(10, 0.5, 0, 0, 0, 0.1);
  s.previous_from_current.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 0.01;
  s.num_tie_points_used = 40;
  s.num_tie_points_rejected = 3;
  s.num_observations = 160;
  s.initial_rms_px = 2.5;
  s.final_rms_px = 0.3;
  s.iterations = 9;
  s.solve_seconds = 0.2;
  s.condition_number = std::numeric_limits<double>::infinity();
  const localization_t m = RoundTrip(LocalizationToMessage(s, 777));
  EXPECT_EQ(m.utime, 777);
  EXPECT_EQ(m.site_id, 7);
  EXPECT_EQ(m.reference_site_id, 6);
  EXPECT_EQ(int(m.status), int(localization_t::STATUS_ILL_CONDITIONED));
  EXPECT_EQ(m.message, s.message);
  EXPECT_EQ(m.relative_pose.frame_id, "site_6");
  EXPECT_EQ(m.relative_pose.child_frame_id, "site_7");
  EXPECT_TRUE(PoseFromMessage(m.pose).pose.isApprox(s.world_from_current.pose, 1e-12));
  EXPECT_TRUE(PoseFromMessage(m.relative_pose).pose.isApprox(s.previous_from_current.pose, 1e-12));
  EXPECT_NEAR(PoseFromMessage(m.pose).covariance(0, 0), 0.04, 1e-12);
  EXPECT_EQ(m.num_tie_points_used, 40);
  EXPECT_EQ(m.num_tie_points_rejected, 3);
  EXPECT_EQ(m.num_observations, 160);
  EXPECT_DOUBLE_EQ(m.initial_rms_px, 2.5);
  EXPECT_DOUBLE_EQ(m.final_rms_px, 0.3);
  EXPECT_EQ(m.iterations, 9);
  EXPECT_DOUBLE_EQ(m.condition_number, 1e300) << "infinity is sent as 1e300";
  s.condition_number = 42;
  EXPECT_DOUBLE_EQ(LocalizationToMessage(s, 0).condition_number, 42);
}

TEST(ConvertTraverse, TraverseCarriesEverySitePoseAndTheSummary) {
  posegraph::TraverseGraph graph;
  for (int site = 0; site < 3; ++site) {
    PoseWithCovariance dr;
    dr.utime = 1000000LL * (site + 1);
    dr.pose = MakePose(10.0 * site, 0, 0, 0, 0, 0);
    dr.covariance = Eigen::Matrix<double, 6, 6>::Identity() * (0.01 * (site + 1));
    ASSERT_TRUE(graph.AddDeadReckoning(site, dr).accepted);
  }
  const posegraph::PoseGraphSummary summary = graph.Optimize();
  const traverse_t m = RoundTrip(TraverseToMessage(graph, summary));
  EXPECT_EQ(m.utime, graph.newest_utime());
  ASSERT_EQ(m.num_sites, 3);
  const auto sites = graph.Sites();
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(m.site_ids[i], sites[i].site_id);
    EXPECT_TRUE(PoseFromMessage(m.poses[i]).pose.isApprox(sites[i].world_from_body.pose, 1e-9));
    EXPECT_EQ(m.poses[i].frame_id, "world");
  }
  EXPECT_EQ(m.num_edges, summary.num_edges);
  EXPECT_EQ(m.num_visual_edges, summary.num_visual_edges);
  EXPECT_EQ(m.num_loop_edges, summary.num_loop_edges);
  EXPECT_DOUBLE_EQ(m.final_chi2, summary.final_chi2);
  EXPECT_EQ(m.iterations, summary.iterations);
}

TEST(ConvertUav, StateCarriesTheFrame) {
  mosaic::FrameState s;
  s.utime = 5000;
  s.frame_index = 12;
  s.status = mosaic::TrackStatus::kLost;
  s.message = "too few inliers";
  s.height = 51.5;
  s.height_raw = 52;
  s.scale = 1.01;
  s.route_px = {100.5, 200.25};
  s.route_local = {-3, 4};
  s.latitude = 46.5;
  s.longitude = 6.6;
  s.gps_aided = true;
  s.num_matches = 300;
  s.num_inliers = 250;
  s.num_foreground = 7;
  s.tracking_seconds = 0.02;
  const uav_state_t m = RoundTrip(StateToMessage(s));
  EXPECT_EQ(m.utime, 5000);
  EXPECT_EQ(m.frame_index, 12);
  EXPECT_EQ(int(m.status), int(s.status));
  EXPECT_EQ(m.message, s.message);
  EXPECT_DOUBLE_EQ(m.height, 51.5);
  EXPECT_DOUBLE_EQ(m.height_raw, 52);
  EXPECT_DOUBLE_EQ(m.scale, 1.01);
  EXPECT_DOUBLE_EQ(m.route_px[0], 100.5);
  EXPECT_DOUBLE_EQ(m.route_px[1], 200.25);
  EXPECT_DOUBLE_EQ(m.route_local[0], -3);
  EXPECT_DOUBLE_EQ(m.route_local[1], 4);
  EXPECT_DOUBLE_EQ(m.latitude, 46.5);
  EXPECT_DOUBLE_EQ(m.longitude, 6.6);
  EXPECT_EQ(m.gps_aided, 1);
  EXPECT_EQ(m.num_matches, 300);
  EXPECT_EQ(m.num_inliers, 250);
  EXPECT_EQ(m.num_foreground, 7);
  // Before GPS, latitude and longitude are NaN, which the schema allows.
  s.latitude = s.longitude = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isnan(RoundTrip(StateToMessage(s)).latitude));
}

TEST(ConvertUav, GpsFixIsValidOnlyWithAFixAndFiniteCoordinates) {
  uav_gps_t m;
  m.utime = 42;
  m.fix = uav_gps_t::FIX_3D;
  m.latitude = 46.5;
  m.longitude = 6.6;
  m.altitude = 500;
  m.height_above_ground = 80;
  m.horizontal_sigma = 1.5;
  m.vertical_sigma = 2.5;
  mosaic::GpsFix f = GpsFromMessage(RoundTrip(m));
  EXPECT_TRUE(f.valid);
  EXPECT_EQ(f.utime, 42);
  EXPECT_DOUBLE_EQ(f.latitude, 46.5);
  EXPECT_DOUBLE_EQ(f.longitude, 6.6);
  EXPECT_DOUBLE_EQ(f.altitude, 500);
  EXPECT_DOUBLE_EQ(f.height_above_ground, 80);
  EXPECT_DOUBLE_EQ(f.horizontal_sigma, 1.5);
  EXPECT_DOUBLE_EQ(f.vertical_sigma, 2.5);
  uav_gps_t none = m;
  none.fix = uav_gps_t::FIX_NONE;
  EXPECT_FALSE(GpsFromMessage(none).valid);
  uav_gps_t nan = m;
  nan.longitude = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(GpsFromMessage(nan).valid);
}

TEST(ConvertTunnel, StatusCarriesTheReportAndEveryChannel) {
  tunnel::TunnelOptions options;
  options.name = "vehicle";
  options.bandwidth_cap_mbps = 8;
  tunnel::TunnelReport r;
  r.peer_name = "ground";
  r.connected = true;
  r.connects = 2;
  r.seconds_since_peer = 0.5;
  r.tx_bytes_per_s = 1000;
  r.sent_messages = 17;
  r.dropped_queue_full = 3;
  r.latency_samples = 5;
  r.latency_median_ms = 12.5;
  tunnel::ChannelReport c;
  c.channel = "NAVCAM_STEREO";
  c.priority = 2;
  c.queued_messages = 4;
  c.sent = 9;
  c.dropped = 1;
  r.channels = {c, c};
  r.channels[1].channel = "TRAVERSE";
  const tunnel_status_t m = RoundTrip(TunnelStatusToMessage(r, options, "tcp://*:7720", 99));
  EXPECT_EQ(m.utime, 99);
  EXPECT_EQ(m.name, "vehicle");
  EXPECT_EQ(m.peer_name, "ground");
  EXPECT_EQ(m.endpoint, "tcp://*:7720");
  EXPECT_TRUE(m.connected);
  EXPECT_EQ(m.connects, 2);
  EXPECT_DOUBLE_EQ(m.seconds_since_peer, 0.5);
  EXPECT_DOUBLE_EQ(m.bandwidth_cap_bytes_per_s, 1e6) << "8 Mbit/s";
  EXPECT_EQ(m.sent_messages, 17);
  EXPECT_EQ(m.dropped_queue_full, 3);
  EXPECT_DOUBLE_EQ(m.latency_median_ms, 12.5);
  ASSERT_EQ(m.num_channels, 2);
  EXPECT_EQ(m.channels[0].channel, "NAVCAM_STEREO");
  EXPECT_EQ(m.channels[0].priority, 2);
  EXPECT_EQ(m.channels[0].queued_messages, 4);
  EXPECT_EQ(m.channels[0].sent, 9);
  EXPECT_EQ(m.channels[0].dropped, 1);
  EXPECT_EQ(m.channels[1].channel, "TRAVERSE");
}

TEST(ConvertLaunch, StatusCarriesEveryProcessAndReadsBackAsAPeerReport) {
  ProcessStatus running;
  running.name = "crosssite_ba";
  running.group = "rover";
  running.pid = 321;
  running.state = ProcState::kRunning;
  running.restarts = 2;
  running.cpu_percent = 37.5;
  running.rss_bytes = 1 << 20;
  running.uptime_seconds = 12.5;
  ProcessStatus crashed = running;
  crashed.name = "feature_frontend";
  crashed.pid = 0;
  crashed.state = ProcState::kBackoff;
  crashed.last_exit_code = -9;
  const procman_status_t m = RoundTrip(ProcmanStatusToMessage("rover", 77, 55, {running, crashed}));
  EXPECT_EQ(m.utime, 55);
  EXPECT_EQ(m.host, "rover");
  EXPECT_EQ(m.launcher_pid, 77);
  ASSERT_EQ(m.num_procs, 2);
  EXPECT_EQ(m.procs[0].state, +proc_status_t::STATE_RUNNING);
  EXPECT_EQ(m.procs[0].restarts, 2);
  EXPECT_DOUBLE_EQ(m.procs[0].cpu_percent, 37.5);
  EXPECT_EQ(m.procs[0].rss_bytes, 1 << 20);
  EXPECT_DOUBLE_EQ(m.procs[0].uptime_seconds, 12.5);
  const PeerReport r = PeerReportFromMessage(m);
  EXPECT_EQ(r.host, "rover");
  EXPECT_EQ(r.launcher_pid, 77);
  ASSERT_EQ(r.procs.size(), 2u);
  EXPECT_EQ(r.procs[0].name, "crosssite_ba");
  EXPECT_EQ(r.procs[0].pid, 321);
  EXPECT_FALSE(r.procs[0].has_exited);
  EXPECT_EQ(r.procs[1].state, ProcState::kBackoff);
  EXPECT_EQ(r.procs[1].last_exit_code, -9);
  EXPECT_TRUE(r.procs[1].has_exited) << "a non-zero exit code";
}

TEST(ConvertLaunch, PeersCarryTheirStateAndCounts) {
  PeerView alive{"ground", 12, false, 0.4, 30, 0};
  PeerView lost{"relay", 13, true, 7.5, 3, 2};
  const procman_peers_t m = RoundTrip(ProcmanPeersToMessage("rover", 77, 55, 3.0, {alive, lost}));
  EXPECT_EQ(m.host, "rover");
  EXPECT_DOUBLE_EQ(m.lost_after_seconds, 3.0);
  ASSERT_EQ(m.num_peers, 2);
  EXPECT_EQ(m.peers[0].state, +procman_peer_t::STATE_ALIVE);
  EXPECT_EQ(m.peers[0].reports, 30);
  EXPECT_EQ(m.peers[1].state, +procman_peer_t::STATE_LOST);
  EXPECT_DOUBLE_EQ(m.peers[1].seconds_since_heard, 7.5);
  EXPECT_EQ(m.peers[1].times_lost, 2);
}

}  // namespace
}  // namespace vloc
