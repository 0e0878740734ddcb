#pragma once
// A folder of synthetic PDS3 Navcam products with known values, written at
// test time, for navcam_driver's PDS mode (procs/navcam_driver/navcam_pds.h):
//
//   site 0 = SITE 3 DRIVE 10 (sol 100)
//     pair 0  t0       left/right .IMG with the label attached, 8 bit      levels 10/11, az 30, el -20 deg
//     pair 1  t0+20 s  left/right .LBL + .IMG, 16 bit (12-bit data) LSB/MSB levels 20/21, az -15, el -25 deg
//   site 1 = SITE 3 DRIVE 20 (START_TIME in day-of-year form)
//     pair 0  t0+100 s .LBL + colour .png browse images (B, G, R = level, 100, 200)  levels 40/41,
//                      no derived pointing: pointing from the model's axis A
//     pair 1  t0+110 s ...M1.LBL + ...M_.jpg browse JPEGs (grey)           levels 60/61, az 90, el 0
// and nine bad products, each one line from the driver (kPdsFixtureProblems).
#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "driver_fixtures.h"

namespace vloc::testing {

// The sol60 frames' CAHVOR (NLA_402815759, rover nav frame): a model Check() accepts.
inline const char* kPdsFixtureModel[6] = {"(0.75256,0.788509,-2.00864)",   "(-0.964222,0.184182,-0.190622)",
                                          "(-714.321,-1112.04,-102.306)",  "(-719.106,130.979,1106.97)",
                                          "(-0.966697,0.167968,-0.193047)", "(0.000274,-0.004951,0.021485)"};

struct PdsFixtureFrame {
  std::string frame_id = "LEFT";
  std::string instrument_id = "NAV_LEFT_A";
  std::string start_time = "2020-01-01T00:00:10.000";  // "" = no START_TIME
  std::string sequence_id = "ncam00001";
  bool motion_counter = true;
  int site = 3, drive = 10, sol = 100;
  bool derived_pointing = true;
  double azimuth_deg = 0, elevation_deg = 0;
  std::string model_4 = kPdsFixtureModel[3];
  std::string model_type = "CAHVOR";
  std::vector<std::string> model;  // MODEL_COMPONENT_1..n as written; empty = kPdsFixtureModel with model_4
  std::string image_pointer;  // e.g. ^IMAGE = 2 or ^IMAGE = ("X.IMG", 1); "" = none
  int record_bytes = 4096;
  int lines = 48, samples = 64, bits = 8;
  std::string sample_type = "UNSIGNED_INTEGER";
};

inline std::string PdsLabelText(const PdsFixtureFrame& f) {
  std::ostringstream os;
  os << "PDS_VERSION_ID = PDS3\r\nRECORD_TYPE = FIXED_LENGTH\r\nRECORD_BYTES = " << f.record_bytes << "\r\n";
  if (!f.image_pointer.empty()) os << f.image_pointer << "\r\n";
  os << "PRODUCT_ID = \"TEST\"\r\nINSTRUMENT_ID = \"" << f.instrument_id << "\"\r\nFRAME_ID = \"" << f.frame_id
     << "\"\r\n";
  if (!f.start_time.empty()) os << "START_TIME = " << f.start_time << "\r\n";
  os << "SEQUENCE_ID = \"" << f.sequence_id << "\"\r\nPLANET_DAY_NUMBER = " << f.sol << "\r\n";
  if (f.motion_counter)
    os << "ROVER_MOTION_COUNTER = (" << f.site << "," << f.drive << ",8,10)\r\n"
       << "ROVER_MOTION_COUNTER_NAME = (\"SITE\",\"DRIVE\",\"POSE\",\"ARM\")\r\n";
  os << "GROUP = GEOMETRIC_CAMERA_MODEL_PARMS\r\n  MODEL_TYPE = " << f.model_type << "\r\n";
  for (size_t k = 0; k < (f.model.empty() ? 6 : f.model.size()); ++k)
    os << "  MODEL_COMPONENT_" << k + 1 << " = "
       << (!f.model.empty() ? f.model[k] : k == 3 ? f.model_4 : std::string(kPdsFixtureModel[k])) << "\r\n";
  os << "  REFERENCE_COORD_SYSTEM_NAME = ROVER_NAV_FRAME\r\nEND_GROUP = GEOMETRIC_CAMERA_MODEL_PARMS\r\n"
     << "GROUP = ROVER_COORD_SYSTEM_PARMS\r\n  ORIGIN_OFFSET_VECTOR = (" << 1.5 + f.drive << ", -2.0, 0.25)\r\n"
     << "  ORIGIN_ROTATION_QUATERNION = (1.0, 0.0, 0.0, 0.0)\r\n  REFERENCE_COORD_SYSTEM_NAME = SITE_FRAME\r\n"
     << "END_GROUP = ROVER_COORD_SYSTEM_PARMS\r\n";
  if (f.derived_pointing)
    os << "GROUP = ROVER_DERIVED_GEOMETRY_PARMS\r\n  INSTRUMENT_AZIMUTH = " << f.azimuth_deg
       << " <deg>\r\n  INSTRUMENT_ELEVATION = " << f.elevation_deg << " <deg>\r\nEND_GROUP = ROVER_DERIVED_GEOMETRY_PARMS\r\n";
  os << "OBJECT = IMAGE\r\n  LINES = " << f.lines << "\r\n  LINE_SAMPLES = " << f.samples
     << "\r\n  SAMPLE_BITS = " << f.bits << "\r\n  SAMPLE_TYPE = " << f.sample_type
     << "\r\n  BANDS = 1\r\nEND_OBJECT = IMAGE\r\nEND\r\n";
  return os.str();
}

// The pixels of an .IMG: 8 bit, or 16 bit holding 12-bit data (level x 16).
inline std::string PdsPixels(const cv::Mat& grey8, int bits, bool lsb) {
  std::string out;
  for (int y = 0; y < grey8.rows; ++y)
    for (int x = 0; x < grey8.cols; ++x) {
      const int v = grey8.at<uint8_t>(y, x);
      if (bits == 8) {
        out.push_back(static_cast<char>(v));
        continue;
      }
      const uint16_t u = static_cast<uint16_t>(v * 16);
      const char lo = static_cast<char>(u & 0xff), hi = static_cast<char>(u >> 8);
      out.push_back(lsb ? lo : hi);
      out.push_back(lsb ? hi : lo);
    }
  return out;
}

inline void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// An .IMG with its label attached (label in record 1, image from record 2).
inline void WriteAttachedImg(const std::string& path, PdsFixtureFrame f, const cv::Mat& grey8) {
  f.image_pointer = "^IMAGE = 2";
  std::string text = PdsLabelText(f);
  text.resize(static_cast<size_t>(f.record_bytes), ' ');
  WriteBytes(path, text + PdsPixels(grey8, f.bits, true));
}

// X.LBL + X.IMG.
inline void WriteDetachedImg(const std::string& dir, const std::string& name, PdsFixtureFrame f, const cv::Mat& grey8,
                             bool lsb) {
  f.image_pointer = "^IMAGE = (\"" + name + ".IMG\", 1)";
  f.sample_type = lsb ? "LSB_UNSIGNED_INTEGER" : "MSB_UNSIGNED_INTEGER";
  WriteBytes(dir + "/" + name + ".LBL", PdsLabelText(f));
  WriteBytes(dir + "/" + name + ".IMG", PdsPixels(grey8, f.bits, lsb));
}

// A browse image beside its label (the EDR's ^IMAGE file absent).
inline void WriteBrowse(const std::string& dir, const std::string& label_name, const std::string& image_name,
                        PdsFixtureFrame f, const cv::Mat& image) {
  f.image_pointer = "^IMAGE = (\"" + label_name + ".IMG\", 23)";
  WriteBytes(dir + "/" + label_name + ".LBL", PdsLabelText(f));
  cv::imwrite(dir + "/" + image_name, image);
}

// A colour image: B = level, G = 100, R = 200, with the fixture's disc.
inline cv::Mat FixtureColour(int level) {
  cv::Mat grey = FixtureImage(level);
  cv::Mat channels[3] = {grey, cv::Mat(grey.size(), CV_8UC1, cv::Scalar(100)), cv::Mat(grey.size(), CV_8UC1, cv::Scalar(200))};
  cv::Mat out;
  cv::merge(channels, 3, out);
  return out;
}

// What the driver says about each bad product of the fixture (one line each).
inline const std::vector<std::string> kPdsFixtureProblems = {
    "bad_model.LBL: MODEL_COMPONENT_4 of GEOMETRIC_CAMERA_MODEL_PARMS: needs 3 numbers, has 2",
    "no_time.LBL: START_TIME: missing",
    "no_counter.LBL: ROVER_MOTION_COUNTER: missing",
    "mono.LBL: FRAME_ID: 'MONO'",
    "thumb.LBL: LINES / LINE_SAMPLES of IMAGE: the label says 64 x 48, its browse image",
    "lonely_right.LBL: FRAME_ID RIGHT: no LEFT frame of SEQUENCE_ID 'ncam00009' within 0.5 s",
    "orphan.jpg: no PDS label beside it",
    "no_pixels.LBL: ^IMAGE: its file no_pixels.IMG is absent",
    "broken.LBL: line ",
};

// Writes the fixture into dir/pds; returns that folder.
inline std::string WritePdsFixture(const std::string& dir) {
  const std::string pds = dir + "/pds";
  std::filesystem::create_directories(pds + "/site_a");
  std::filesystem::create_directories(pds + "/site_b");
  const std::string a = pds + "/site_a", b = pds + "/site_b";
  PdsFixtureFrame left, right;
  right.frame_id = "RIGHT";
  right.instrument_id = "NAV_RIGHT_A";
  // Site 0, pair 0: attached labels.
  left.azimuth_deg = right.azimuth_deg = 30;
  left.elevation_deg = right.elevation_deg = -20;
  WriteAttachedImg(a + "/L0.IMG", left, FixtureImage(10));
  WriteAttachedImg(a + "/R0.IMG", right, FixtureImage(11));
  // Site 0, pair 1: detached, 16 bit; the right eye 40 ms later.
  left.start_time = "2020-01-01T00:00:30.000";
  right.start_time = "2020-01-01T00:00:30.040";
  left.azimuth_deg = right.azimuth_deg = -15;
  left.elevation_deg = right.elevation_deg = -25;
  left.bits = right.bits = 16;
  WriteDetachedImg(a, "L1", left, FixtureImage(20), true);
  WriteDetachedImg(a, "R1", right, FixtureImage(21), false);
  left.bits = right.bits = 8;
  // Site 1, pair 0: colour PNG browse images, pointing from the model.
  left.drive = right.drive = 20;
  left.start_time = right.start_time = "2020-001T00:01:50.000";
  left.derived_pointing = right.derived_pointing = false;
  WriteBrowse(b, "L2", "L2.png", left, FixtureColour(40));
  WriteBrowse(b, "R2", "R2.png", right, FixtureColour(41));
  // Site 1, pair 1: the gallery's ...M1.LBL + ...M_.jpg.
  left.start_time = right.start_time = "2020-01-01T00:02:00.000";
  left.derived_pointing = right.derived_pointing = true;
  left.azimuth_deg = right.azimuth_deg = 90;
  left.elevation_deg = right.elevation_deg = 0;
  left.sequence_id = right.sequence_id = "ncam00002";
  WriteBrowse(b, "NLA_0001M1", "NLA_0001M_.jpg", left, FixtureImage(60));
  WriteBrowse(b, "NRA_0001M1", "NRA_0001M_.jpg", right, FixtureImage(61));
  // Bad products, all at site 0's counters.
  PdsFixtureFrame bad;
  bad.model_4 = "(1.0, 2.0)";
  WriteBrowse(a, "bad_model", "bad_model.png", bad, FixtureImage(90));
  bad = PdsFixtureFrame();
  bad.start_time = "";
  WriteBrowse(a, "no_time", "no_time.png", bad, FixtureImage(90));
  bad = PdsFixtureFrame();
  bad.motion_counter = false;
  WriteBrowse(a, "no_counter", "no_counter.png", bad, FixtureImage(90));
  bad = PdsFixtureFrame();
  bad.frame_id = "MONO";
  WriteBrowse(a, "mono", "mono.png", bad, FixtureImage(90));
  bad = PdsFixtureFrame();
  WriteBrowse(a, "thumb", "thumb.png", bad, FixtureImage(90, 32, 24));
  bad = right;
  bad.site = 3;
  bad.drive = 10;
  bad.sequence_id = "ncam00009";
  bad.start_time = "2020-01-01T00:00:50.000";
  WriteBrowse(a, "lonely_right", "lonely_right.png", bad, FixtureImage(90));
  cv::imwrite(a + "/orphan.jpg", FixtureImage(90));
  bad = PdsFixtureFrame();
  bad.image_pointer = "^IMAGE = (\"no_pixels.IMG\", 1)";
  WriteBytes(a + "/no_pixels.LBL", PdsLabelText(bad));
  WriteBytes(a + "/broken.LBL", "PDS_VERSION_ID = PDS3\r\nGROUP = X\r\n  A = (1, 2\r\nEND\r\n");
  return pds;
}

}  // namespace vloc::testing
