// TunnelCore back to back in one thread: a lossy "link" between two cores
// (frames dropped or a connection cut), checked for complete, in-order
// delivery per channel, priorities, bounded queues with named drops, no
// echo, and hostile frames refused. Seeds fixed.

#include <gtest/gtest.h>

#include <map>
#include <random>

#include "vloc/tunnel/frame.h"
#include "vloc/tunnel/tunnel_core.h"

namespace vloc::tunnel {
namespace {

std::vector<uint8_t> Payload(int index, size_t size) {
  std::vector<uint8_t> p(size);
  for (size_t i = 0; i < size; ++i) p[i] = static_cast<uint8_t>(index * 31 + i * 7);
  return p;
}

TunnelOptions Options(const std::string& name) {
  TunnelOptions o;
  o.name = name;
  o.bind = name == "a" ? "tcp://*:1" : "";
  o.connect = name == "a" ? "" : "tcp://x:1";
  o.chunk_bytes = 1000;
  o.window_mb = 0.05;
  return o;
}

// Two cores and the frames between them. A connection "drops" frames while
// cut; `loss` drops frames at random only by cutting the connection (a TCP
// connection never loses frames in the middle).
struct Pair {
  TunnelCore a, b;
  std::vector<std::vector<uint8_t>> a_to_b, b_to_a;
  std::map<std::string, std::vector<std::vector<uint8_t>>> at_a, at_b;  // delivered, per channel
  double now = 0;
  bool up = false;

  Pair(const TunnelOptions& oa, const TunnelOptions& ob) : a(oa, 11), b(ob, 22) {}
  void Connect() {
    up = true;
    a.OnConnected(now);
    b.OnConnected(now);
  }
  void Cut() {
    up = false;
    a_to_b.clear();
    b_to_a.clear();
    a.OnDisconnected();
    b.OnDisconnected();
  }
  // Runs the link for `steps` of 10 ms; `cut_after_frames` cuts the
  // connection after that many frames a->b (in-flight frames are lost).
  void Run(int steps, int cut_after_frames = -1) {
    int frames = 0;
    for (int s = 0; s < steps; ++s) {
      now += 0.01;
      a.Pump(now, [&](const std::vector<uint8_t>& f) {
        if (!up) return false;
        a_to_b.push_back(f);
        return true;
      });
      b.Pump(now, [&](const std::vector<uint8_t>& f) {
        if (!up) return false;
        b_to_a.push_back(f);
        return true;
      });
      auto to_b = std::move(a_to_b);
      auto to_a = std::move(b_to_a);
      a_to_b.clear();
      b_to_a.clear();
      for (const auto& f : to_b) {
        if (cut_after_frames >= 0 && ++frames > cut_after_frames) {
          Cut();
          cut_after_frames = -1;
          break;
        }
        b.OnFrame(f.data(), f.size(), 0, now, [&](const std::string& c, const uint8_t* d, size_t n) {
          at_b[c].emplace_back(d, d + n);
        });
      }
      if (!up) continue;
      for (const auto& f : to_a)
        a.OnFrame(f.data(), f.size(), 0, now, [&](const std::string& c, const uint8_t* d, size_t n) {
          at_a[c].emplace_back(d, d + n);
        });
    }
  }
};

TEST(TunnelCore, DefaultsPassBadPatternsAndTwoEndpointsDoNot) {
  TunnelOptions o;
  std::string error;
  EXPECT_TRUE(o.Check(&error)) << error;
  o.bind = "tcp://*:7720";
  o.connect = "tcp://10.0.0.1:7720";
  EXPECT_FALSE(o.Check(&error));
  o.connect.clear();
  o.send_channels = {"(unclosed"};
  EXPECT_FALSE(o.Check(&error));
  EXPECT_NE(error.find("(unclosed"), std::string::npos);
}

TEST(TunnelCore, DeliversEverythingInOrderAcrossCutsAndReconnections) {
  Pair p(Options("a"), Options("b"));
  p.Connect();
  for (int i = 0; i < 60; ++i) {
    const auto big = Payload(i, 5000 + i * 17);  // 6-7 chunks each
    p.a.OnLocalMessage("NAVCAM_STEREO", big.data(), big.size(), 0, p.now);
    const auto small = Payload(1000 + i, 40);
    p.a.OnLocalMessage("DR_POSE", small.data(), small.size(), 0, p.now);
  }
  std::mt19937 rng(7);
  for (int round = 0; round < 12; ++round) {
    p.Run(3, static_cast<int>(rng() % 40));  // frames in flight lost with the connection
    p.Run(5);                                // down a while
    p.Connect();
  }
  p.Run(2000);
  ASSERT_EQ(p.at_b["NAVCAM_STEREO"].size(), 60u);
  ASSERT_EQ(p.at_b["DR_POSE"].size(), 60u);
  for (int i = 0; i < 60; ++i) {
    EXPECT_EQ(p.at_b["NAVCAM_STEREO"][i], Payload(i, 5000 + i * 17)) << i;
    EXPECT_EQ(p.at_b["DR_POSE"][i], Payload(1000 + i, 40)) << i;
  }
  const TunnelReport r = p.a.Report(p.now);
  EXPECT_GT(r.resent_frames, 0);
  EXPECT_EQ(r.dropped_queue_full, 0);
  EXPECT_EQ(r.queued_messages, 0);
}

TEST(TunnelCore, UrgentChannelsOvertakeImagesChunkByChunk) {
  TunnelOptions o = Options("a");
  o.bandwidth_cap_mbps = 0.8;  // 100 kB/s: 1 chunk per 10 ms step
  Pair p(o, Options("b"));
  p.Connect();
  p.Run(1);
  const auto image = Payload(1, 40000);  // 40 chunks
  p.a.OnLocalMessage("NAVCAM_STEREO", image.data(), image.size(), 0, p.now);
  p.Run(2);  // the image has started
  const auto pose = Payload(2, 50);
  p.a.OnLocalMessage("DR_POSE", pose.data(), pose.size(), 0, p.now);
  p.Run(5);  // about 5 chunks
  EXPECT_EQ(p.at_b["DR_POSE"].size(), 1u);
  EXPECT_EQ(p.at_b["NAVCAM_STEREO"].size(), 0u);
  p.Run(200);
  EXPECT_EQ(p.at_b["NAVCAM_STEREO"].size(), 1u);
}

TEST(TunnelCore, FullQueuesDropTheOldestAndNameTheChannel) {
  TunnelOptions o = Options("a");
  o.bulk_queue_messages = 5;
  Pair p(o, Options("b"));  // not connected: everything queues
  for (int i = 0; i < 12; ++i) {
    const auto m = Payload(i, 100);
    p.a.OnLocalMessage("UAV_CAMERA", m.data(), m.size(), 0, 0);
  }
  TunnelReport r = p.a.Report(0);
  EXPECT_EQ(r.dropped_queue_full, 7);
  ASSERT_EQ(r.channels.size(), 1u);
  EXPECT_EQ(r.channels[0].channel, "UAV_CAMERA");
  EXPECT_EQ(r.channels[0].dropped, 7);
  EXPECT_EQ(r.channels[0].queued_messages, 5);
  p.Connect();
  p.Run(100);
  ASSERT_EQ(p.at_b["UAV_CAMERA"].size(), 5u);
  EXPECT_EQ(p.at_b["UAV_CAMERA"][0], Payload(7, 100));  // the newest five, in order
}

TEST(TunnelCore, ARepublishedMessageHeardOnItsOwnBusIsNotSentBack) {
  Pair p(Options("a"), Options("b"));
  p.Connect();
  const auto status = Payload(3, 60);
  p.a.OnLocalMessage("PROCMAN_STATUS", status.data(), status.size(), 0, p.now);
  p.Run(10);
  ASSERT_EQ(p.at_b["PROCMAN_STATUS"].size(), 1u);
  // b's bus echoes it back to b (LCM hears its own publications).
  p.b.OnLocalMessage("PROCMAN_STATUS", status.data(), status.size(), 0, p.now);
  p.Run(10);
  EXPECT_EQ(p.at_a["PROCMAN_STATUS"].size(), 0u);
  EXPECT_EQ(p.b.Report(p.now).echoes_skipped, 1);
  // The same bytes published again by a process on b's bus do cross.
  p.b.OnLocalMessage("PROCMAN_STATUS", status.data(), status.size(), 0, p.now);
  p.Run(10);
  EXPECT_EQ(p.at_a["PROCMAN_STATUS"].size(), 1u);
}

TEST(TunnelCore, ChannelsTheReceiverDoesNotAcceptAreRefused) {
  TunnelOptions ob = Options("b");
  ob.receive_channels = {"DR_POSE"};
  Pair p(Options("a"), ob);
  p.Connect();
  const auto m = Payload(4, 3000);
  p.a.OnLocalMessage("PROCMAN_ORDERS", m.data(), m.size(), 0, p.now);
  p.a.OnLocalMessage("DR_POSE", m.data(), m.size(), 0, p.now);
  p.Run(20);
  EXPECT_EQ(p.at_b.count("PROCMAN_ORDERS"), 0u);
  EXPECT_EQ(p.at_b["DR_POSE"].size(), 1u);
  EXPECT_EQ(p.b.Report(p.now).refused_from_peer, 1);
}

TEST(TunnelCore, BandwidthCapHoldsTheRate) {
  TunnelOptions o = Options("a");
  o.bandwidth_cap_mbps = 0.8;  // 100 kB/s
  Pair p(o, Options("b"));
  p.Connect();
  p.Run(1);
  p.a.Report(p.now);
  for (int i = 0; i < 30; ++i) {
    const auto m = Payload(i, 10000);
    p.a.OnLocalMessage("UAV_CAMERA", m.data(), m.size(), 0, p.now);
  }
  p.Run(100);  // 1 s: about 100 kB of 300 kB
  const auto n = p.at_b["UAV_CAMERA"].size();
  EXPECT_GE(n, 8u);
  EXPECT_LE(n, 12u);
}

TEST(Frame, RoundTripAndHostileFramesRefused) {
  DataFrame d;
  d.seq = 5;
  d.msg_id = 9;
  d.total_size = 10;
  d.offset = 4;
  d.channel = "IMU";
  const uint8_t chunk[3] = {1, 2, 3};
  d.chunk = chunk;
  d.chunk_size = 3;
  auto bytes = EncodeData(77, d);
  FrameLimits limits;
  Frame f;
  std::string error;
  ASSERT_TRUE(DecodeFrame(bytes.data(), bytes.size(), limits, &f, &error)) << error;
  EXPECT_EQ(f.session, 77u);
  EXPECT_EQ(f.data.channel, "IMU");
  EXPECT_EQ(f.data.chunk_size, 3u);
  // Every truncation and 20,000 random flips: refused or decoded, never a crash.
  for (size_t n = 0; n < bytes.size(); ++n) EXPECT_FALSE(DecodeFrame(bytes.data(), n, limits, &f, &error)) << n;
  std::mt19937 rng(3);
  for (int i = 0; i < 20000; ++i) {
    auto b = bytes;
    b[rng() % b.size()] = static_cast<uint8_t>(rng());
    if (DecodeFrame(b.data(), b.size(), limits, &f, &error)) {
      EXPECT_LE(f.data.offset + f.data.chunk_size, f.data.total_size);
    }
  }
  // A chunk outside its message; a message over the limit.
  d.offset = 9;
  bytes = EncodeData(77, d);
  EXPECT_FALSE(DecodeFrame(bytes.data(), bytes.size(), limits, &f, &error));
  d.offset = 0;
  d.total_size = 0xffffffffu;
  bytes = EncodeData(77, d);
  EXPECT_FALSE(DecodeFrame(bytes.data(), bytes.size(), limits, &f, &error));
}

TEST(TunnelCore, RandomFramesNeverCrashOrDeliver) {
  TunnelCore core(Options("a"), 1);
  core.OnConnected(0);
  std::mt19937 rng(5);
  int delivered = 0;
  for (int i = 0; i < 5000; ++i) {
    std::vector<uint8_t> f(rng() % 200);
    for (auto& b : f) b = static_cast<uint8_t>(rng());
    if (f.size() >= 4 && i % 2) f[0] = 0x56, f[1] = 0x4C, f[2] = 0x54, f[3] = 0x31;  // right magic
    core.OnFrame(f.data(), f.size(), 0, i * 0.001, [&](const std::string&, const uint8_t*, size_t) { ++delivered; });
  }
  EXPECT_EQ(delivered, 0);
  EXPECT_GT(core.Report(5).rejected_frames, 2000);
}

}  // namespace
}  // namespace vloc::tunnel
