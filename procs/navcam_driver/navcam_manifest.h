#pragma once
// Reading a Navcam manifest: a YAML file listing recorded stereo pairs.
//
//   # times in seconds (any epoch), angles in `angle_unit` (rad or deg)
//   angle_unit: deg
//   pairs:
//     - {site: 0, pair: 0, pan: 30.0, tilt: 25.0, time: 100.0, left: site0/L0.png, right: site0/R0.png}
//     - {site: 0, pair: 1, pan: 15.0, tilt: 25.0, time: 102.5, left: site0/L1.png, right: site0/R1.png}
//
// Image paths are relative to the manifest's folder. Every problem with a
// row (missing key, value out of range, missing image file) is one line in
// `problems` naming the row, its line in the file and the fix; the row is
// skipped and the good rows are kept. A site is a run of equal site ids in
// time order and its num_pairs is the number of its rows, so its pair
// indices must be distinct and below that count (and kMaxPairsPerSite):
// a repeated index, or one at or beyond the count (pair 99 of a site of 6
// rows), is refused the same way. No LCM here (the driver's adapter
// publishes).

#include <cstdint>
#include <string>
#include <vector>

#include "vloc/common/rover_data.h"

namespace vloc {

struct NavcamManifestEntry {
  int row = 0;            // 1-based row in `pairs`
  int line = 0;           // 1-based line of the row in the manifest file
  int64_t utime = 0;      // microseconds
  int site_id = 0;
  int pair_index = 0;
  double pan = 0;         // rad, positive left
  double tilt = 0;        // rad, positive down
  std::string left_path;  // resolved paths (an .IMG is read as a PDS3 product, its label attached or beside it)
  std::string right_path;
  bool has_rover_pose = false;                // PDS: the label gave the rover's pose
  Pose3 site_from_rover = Pose3::Identity();  // PDS: ROVER_COORD_SYSTEM_PARMS (site frame x north, y east, z down)
};

struct NavcamManifest {
  std::vector<NavcamManifestEntry> entries;  // good rows, sorted by time
  std::vector<std::string> problems;         // one line per skipped row or file-level problem
  bool readable = false;                     // false when the manifest itself could not be read
};

NavcamManifest ReadNavcamManifest(const std::string& path);

// Loads both images of an entry as they are: 8-bit grey, or BGR colour when
// both files are colour (a colour and a grey eye: both grey); 16-bit images
// (PNG, PDS .IMG) scaled to 8 bits (12-bit data by 1/16, else by 1/256),
// an alpha channel dropped. An .IMG path is read as a PDS3 product. False
// with one line in *error (unreadable image, sizes differ); `num_pairs` is
// set by the caller.
bool LoadNavcamPair(const NavcamManifestEntry& entry, StereoPair* pair, std::string* error);

}  // namespace vloc
