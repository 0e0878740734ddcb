#pragma once
// PDS3 labels: a parser of the Object Description Language (PDS Standards
// Reference v3.8, chapter 12) and the reader of the planetary camera
// products vloc uses (a camera model, the rover's pose in the site frame,
// the motion counters and the mast angles).
//
// The ODL parser handles what real labels hold: OBJECT / GROUP blocks
// (nested, END_OBJECT / END_GROUP with or without the name), namespaced
// keywords (MSL:REQUEST_ID), pointers (^IMAGE), integers (also radix
// 16#FF#), reals, units (12.5 <m>), quoted strings across lines (line breaks
// and the blanks around them become one space), 'symbols', bare identifiers
// and dates, sequences (a, b), sequences of sequences ((a, b), (c)), sets
// {a, b}, /* comments */, CR LF line ends, and the END statement (what
// follows it, e.g. the image of an attached label, is not read).
// Why not GDAL's PDS driver (libgdal-dev, 3.6): it exposes the whole label
// as JSON (metadata domain json:PDS), but it opens a product only with its
// image: a detached .LBL beside the JPEG/PNG browse image the public
// galleries serve (the shared sol60 panorama) is refused ("Failed to open
// ....IMG"), and the common layer must not depend on GDAL.
//
//   vloc::OdlBlock label;
//   if (!vloc::ParseOdlFile(path, vloc::OdlLimits(), &label, &error)) ...
//   const vloc::OdlValue* m = label.FindPath("GEOMETRIC_CAMERA_MODEL_PARMS/MODEL_TYPE");

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/cahvor.h"
#include "vloc/common/pose.h"

namespace vloc {

// One ODL value.
struct OdlValue {
  enum class Type { kInteger, kReal, kString, kSymbol, kIdentifier, kSequence, kSet };
  Type type = Type::kIdentifier;
  std::string text;             // as written (strings without their quotes, blanks normalised)
  double number = 0;            // kInteger, kReal
  std::string unit;             // "m" for 12.5 <m>; empty without one
  std::vector<OdlValue> items;  // kSequence, kSet

  bool IsNumber() const { return type == Type::kInteger || type == Type::kReal; }
  bool IsList() const { return type == Type::kSequence || type == Type::kSet; }
};

// A keyword = value statement, with the line it started on.
struct OdlAttribute {
  std::string keyword;  // upper case as written, namespace and ^ kept: "MSL:REQUEST_ID", "^IMAGE"
  OdlValue value;
  int line = 0;
};

// The label (kind "ROOT") or an OBJECT / GROUP block in it.
struct OdlBlock {
  std::string kind;  // "ROOT", "OBJECT" or "GROUP"
  std::string name;
  int line = 0;
  std::vector<OdlAttribute> attributes;
  std::vector<OdlBlock> children;

  // The first attribute / child block of that name (case-insensitive), or
  // null.
  const OdlAttribute* Find(const std::string& keyword) const;
  const OdlBlock* FindBlock(const std::string& name) const;
  // "GROUP_NAME/KEYWORD" (any depth, blocks separated by '/'), or null.
  const OdlAttribute* FindPath(const std::string& path) const;
};

struct OdlLimits {
  size_t max_bytes = 4 << 20;     // label text read at most (bytes)
  int max_depth = 16;             // nested OBJECT / GROUP / sequence levels
  size_t max_statements = 100000; // attributes and blocks
};

// Parses label text. On failure false and *error = "line N: what". The
// optional *end_offset is the byte just after the END statement's line.
bool ParseOdl(const std::string& text, const OdlLimits& limits, OdlBlock* root, std::string* error,
              size_t* end_offset = nullptr);
// Reads and parses a label file (a detached .LBL, or the attached label at
// the start of an .IMG): at most limits.max_bytes are read; an attached
// label must end (END) within them. *error names the file.
bool ParseOdlFile(const std::string& path, const OdlLimits& limits, OdlBlock* root, std::string* error);

// What vloc reads from a rover camera product's label.
struct PdsCameraLabel {
  std::string label_path;
  std::string product_id;       // PRODUCT_ID
  std::string instrument_id;    // INSTRUMENT_ID, e.g. NAV_LEFT_A
  std::string frame_id;         // FRAME_ID: LEFT / RIGHT / MONO
  std::string start_time;       // START_TIME, UTC as written
  std::string spacecraft_clock; // SPACECRAFT_CLOCK_START_COUNT as written ("402815759.199"); "" when absent
  std::string sequence_id;      // SEQUENCE_ID ("ncam00451"); "" when absent
  int sol = -1;                 // PLANET_DAY_NUMBER, -1 when absent
  int site = -1;                // ROVER_MOTION_COUNTER[SITE]
  int drive = -1;               // ROVER_MOTION_COUNTER[DRIVE]
  std::vector<int> motion_counter;  // the whole ROVER_MOTION_COUNTER

  CahvModel camera;             // GEOMETRIC_CAMERA_MODEL_PARMS
  std::string camera_frame;     // its REFERENCE_COORD_SYSTEM_NAME, e.g. ROVER_NAV_FRAME
  std::vector<int> camera_frame_index;  // its REFERENCE_COORD_SYSTEM_INDEX

  bool has_rover_pose = false;  // ROVER_COORD_SYSTEM_PARMS read
  Pose3 site_from_rover = Pose3::Identity();  // ORIGIN_OFFSET_VECTOR (m), ORIGIN_ROTATION_QUATERNION (s, x, y, z)
  std::string rover_pose_frame; // its REFERENCE_COORD_SYSTEM_NAME (SITE_FRAME)

  bool has_mast_angles = false; // RSM_ARTICULATION_STATE_PARMS read
  double mast_azimuth = 0;      // rad, AZIMUTH-MEASURED (the joint's own zero)
  double mast_elevation = 0;    // rad, ELEVATION-MEASURED
  bool has_instrument_pointing = false;  // ROVER_DERIVED_GEOMETRY_PARMS read
  double instrument_azimuth = 0;    // rad, in the rover frame (clockwise from +x about +z down)
  double instrument_elevation = 0;  // rad, up from the rover's x-y plane

  std::string image_file;       // the ^IMAGE file ("" for an attached label: the label's own file)
  int64_t image_offset_bytes = -1;  // where the image starts in it (-1: no ^IMAGE)
  int lines = 0, line_samples = 0, sample_bits = 0, bands = 0;  // the IMAGE object
  std::string sample_type;      // its SAMPLE_TYPE
};

// Reads a rover camera label (a .LBL, or an .IMG with its label attached).
// Needs a camera model (MODEL_TYPE CAHV, CAHVOR or CAHVORE and its
// components); everything else is read when present. On failure false and
// *error is one line naming the file and the keyword ("x.LBL: MODEL_COMPONENT_4
// of GEOMETRIC_CAMERA_MODEL_PARMS: needs 3 numbers, has 2").
bool ReadPdsCameraLabel(const std::string& path, PdsCameraLabel* out, std::string* error,
                        const OdlLimits& limits = OdlLimits());

// The image of a PDS3 product (uncompressed, BAND_SEQUENTIAL band 1:
// 8-bit or 16-bit integers, MSB/LSB, with optional line prefix/suffix
// bytes): CV_8UC1 or CV_16UC1 (signed 16-bit clamped at 0). Image sizes over
// max_pixels are refused before reading. False with *error naming the file
// and the keyword.
bool ReadPdsImage(const std::string& path, cv::Mat* image, std::string* error, const OdlLimits& limits = OdlLimits(),
                  int64_t max_pixels = int64_t(1) << 27);

}  // namespace vloc
