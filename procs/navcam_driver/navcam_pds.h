#pragma once
// Reading a folder of PDS3 Navcam products without a manifest (issue 33).
//
// Products found under the folder (recursively, at most max_files files):
//   - an .IMG with its label attached;
//   - a detached .LBL with the .IMG its ^IMAGE names;
//   - a detached .LBL beside a JPEG/PNG browse image, as the public raw-image
//     galleries serve them: X.jpg / X.jpeg / X.png / X.IMG.png / X.IMG.jpg
//     beside X.LBL, and the EDR naming ...M_.jpg beside ...M1.LBL (the last
//     character of the label's name, the product version, replaced by '_').
// From each label (vloc::ReadPdsCameraLabel, libs/common/pds_label.h):
//   eye        FRAME_ID LEFT / RIGHT, else LEFT / RIGHT in INSTRUMENT_ID
//   time       START_TIME (UTC, 2012-10-06T17:18:59.259 or 2012-280T17:18:59.259)
//   site       ROVER_MOTION_COUNTER: SITE and DRIVE
//   pointing   ROVER_DERIVED_GEOMETRY_PARMS INSTRUMENT_AZIMUTH / _ELEVATION
//              (rover frame), else the camera model's axis A when the model
//              is in the rover frame: pan = -azimuth (vloc: positive left),
//              tilt = -elevation (vloc: positive down)
//   rover pose ROVER_COORD_SYSTEM_PARMS (site frame), kept in the entry
// Grouping by the labels' fields alone: a site is one (SITE, DRIVE) pair of
// counters (sites numbered 0, 1, ... in time order: vloc's site ids); a
// stereo pair is a LEFT and a RIGHT frame of one site and one SEQUENCE_ID
// whose start times lie within pair_max_dt (each frame in one pair, the
// nearest in time first); pairs numbered in time order within their site.
// Every problem is one line naming the file and the keyword, and the good
// products are kept: a label that cannot be read, a label without an image
// (or an image without a label), a browse image of another size than its
// label's IMAGE object, a frame with no other eye (published nowhere: vloc's
// stereo_image_t and the front end need both eyes), a MONO frame. The
// camera model does not travel (stereo_image_t has no field for it): give
// the front end a camera file of the same camera. No LCM here.

#include <string>
#include <vector>

#include "navcam_manifest.h"

namespace vloc {

class OptionsReader;

struct NavcamPdsOptions {
  double pair_max_dt = 0.5;      // s, most start-time difference of a LEFT and a RIGHT frame of one pair
  int max_files = 100000;        // files looked at under the folder (a folder of more is refused)
  int max_image_side = 8192;     // px, largest image width / height read (LINES, LINE_SAMPLES or a browse image)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// One site as the labels define it (for the log: vloc site id -> counters).
struct NavcamPdsSite {
  int site_id = 0;          // vloc's site id (0 = first in time)
  int pds_site = -1;        // ROVER_MOTION_COUNTER SITE
  int pds_drive = -1;       // ROVER_MOTION_COUNTER DRIVE
  int sol = -1;             // PLANET_DAY_NUMBER of its first frame
  int frames = 0;           // frames read (both eyes)
  int pairs = 0;            // stereo pairs formed
  std::string Describe() const;  // "site 0: SITE 5 DRIVE 104 (sol 60): 6 stereo pairs of 12 frames"
};

struct NavcamPdsFolder {
  NavcamManifest manifest;           // entries (site ids, pair indices, times, pointing, files) + problem lines
  std::vector<NavcamPdsSite> sites;  // in site-id order, also those without a pair
};

// Reads every product under `folder`. manifest.readable is false only when
// the folder itself cannot be listed (or holds more than max_files files).
NavcamPdsFolder ReadNavcamPdsFolder(const std::string& folder, const NavcamPdsOptions& options);

// "2012-10-06T17:18:59.259" or "2012-280T17:18:59.259" (UTC, optional Z) to
// microseconds since 1970-01-01; false when not such a time.
bool ParsePdsUtcTime(const std::string& text, int64_t* utime);

}  // namespace vloc
