// Starts the real feature_frontend process on loopback LCM and feeds it two
// textureless sites: it must answer with a FRONTEND_STATUS that says why it
// failed (and keep running), and reject a bad config with one line.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>

#include "vloc/frontend_status_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/testing/rover_inputs.h"

namespace vloc {
namespace {

const char* kUrl = "udpm://239.255.76.67:7741?ttl=0&recv_buf_size=33554432";

std::string Bin() {
  const char* b = std::getenv("VLOC_BIN_DIR");
  return std::string(b ? b : VLOC_BIN_DIR) + "/feature_frontend";
}

pid_t Start(const std::string& config) {
  const pid_t pid = fork();
  if (pid == 0) {
    execl(Bin().c_str(), "feature_frontend", "--config", config.c_str(), "--lcm-url", kUrl, nullptr);
    _exit(127);
  }
  return pid;
}

// The dead-reckoning pose of `site` (10 m apart along x).
void PublishDrPose(Transport& transport, int site) {
  PoseWithCovariance pose;
  pose.pose = MakePose(10.0 * site, 0, 0, 0, 0, 0);
  Publish(transport, "SITE_POSE_DR", SitePoseToMessage(site, site_pose_t::SOURCE_DEAD_RECKONING, pose));
}

// FRONTEND_STATUS as it arrives: how many, and the last one.
struct StatusWatch {
  std::atomic<int> received{0};
  frontend_status_t last;
  explicit StatusWatch(Transport& transport) {
    Subscribe<frontend_status_t>(transport, "FRONTEND_STATUS", [this](const std::string&, const frontend_status_t& m) {
      last = m;
      ++received;
    });
  }
  // Handles the transport until a status arrives or `seconds` pass.
  void WaitForFirst(Transport& transport, int seconds) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(seconds);
    while (received == 0 && std::chrono::steady_clock::now() < deadline) transport.Handle(100);
  }
};

// SIGTERM to the process, then its wait status.
int Stop(pid_t pid) {
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

// A whole textureless site: its DR pose, then 3 stereo pairs.
void PublishTexturelessSite(Transport& transport, int site) {
  PublishDrPose(transport, site);
  for (int k = 0; k < 3; ++k) {
    Publish(transport, "NAVCAM_STEREO", StereoPairToMessage(testing::TexturelessPair(site, k), ImageEncoding::kPng));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

TEST(FeatureFrontendProc, TexturelessSitesGiveLowTextureStatus) {
  std::string error;
  auto transport = MakeLcmTransport(kUrl, &error);
  ASSERT_TRUE(transport) << error;
  StatusWatch watch(*transport);
  const pid_t pid = Start("config/procs/feature_frontend.yaml");
  ASSERT_GT(pid, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // process start-up (no handshake channel)
  for (int site = 0; site < 2; ++site) PublishTexturelessSite(*transport, site);
  watch.WaitForFirst(*transport, 60);
  const int status = Stop(pid);
  ASSERT_EQ(watch.received.load(), 1);
  EXPECT_EQ(watch.last.previous_site_id, 0);
  EXPECT_EQ(watch.last.current_site_id, 1);
  EXPECT_EQ(static_cast<int>(watch.last.status), static_cast<int>(frontend_status_t::STATUS_LOW_TEXTURE)) << watch.last.message;
  EXPECT_FALSE(watch.last.message.empty());
  EXPECT_EQ(watch.last.num_stages, static_cast<int>(watch.last.stage_names.size()));
  EXPECT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

// A site whose imaging is done but whose images never arrived (a lossy link)
// is reported as MISSING_INPUT naming the missing pairs as soon as the rover
// reaches the next site, not left waiting for a later site to complete.
TEST(FeatureFrontendProc, SiteWithoutImagesIsReportedNotAwaited) {
  std::string error;
  auto transport = MakeLcmTransport(kUrl, &error);
  ASSERT_TRUE(transport) << error;
  StatusWatch watch(*transport);
  const pid_t pid = Start("config/procs/feature_frontend.yaml");
  ASSERT_GT(pid, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  PublishTexturelessSite(*transport, 0);
  // Site 1: its DR pose and IMAGING_DONE (3 pairs) arrive; its images do not.
  PublishDrPose(*transport, 1);
  SiteEvent done;
  done.utime = 5000000;
  done.site_id = 1;
  done.event = SiteEventType::kImagingDone;
  done.num_pairs = 3;
  Publish(*transport, "ROVER_SITE", SiteEventToMessage(done));
  const auto wait_until = std::chrono::steady_clock::now() + std::chrono::milliseconds(1500);
  while (std::chrono::steady_clock::now() < wait_until) transport->Handle(100);
  EXPECT_EQ(watch.received.load(), 0) << "reported before the rover moved on (images may still be on their way)";
  // The rover reaches site 2: site 1's images are not coming.
  PublishDrPose(*transport, 2);
  watch.WaitForFirst(*transport, 20);
  const int status = Stop(pid);
  ASSERT_EQ(watch.received.load(), 1);
  EXPECT_EQ(static_cast<int>(watch.last.status), static_cast<int>(frontend_status_t::STATUS_MISSING_INPUT)) << watch.last.message;
  EXPECT_EQ(watch.last.current_site_id, 1);
  EXPECT_NE(watch.last.message.find("0 of 3 pairs (missing 0, 1, 2)"), std::string::npos) << watch.last.message;
  EXPECT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST(FeatureFrontendProc, BadConfigIsRejectedWithOneLine) {
  char path[] = "/tmp/feature_frontend_bad_XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  const std::string text = "frontend:\n  no_such_key: 3\n";
  ASSERT_EQ(write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  close(fd);
  const pid_t pid = Start(path);
  int status = 0;
  waitpid(pid, &status, 0);
  unlink(path);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1);
}

}  // namespace
}  // namespace vloc
