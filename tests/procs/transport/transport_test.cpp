// Real processes over real LCM: loopback multicast on test-unique ports
// (7700-7719), lcm-logger / lcm-logplayer, and LCM refusing to start.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <thread>

#include "vloc/lcm_io/convert_rover.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/testing/subprocess.h"

namespace vloc {
namespace {

using testing::BinPath;
using testing::Subprocess;
using testing::TestLcmUrl;

int Field(const std::string& output, const std::string& key) {
  const auto pos = output.find("\n" + key + ": ");
  if (pos == std::string::npos) return -1;
  return std::stoi(output.substr(pos + key.size() + 3));
}

TEST(Transport, TwoProcessesExchange100MessagesOf1MBWithoutLoss) {
  const std::string url = TestLcmUrl(7701);
  Subprocess receiver({BinPath("vloc_lcm_probe"), "receive", "--count", "100", "--timeout", "60", "--lcm-url", url});
  ASSERT_TRUE(receiver.WaitForOutput("ready", 10)) << receiver.output();
  Subprocess sender({BinPath("vloc_lcm_probe"), "send", "--count", "100", "--size", "1048576", "--rate", "50",
                     "--lcm-url", url});
  ASSERT_EQ(sender.WaitExit(60), 0) << sender.output();
  ASSERT_EQ(receiver.WaitExit(60), 0) << receiver.output();
  EXPECT_EQ(Field(receiver.output(), "received"), 100) << receiver.output();
  EXPECT_EQ(Field(receiver.output(), "lost"), 0);
  EXPECT_EQ(Field(receiver.output(), "corrupt"), 0);
}

TEST(Transport, WrongTypeOnAChannelIsReportedAndSkipped) {
  const std::string url = TestLcmUrl(7702);
  Subprocess receiver({BinPath("vloc_lcm_probe"), "receive", "--count", "5", "--timeout", "30", "--lcm-url", url});
  ASSERT_TRUE(receiver.WaitForOutput("ready", 10)) << receiver.output();
  std::string error;
  auto transport = MakeLcmTransport(url, &error);
  ASSERT_TRUE(transport) << error;
  ASSERT_TRUE(Publish(*transport, "VLOC_PROBE", WheelOdometryToMessage({1, 2.0, 0.1})));
  Subprocess sender({BinPath("vloc_lcm_probe"), "send", "--count", "5", "--size", "1000", "--lcm-url", url});
  ASSERT_EQ(sender.WaitExit(30), 0) << sender.output();
  ASSERT_EQ(receiver.WaitExit(30), 0) << receiver.output();
  EXPECT_EQ(Field(receiver.output(), "received"), 5);
  EXPECT_EQ(Field(receiver.output(), "wrong_type"), 1);
  EXPECT_NE(receiver.output().find("channel VLOC_PROBE: a message of"), std::string::npos) << receiver.output();
  EXPECT_NE(receiver.output().find("is not a vloc::image_t"), std::string::npos) << receiver.output();
}

TEST(Transport, LoggerRecordsAndLogplayerReplaysIntoAProcess) {
  const std::string record_url = TestLcmUrl(7703);
  const std::string replay_url = TestLcmUrl(7704);
  const std::string log = ::testing::TempDir() + "/transport_test_" + std::to_string(getpid()) + ".lcmlog";
  std::filesystem::remove(log);
  {
    Subprocess logger({"/usr/bin/lcm-logger", "--lcm-url=" + record_url, "-f", log});
    // The logger has subscribed once a warm-up message shows up in the file
    // (200 kB: larger than stdio's buffer, so it is written at once); what
    // is sent before that is lost, by design of multicast.
    std::string error;
    auto transport = MakeLcmTransport(record_url, &error);
    ASSERT_TRUE(transport) << error;
    const std::vector<uint8_t> warm_up(200000, 0);
    bool subscribed = false;
    for (int i = 0; i < 100 && !subscribed; ++i) {
      ASSERT_TRUE(transport->Publish("VLOC_WARM_UP", warm_up.data(), warm_up.size()));
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      subscribed = std::filesystem::exists(log) && std::filesystem::file_size(log) > 0;
    }
    ASSERT_TRUE(subscribed) << "lcm-logger wrote nothing in 10 s\n" << logger.output();
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // warm-ups still in flight land
    Subprocess sender({BinPath("vloc_lcm_probe"), "send", "--count", "20", "--size", "200000", "--rate", "20",
                       "--lcm-url", record_url});
    ASSERT_EQ(sender.WaitExit(30), 0) << sender.output();
    // Wait until all 20 are on disk (each ~200 kB).
    const auto before = std::filesystem::file_size(log);
    for (int i = 0; i < 100 && std::filesystem::file_size(log) < before + 20 * 200000; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    logger.Signal(SIGINT);
    ASSERT_TRUE(logger.WaitExit(10)) << logger.output();
  }
  // What the log holds, read directly.
  int in_log = 0;
  {
    lcm::LogFile file(log, "r");
    ASSERT_TRUE(file.good());
    while (const lcm::LogEvent* ev = file.readNextEvent()) in_log += ev->channel == "VLOC_PROBE";
  }
  ASSERT_EQ(in_log, 20) << "lcm-logger did not record every message";

  Subprocess receiver({BinPath("vloc_lcm_probe"), "receive", "--count", "20", "--timeout", "30", "--lcm-url",
                       replay_url});
  ASSERT_TRUE(receiver.WaitForOutput("ready", 10));
  Subprocess player({"/usr/bin/lcm-logplayer", "--lcm-url=" + replay_url, "--speed=4", log});
  ASSERT_EQ(receiver.WaitExit(30), 0) << receiver.output();
  EXPECT_EQ(Field(receiver.output(), "received"), 20);
  EXPECT_EQ(Field(receiver.output(), "corrupt"), 0);
  player.WaitExit(10);
  std::filesystem::remove(log);
}

TEST(Transport, NoMulticastRouteIsOneLineWithTheFix) {
  // A fresh network namespace has no multicast route, like a vehicle booted
  // without a network. Needs CAP_SYS_ADMIN (CI runs as root).
  if (geteuid() != 0) GTEST_SKIP() << "needs root for unshare -n";
  Subprocess p({"/usr/bin/unshare", "-n", BinPath("vloc_lcm_probe"), "receive", "--count", "1", "--timeout", "1",
                "--lcm-url", TestLcmUrl(7705)});
  EXPECT_EQ(p.WaitExit(20), 1) << p.output();
  EXPECT_NE(p.output().find("LCM could not start"), std::string::npos) << p.output();
  EXPECT_NE(p.output().find("ip route add 224.0.0.0/4 dev lo"), std::string::npos);
  // LCM's own multi-line explanation is held back: exactly one line.
  EXPECT_EQ(std::count(p.output().begin(), p.output().end(), '\n'), 1) << p.output();
}

TEST(Transport, MissingConfigAndUnknownFlagAreOneLine) {
  Subprocess p({BinPath("vloc_lcm_probe"), "receive", "--cuont", "3"});
  EXPECT_EQ(p.WaitExit(10), 1);
  EXPECT_NE(p.output().find("unknown option --cuont"), std::string::npos) << p.output();
}

}  // namespace
}  // namespace vloc
