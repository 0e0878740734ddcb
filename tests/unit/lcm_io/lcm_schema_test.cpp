// The schema check that stands between the bus and lcm-gen's decoders:
// parsed schemas agree with lcm-gen (fingerprints), every well-formed
// message passes, and hostile bytes (huge string lengths, absurd counts,
// truncations, random flips) are rejected without a crash.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>

#include "vloc/frontend_status_t.hpp"
#include "vloc/image_t.hpp"
#include "vloc/imu_t.hpp"
#include "vloc/lcm_io/lcm_schema.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/pose_t.hpp"
#include "vloc/proc_status_t.hpp"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/site_event_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/tie_observation_t.hpp"
#include "vloc/tie_point_t.hpp"
#include "vloc/tie_points_t.hpp"
#include "vloc/traverse_t.hpp"
#include "vloc/uav_gps_t.hpp"
#include "vloc/uav_state_t.hpp"
#include "vloc/wheel_odometry_t.hpp"

namespace vloc {
namespace {

const LcmSchema& Schema() { return LcmSchema::Vloc(); }

template <class Msg>
std::vector<uint8_t> Bytes(const Msg& msg) {
  std::vector<uint8_t> b(static_cast<size_t>(msg.getEncodedSize()));
  EXPECT_EQ(msg.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  return b;
}

template <class Msg>
void ExpectSchemaMatches() {
  SCOPED_TRACE(Msg::getTypeName());
  ASSERT_TRUE(Schema().Has(Msg::getTypeName()));
  EXPECT_EQ(Schema().Fingerprint(Msg::getTypeName()), Msg::getHash());
  EXPECT_EQ(Schema().TypeOfFingerprint(Msg::getHash()), Msg::getTypeName());
  const Msg empty{};
  const auto bytes = Bytes(empty);
  std::string error;
  EXPECT_TRUE(Schema().Check(Msg::getTypeName(), bytes.data(), bytes.size(), &error)) << error;
}

TEST(LcmSchema, FingerprintsAgreeWithLcmGenForEveryType) {
  ExpectSchemaMatches<frontend_status_t>();
  ExpectSchemaMatches<image_t>();
  ExpectSchemaMatches<imu_t>();
  ExpectSchemaMatches<localization_t>();
  ExpectSchemaMatches<pose_t>();
  ExpectSchemaMatches<proc_status_t>();
  ExpectSchemaMatches<procman_order_t>();
  ExpectSchemaMatches<procman_status_t>();
  ExpectSchemaMatches<site_event_t>();
  ExpectSchemaMatches<site_pose_t>();
  ExpectSchemaMatches<stereo_image_t>();
  ExpectSchemaMatches<tie_observation_t>();
  ExpectSchemaMatches<tie_point_t>();
  ExpectSchemaMatches<tie_points_t>();
  ExpectSchemaMatches<traverse_t>();
  ExpectSchemaMatches<uav_gps_t>();
  ExpectSchemaMatches<uav_state_t>();
  ExpectSchemaMatches<wheel_odometry_t>();
}

TEST(LcmSchema, EveryLcmFileOfTheProjectIsEmbedded) {
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(VLOC_SOURCE_DIR) + "/lcmtypes")) {
    if (entry.path().extension() != ".lcm") continue;
    ++files;
    EXPECT_TRUE(Schema().Has(entry.path().stem().string())) << entry.path();
  }
  EXPECT_EQ(static_cast<int>(Schema().TypeNames().size()), files);
}

TEST(LcmSchema, ParserNamesFileAndLineOfAnError) {
  LcmSchema s;
  try {
    s.AddSource("bad.lcm", "package p;\nstruct a_t {\n  int32_t n;\n  double x[m];\n}\n");
    FAIL() << "accepted an array sized by an unknown member";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("bad.lcm:4"), std::string::npos) << e.what();
  }
  EXPECT_THROW(s.AddSource("bad2.lcm", "struct b_t { int32_t x }"), std::invalid_argument);
}

tie_points_t FullTiePoints() {
  tie_points_t m;
  m.utime = 123;
  m.previous_site_id = 3;
  m.current_site_id = 4;
  m.num_previous_pairs = m.num_current_pairs = 2;
  m.previous_mast_pan = m.previous_mast_tilt = m.current_mast_pan = m.current_mast_tilt = {0.1, 0.2};
  for (int i = 0; i < 5; ++i) {
    tie_point_t p;
    p.id = i;
    p.num_observations = 2;
    p.observations.resize(2);
    p.observations[1].u = 3.5;
    m.points.push_back(p);
  }
  m.num_points = 5;
  m.previous_site_pose.pose.frame_id = "world";
  m.current_site_pose_dr.pose.child_frame_id = "body";
  return m;
}

TEST(LcmSchema, FilledMessagesPassAndDecode) {
  const auto bytes = Bytes(FullTiePoints());
  std::string error;
  EXPECT_TRUE(Schema().Check("tie_points_t", bytes.data(), bytes.size(), &error)) << error;
  tie_points_t back;
  EXPECT_TRUE(Decode(bytes.data(), bytes.size(), &back, &error)) << error;
  EXPECT_EQ(back.points.size(), 5u);
}

// Offset of the first string length field of a procman_order_t (after the
// 8-byte fingerprint and the int64 utime).
constexpr size_t kHostLengthOffset = 16;

void PutInt32(std::vector<uint8_t>* b, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) (*b)[at + static_cast<size_t>(k)] = static_cast<uint8_t>(v >> (24 - 8 * k));
}

TEST(LcmSchema, StringLengthsThatWouldOverrunTheBufferAreRejected) {
  procman_order_t order;
  order.host = "rover";
  order.target = "crosssite_ba";
  for (uint32_t length : {0x80000000u, 0xFFFFFFFFu, 0u, 0x7FFFFFFFu, 1000u}) {
    auto bytes = Bytes(order);
    PutInt32(&bytes, kHostLengthOffset, length);
    std::string error;
    EXPECT_FALSE(Schema().Check("procman_order_t", bytes.data(), bytes.size(), &error)) << length;
    EXPECT_NE(error.find("host"), std::string::npos) << error;
    procman_order_t decoded;
    EXPECT_FALSE(Decode(bytes.data(), bytes.size(), &decoded));  // and, above all, no SIGSEGV
  }
}

TEST(LcmSchema, AbsurdArrayCountsAreRejectedBeforeAnyAllocation) {
  auto bytes = Bytes(FullTiePoints());
  // num_previous_pairs sits after the fingerprint, utime, two ids and two site poses.
  const LcmStruct* s = Schema().Find("tie_points_t");
  ASSERT_NE(s, nullptr);
  image_t image;
  image.size = 3;
  image.data = {1, 2, 3};
  auto image_bytes = Bytes(image);
  // image_t: fingerprint 8, utime 8, frame_id (4 + 1), width 4, height 4, encoding 1, then size.
  for (uint32_t count : {0x80000000u, 0x7FFFFFFFu, 4u, 0xFFFFFFFFu}) {
    auto b = image_bytes;
    PutInt32(&b, 8 + 8 + 5 + 4 + 4 + 1, count);
    std::string error;
    EXPECT_FALSE(Schema().Check("image_t", b.data(), b.size(), &error)) << count;
    EXPECT_NE(error.find("data"), std::string::npos) << error;
  }
}

TEST(LcmSchema, EveryTruncationIsRejected) {
  const auto bytes = Bytes(FullTiePoints());
  for (size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_FALSE(Schema().Check("tie_points_t", bytes.data(), n)) << n;
    tie_points_t m;
    EXPECT_FALSE(Decode(bytes.data(), n, &m)) << n;
  }
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_FALSE(Schema().Check("tie_points_t", longer.data(), longer.size()));
}

TEST(LcmSchema, RandomFlipsNeverGetPastTheCheckIntoAnUnsafeDecode) {
  std::mt19937 rng(7);
  const auto good = Bytes(FullTiePoints());
  int accepted = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    auto b = good;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) b[8 + rng() % (b.size() - 8)] = static_cast<uint8_t>(rng());
    tie_points_t m;
    accepted += Decode(b.data(), b.size(), &m);  // a crash here fails the test
  }
  EXPECT_GT(accepted, 0);  // flips of numbers still decode: the check is not a blanket refusal
}

TEST(LcmSchema, WrongTypeIsNamed) {
  const auto bytes = Bytes(FullTiePoints());
  std::string error;
  EXPECT_FALSE(Schema().Check("site_pose_t", bytes.data(), bytes.size(), &error));
  EXPECT_NE(error.find("tie_points_t"), std::string::npos) << error;
}

TEST(LcmSchema, NonFiniteNumbersAreFoundUnlessTheSchemaAllowsNaN) {
  site_pose_t pose;
  pose.pose.orientation[0] = 1;
  auto bytes = Bytes(pose);
  EXPECT_EQ(Schema().CountNonFinite("site_pose_t", bytes.data(), bytes.size()), 0);
  pose.pose.position[1] = std::numeric_limits<double>::quiet_NaN();
  pose.pose.covariance[7] = std::numeric_limits<double>::infinity();
  bytes = Bytes(pose);
  std::string first;
  EXPECT_EQ(Schema().CountNonFinite("site_pose_t", bytes.data(), bytes.size(), &first), 2);
  EXPECT_NE(first.find("position"), std::string::npos) << first;

  uav_state_t state;  // latitude/longitude: "NaN when not georeferenced"
  state.latitude = state.longitude = std::numeric_limits<double>::quiet_NaN();
  bytes = Bytes(state);
  EXPECT_EQ(Schema().CountNonFinite("uav_state_t", bytes.data(), bytes.size()), 0);
  state.height = std::numeric_limits<double>::quiet_NaN();
  state.latitude = std::numeric_limits<double>::infinity();
  bytes = Bytes(state);
  EXPECT_EQ(Schema().CountNonFinite("uav_state_t", bytes.data(), bytes.size()), 2);
}

TEST(TypedPublish, RefusesNonFiniteNumbers) {
  MockTransport t;
  site_pose_t pose;
  pose.pose.orientation[0] = 1;
  EXPECT_TRUE(Publish(t, "X", pose));
  pose.pose.position[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(Publish(t, "X", pose));
  EXPECT_EQ(t.Count("X"), 1);
}

TEST(LcmTransportQueue, DropsAreCountedNotSilent) {
  std::string error;
  auto t = MakeLcmTransport("memq://", &error);
  ASSERT_TRUE(t) << error;
  int handled = 0;
  auto stats = Subscribe<site_event_t>(*t, "EV", [&](const std::string&, const site_event_t&) { ++handled; }, 10);
  site_event_t ev{};
  for (int i = 0; i < 50; ++i) ASSERT_TRUE(Publish(*t, "EV", ev));
  while (t->Handle(0) > 0) {
  }
  EXPECT_EQ(handled + stats->dropped, 50);
  EXPECT_EQ(stats->dropped, 40);
  EXPECT_EQ(stats->received, 10);
}

}  // namespace
}  // namespace vloc
