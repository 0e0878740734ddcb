// PDS3 labels: the ODL parser on labels written here with known values
// (every construct real labels use), on malformed labels (one line naming
// the file, the line or the keyword), an attached label with its image in
// one .IMG, and every shared Curiosity label (../shared/data; skipped when
// absent): camera model, rover pose, counters, mast angles, and the
// linearisation error of each labelled CAHVOR model.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include "vloc/common/pds_label.h"

namespace vloc {
namespace {

namespace fs = std::filesystem;

std::string TempPath(const std::string& name) {
  return (fs::temp_directory_path() / ("vloc_pds_" + std::to_string(::getpid()) + "_" + name)).string();
}

std::string WriteFile(const std::string& name, const std::string& text) {
  const std::string path = TempPath(name);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// A label with known values in every construct the parser must handle
// (CR LF line ends, comments, units, a string across lines, nested
// sequences, a set, radix and namespaced keywords).
const char* kKnownLabel =
    "PDS_VERSION_ID = PDS3\r\n"
    "/* FILE DATA ELEMENTS */\r\n"
    "RECORD_TYPE = FIXED_LENGTH\r\n"
    "RECORD_BYTES = 64\r\n"
    "LABEL_RECORDS = 40\r\n"
    "^IMAGE = (\"TEST.IMG\",\r\n      41)\r\n"
    "PRODUCT_ID = \"NLA_TEST\"\r\n"
    "INSTRUMENT_ID = \"NAV_LEFT_A\"\r\n"
    "FRAME_ID = \"LEFT\"\r\n"
    "START_TIME = 2012-10-06T17:18:59.259\r\n"
    "PLANET_DAY_NUMBER = 60\r\n"
    "PRODUCER_INSTITUTION_NAME = \"MULTIMISSION INSTRUMENT PROCESSING \r\n"
    "                             LAB, JET PROPULSION LAB\"\r\n"
    "MSL:FLAGS = 16#FF#\r\n"
    "SYMBOL = 'A B'\r\n"
    "SET_VALUE = {1, 2, 3}\r\n"
    "MATRIX = ((1, 2), (3, 4))\r\n"
    "ROVER_MOTION_COUNTER = (7, 1234, 3)\r\n"
    "ROVER_MOTION_COUNTER_NAME = (\"SITE\",\"DRIVE\",\"POSE\")\r\n"
    "GROUP = GEOMETRIC_CAMERA_MODEL_PARMS\r\n"
    "  MODEL_TYPE = CAHVOR\r\n"
    "  MODEL_COMPONENT_1 = (1.0, 2.0, -1.5)\r\n"
    "  MODEL_COMPONENT_2 = (1.0, 0.0, 0.0)\r\n"
    "  MODEL_COMPONENT_3 = (500.0, 1000.0, 0.0)\r\n"
    "  MODEL_COMPONENT_4 = (500.0, 0.0,\r\n"
    "                       1000.0)\r\n"
    "  MODEL_COMPONENT_5 = (0.999999, 0.001, 0.0)\r\n"
    "  MODEL_COMPONENT_6 = (0.0, -0.005, 0.02) /* R */\r\n"
    "  REFERENCE_COORD_SYSTEM_NAME = \"ROVER_NAV_FRAME\"\r\n"
    "  REFERENCE_COORD_SYSTEM_INDEX = (7, 1234, 3)\r\n"
    "END_GROUP = GEOMETRIC_CAMERA_MODEL_PARMS\r\n"
    "GROUP = ROVER_COORD_SYSTEM_PARMS\r\n"
    "  ORIGIN_OFFSET_VECTOR = (10.0, -20.0, 0.5)\r\n"
    "  ORIGIN_ROTATION_QUATERNION = (0.70710678, 0.0, 0.0, 0.70710678)\r\n"
    "  REFERENCE_COORD_SYSTEM_NAME = \"SITE_FRAME\"\r\n"
    "END_GROUP\r\n"
    "GROUP = RSM_ARTICULATION_STATE_PARMS\r\n"
    "  ARTICULATION_DEVICE_ANGLE = (3.0 <rad>, 90.0 <deg>)\r\n"
    "  ARTICULATION_DEVICE_ANGLE_NAME = (\"AZIMUTH-MEASURED\", \"ELEVATION-MEASURED\")\r\n"
    "END_GROUP = RSM_ARTICULATION_STATE_PARMS\r\n"
    "GROUP = ROVER_DERIVED_GEOMETRY_PARMS\r\n"
    "  INSTRUMENT_AZIMUTH = 45.0 <deg>\r\n"
    "  INSTRUMENT_ELEVATION = -10.0 <deg>\r\n"
    "END_GROUP = ROVER_DERIVED_GEOMETRY_PARMS\r\n"
    "OBJECT = IMAGE\r\n"
    "  LINES = 3\r\n"
    "  LINE_SAMPLES = 4\r\n"
    "  SAMPLE_TYPE = MSB_INTEGER\r\n"
    "  SAMPLE_BITS = 16\r\n"
    "  BANDS = 1\r\n"
    "END_OBJECT = IMAGE\r\n"
    "END\r\n";

TEST(OdlParser, ReadsEveryConstructWithItsValue) {
  OdlBlock label;
  std::string error;
  size_t end = 0;
  ASSERT_TRUE(ParseOdl(kKnownLabel, OdlLimits(), &label, &error, &end)) << error;
  EXPECT_EQ(end, std::string(kKnownLabel).size());
  EXPECT_EQ(label.Find("PRODUCER_INSTITUTION_NAME")->value.text,
            "MULTIMISSION INSTRUMENT PROCESSING LAB, JET PROPULSION LAB");
  EXPECT_EQ(label.Find("msl:flags")->value.number, 255);
  EXPECT_EQ(label.Find("SYMBOL")->value.type, OdlValue::Type::kSymbol);
  EXPECT_EQ(label.Find("SET_VALUE")->value.type, OdlValue::Type::kSet);
  EXPECT_EQ(label.Find("MATRIX")->value.items[1].items[0].number, 3);
  EXPECT_EQ(label.Find("START_TIME")->value.type, OdlValue::Type::kIdentifier);
  EXPECT_EQ(label.Find("START_TIME")->value.text, "2012-10-06T17:18:59.259");
  const OdlAttribute* angle = label.FindPath("RSM_ARTICULATION_STATE_PARMS/ARTICULATION_DEVICE_ANGLE");
  ASSERT_TRUE(angle);
  EXPECT_EQ(angle->value.items[1].unit, "deg");
  EXPECT_EQ(label.FindPath("GEOMETRIC_CAMERA_MODEL_PARMS/MODEL_COMPONENT_4")->value.items[2].number, 1000.0);
  EXPECT_EQ(label.FindBlock("IMAGE")->kind, "OBJECT");
  EXPECT_EQ(label.Find("^IMAGE")->value.items[1].number, 41);
}

TEST(PdsCameraLabel, ReadsTheKnownValues) {
  const std::string path = WriteFile("known.LBL", kKnownLabel);
  PdsCameraLabel l;
  std::string error;
  ASSERT_TRUE(ReadPdsCameraLabel(path, &l, &error)) << error;
  EXPECT_EQ(l.camera.kind, CahvKind::kCahvor);
  EXPECT_EQ(l.camera.c, Eigen::Vector3d(1.0, 2.0, -1.5));
  EXPECT_NEAR(l.camera.o.norm(), 1.0, 1e-15) << "O normalised";
  EXPECT_EQ(l.camera.r, Eigen::Vector3d(0.0, -0.005, 0.02));
  EXPECT_NEAR(l.camera.hs(), 1000, 1e-9);
  EXPECT_NEAR(l.camera.hc(), 500, 1e-9);
  EXPECT_EQ(l.camera_frame, "ROVER_NAV_FRAME");
  EXPECT_EQ(l.camera_frame_index, (std::vector<int>{7, 1234, 3}));
  EXPECT_EQ(l.sol, 60);
  EXPECT_EQ(l.site, 7);
  EXPECT_EQ(l.drive, 1234);
  EXPECT_EQ(l.frame_id, "LEFT");
  ASSERT_TRUE(l.has_rover_pose);
  // 90 degrees about z: rover x is site y.
  EXPECT_TRUE((l.site_from_rover * Eigen::Vector3d(1, 0, 0)).isApprox(Eigen::Vector3d(10, -19, 0.5), 1e-7));
  EXPECT_EQ(l.rover_pose_frame, "SITE_FRAME");
  ASSERT_TRUE(l.has_mast_angles);
  EXPECT_DOUBLE_EQ(l.mast_azimuth, 3.0);
  EXPECT_NEAR(l.mast_elevation, M_PI / 2, 1e-12);
  EXPECT_NEAR(l.instrument_azimuth, M_PI / 4, 1e-12);
  EXPECT_EQ(l.image_file, "TEST.IMG");
  EXPECT_EQ(l.image_offset_bytes, 40 * 64);
  EXPECT_EQ(l.lines, 3);
  EXPECT_EQ(l.sample_bits, 16);
  std::remove(path.c_str());
}

// An .IMG with its label attached: ^IMAGE = 41 (records of 64 bytes), then
// 3 x 4 MSB 16-bit pixels.
TEST(PdsImage, ReadsAnAttachedLabelsImage) {
  std::string label = kKnownLabel;
  const std::string pointer = "^IMAGE = (\"TEST.IMG\",\r\n      41)";
  label.replace(label.find(pointer), pointer.size(), "^IMAGE = 41");
  ASSERT_LE(label.size(), 40u * 64);
  std::string bytes = label + std::string(40 * 64 - label.size(), ' ');
  for (int k = 0; k < 12; ++k) bytes += static_cast<char>((k * 300) >> 8), bytes += static_cast<char>((k * 300) & 0xff);
  const std::string path = WriteFile("attached.IMG", bytes);
  PdsCameraLabel l;
  std::string error;
  ASSERT_TRUE(ReadPdsCameraLabel(path, &l, &error)) << error;
  EXPECT_EQ(l.image_file, "");
  cv::Mat image;
  ASSERT_TRUE(ReadPdsImage(path, &image, &error)) << error;
  ASSERT_EQ(image.type(), CV_16UC1);
  EXPECT_EQ(image.size(), cv::Size(4, 3));
  EXPECT_EQ(image.at<uint16_t>(2, 3), 11 * 300);
  // A file cut short: one line naming the file and ^IMAGE.
  const std::string cut = WriteFile("cut.IMG", bytes.substr(0, bytes.size() - 2));
  EXPECT_FALSE(ReadPdsImage(cut, &image, &error));
  EXPECT_NE(error.find("cut.IMG: ^IMAGE"), std::string::npos) << error;
  std::remove(path.c_str());
  std::remove(cut.c_str());
}

struct Malformed {
  const char* what;
  std::string from, to;  // replace in kKnownLabel
  const char* expect;    // in the error line
  bool all = false;      // replace every occurrence
};

TEST(PdsCameraLabel, MalformedLabelsAreOneLineNamingTheFileAndKeyword) {
  const std::vector<Malformed> cases = {
      {"unclosed string", "\"ELEVATION-MEASURED\")", "\"ELEVATION-MEASURED)", "the string opened on line 40 is not closed"},
      {"unclosed group", "END_GROUP = ROVER_DERIVED_GEOMETRY_PARMS\r\n", "", "END inside GROUP ROVER_DERIVED_GEOMETRY_PARMS"},
      {"wrong end", "END_OBJECT = IMAGE", "END_GROUP = IMAGE", "closes OBJECT IMAGE"},
      {"no END", "END\r\n", "", "no END statement"},
      {"missing =", "SYMBOL = 'A B'", "SYMBOL 'A B'", "SYMBOL: '=' expected"},
      {"unclosed sequence", "(7, 1234, 3)\r\nROVER_MOTION_COUNTER_NAME", "(7, 1234, 3\r\nROVER_MOTION_COUNTER_NAME",
       "ROVER_MOTION_COUNTER: ',' or ')' expected"},
      {"short component", "(500.0, 1000.0, 0.0)", "(500.0, 1000.0)",
       "MODEL_COMPONENT_3 of GEOMETRIC_CAMERA_MODEL_PARMS: needs 3 numbers, has 2"},
      {"text component", "(1.0, 2.0, -1.5)", "(1.0, \"two\", -1.5)", "MODEL_COMPONENT_1 of GEOMETRIC_CAMERA_MODEL_PARMS"},
      {"unknown model", "MODEL_TYPE = CAHVOR", "MODEL_TYPE = PSPH", "MODEL_TYPE of GEOMETRIC_CAMERA_MODEL_PARMS: 'PSPH'"},
      {"no model", "GEOMETRIC_CAMERA_MODEL_PARMS", "OTHER_PARMS", "GEOMETRIC_CAMERA_MODEL_PARMS: missing", true},
      {"missing O", "  MODEL_COMPONENT_5 = (0.999999, 0.001, 0.0)\r\n", "", "MODEL_COMPONENT_5 of GEOMETRIC_CAMERA_MODEL_PARMS: missing"},
      {"A not unit", "MODEL_COMPONENT_2 = (1.0, 0.0, 0.0)", "MODEL_COMPONENT_2 = (2.0, 0.0, 0.0)", "MODEL_COMPONENT_2"},
      {"bad quaternion", "(0.70710678, 0.0, 0.0, 0.70710678)", "(0.70710678, 0.0, 0.70710678)",
       "ORIGIN_ROTATION_QUATERNION of ROVER_COORD_SYSTEM_PARMS: needs 4 numbers"},
      {"angle unit", "90.0 <deg>", "90.0 <m>", "ARTICULATION_DEVICE_ANGLE of RSM_ARTICULATION_STATE_PARMS: unit <m>"},
      {"binary byte", "SYMBOL = 'A B'", std::string("SYMBOL = A\x01") + "B", "control or non-ASCII"},
      {"deep nesting", "MATRIX = ((1, 2), (3, 4))", "MATRIX = " + std::string(40, '(') + "1" + std::string(40, ')'),
       "nested deeper than 16"},
  };
  for (const Malformed& m : cases) {
    std::string text = kKnownLabel;
    const size_t at = text.find(m.from);
    ASSERT_NE(at, std::string::npos) << m.what;
    text.replace(at, m.from.size(), m.to);
    for (size_t next = text.find(m.from); m.all && next != std::string::npos; next = text.find(m.from))
      text.replace(next, m.from.size(), m.to);
    const std::string path = WriteFile("bad.LBL", text);
    PdsCameraLabel l;
    std::string error;
    EXPECT_FALSE(ReadPdsCameraLabel(path, &l, &error)) << m.what;
    EXPECT_EQ(error.find('\n'), std::string::npos) << m.what << ": " << error;
    EXPECT_EQ(error.rfind(path, 0), 0u) << m.what << ": names the file: " << error;
    EXPECT_NE(error.find(m.expect), std::string::npos) << m.what << ": " << error;
    std::remove(path.c_str());
  }
  PdsCameraLabel l;
  std::string error;
  EXPECT_FALSE(ReadPdsCameraLabel(TempPath("absent.LBL"), &l, &error));
  EXPECT_NE(error.find("cannot open"), std::string::npos) << error;
  // A huge file without END: refused after max_bytes, not read whole.
  const std::string big = WriteFile("big.LBL", "PDS_VERSION_ID = PDS3\n" + std::string(1 << 16, ' '));
  OdlLimits small;
  small.max_bytes = 4096;
  EXPECT_FALSE(ReadPdsCameraLabel(big, &l, &error, small));
  EXPECT_NE(error.find("no END within the first 4096 bytes"), std::string::npos) << error;
  std::remove(big.c_str());
}

TEST(PdsCameraLabel, CahvoreTypeAndLinearity) {
  std::string text = kKnownLabel;
  text.replace(text.find("MODEL_TYPE = CAHVOR"), 19, "MODEL_TYPE = CAHVORE");
  const std::string r = "  MODEL_COMPONENT_6 = (0.0, -0.005, 0.02) /* R */\r\n";
  text.replace(text.find(r), r.size(),
               r + "  MODEL_COMPONENT_7 = (0.0, 0.004, -0.002)\r\n  MODEL_COMPONENT_8 = 3.0\r\n  MODEL_COMPONENT_9 = 0.25\r\n");
  const std::string path = WriteFile("cahvore.LBL", text);
  PdsCameraLabel l;
  std::string error;
  ASSERT_TRUE(ReadPdsCameraLabel(path, &l, &error)) << error;
  EXPECT_EQ(l.camera.kind, CahvKind::kCahvore);
  EXPECT_EQ(l.camera.linearity, 0.25);
  EXPECT_EQ(l.camera.e, Eigen::Vector3d(0.0, 0.004, -0.002));
  text.replace(text.find("MODEL_COMPONENT_8 = 3.0"), 23, "MODEL_COMPONENT_8 = 7.0");
  const std::string bad = WriteFile("cahvore_bad.LBL", text);
  EXPECT_FALSE(ReadPdsCameraLabel(bad, &l, &error));
  EXPECT_NE(error.find("MODEL_COMPONENT_8 of GEOMETRIC_CAMERA_MODEL_PARMS: the CAHVORE type must be 1, 2 or 3"),
            std::string::npos)
      << error;
  std::remove(path.c_str());
  std::remove(bad.c_str());
}

// ------------------------------------------------------- shared labels

std::vector<std::string> SharedLabels() {
  const fs::path root = fs::path(VLOC_SOURCE_DIR) / ".." / "shared" / "data" / "real";
  std::vector<std::string> out;
  for (const char* dir : {"mars_navcam", "mars_navcam_pano/sol38", "mars_navcam_pano/sol60"}) {
    if (!fs::is_directory(root / dir)) continue;
    for (const auto& e : fs::directory_iterator(root / dir))
      if (e.path().extension() == ".LBL") out.push_back(e.path().string());
  }
  std::sort(out.begin(), out.end());
  return out;
}

double Percentile(std::vector<double> v, double pct) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(pct / 100 * (v.size() - 1) + 0.5))];
}

TEST(PdsCameraLabel, EverySharedCuriosityLabel) {
  const std::vector<std::string> labels = SharedLabels();
  if (labels.empty()) GTEST_SKIP() << "../shared/data/real/mars_navcam* absent (real data beside the repo, see ../shared/data/README.md)";
  EXPECT_EQ(labels.size(), 22u);
  double worst_round_trip = 0;
  for (const std::string& path : labels) {
    PdsCameraLabel l;
    std::string error;
    ASSERT_TRUE(ReadPdsCameraLabel(path, &l, &error)) << error;
    EXPECT_EQ(l.camera.kind, CahvKind::kCahvor) << path;
    EXPECT_EQ(l.camera_frame, "ROVER_NAV_FRAME") << path;
    EXPECT_TRUE(l.has_rover_pose && l.has_mast_angles && l.has_instrument_pointing) << path;
    EXPECT_EQ(l.rover_pose_frame, "SITE_FRAME") << path;
    EXPECT_GT(l.site, 0) << path;
    EXPECT_EQ(l.camera_frame_index.at(0), l.site) << path;
    EXPECT_EQ(l.lines, 1024) << path;
    // The model's axis points where the label's derived geometry says the
    // instrument points (rover frame: azimuth clockwise from x about z
    // down, elevation up).
    const Eigen::Vector3d a = l.camera.a;
    const double az = std::atan2(a.y(), a.x()), el = std::asin(-a.z());
    const double daz = std::remainder(az - l.instrument_azimuth, 2 * M_PI);
    EXPECT_LT(std::abs(daz), 1.0 * M_PI / 180) << path;
    EXPECT_LT(std::abs(el - l.instrument_elevation), 1.0 * M_PI / 180) << path;
    // Round trip and linearisation over the image (every 16 px).
    const CahvModel lin = l.camera.LinearPart();
    std::vector<double> dist;
    for (int y = 0; y < 1024; y += 16)
      for (int x = 0; x < 1024; x += 16) {
        const Eigen::Vector2d px(x, y);
        const auto ray = l.camera.BackProject(px);
        ASSERT_TRUE(ray);
        worst_round_trip = std::max(worst_round_trip, (*l.camera.Project(ray->At(50)) - px).norm());
        dist.push_back((*lin.Project(ray->At(50)) - px).norm());
      }
    std::cout << fs::path(path).filename().string() << ": sol " << l.sol << " site " << l.site << " drive " << l.drive
              << ", CAHVOR -> CAHV max " << Percentile(dist, 100) << " px, p95 " << Percentile(dist, 95)
              << " px; axis az/el " << az * 180 / M_PI << "/" << el * 180 / M_PI << " deg vs label "
              << l.instrument_azimuth * 180 / M_PI << "/" << l.instrument_elevation * 180 / M_PI << "; mast "
              << l.mast_azimuth * 180 / M_PI << "/" << l.mast_elevation * 180 / M_PI << " deg\n";
  }
  std::cout << "round trip max over " << labels.size() << " labels: " << worst_round_trip << " px\n";
  EXPECT_LT(worst_round_trip, 1e-6);
}

}  // namespace
}  // namespace vloc
