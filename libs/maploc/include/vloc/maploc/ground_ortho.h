#pragma once
// The rover's ground orthophoto at a site: the Navcam stereo pairs of the
// site's panorama, matched by the project's dense ZNCC + LSM stereo
// (libs/features dense_stereo.h), intersected into 3-D, levelled with the
// site's roll and pitch, and binned into a north-up raster of the site's
// level frame (x forward, y left, z up, origin at the body origin): mean
// grey level and mean height per cell, unseen cells marked invalid.
//
//   vloc::maploc::GroundOrthoSummary summary;
//   vloc::maploc::MapRaster ortho = vloc::maploc::BuildGroundOrtho(pairs, navcam, roll, pitch, options, &summary);

#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/rover_data.h"
#include "vloc/features/dense_stereo.h"
#include "vloc/maploc/map_raster.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::maploc {

struct GroundOrthoOptions {
  double m_per_px = 0.1;        // m, cell size of the orthophoto
  double max_range_m = 12.0;    // m, horizontal range kept around the rover
  double min_range_m = 1.0;     // m, nearer points are the rover itself
  int downsample = 2;           // images reduced by this factor before stereo (1 = full size)
  DenseStereoOptions stereo;    // dense stereo on the reduced images (max_disparity in reduced px)
  double max_rectification_error = 1e-6;  // rig must be rectified: |R - I| and intrinsics difference below this

  GroundOrthoOptions();
  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct GroundOrthoSummary {
  bool usable = false;
  std::string message;          // why not usable, or "ok"
  int pairs = 0;                // stereo pairs used
  long stereo_points = 0;       // matched points in range
  long valid_cells = 0;         // orthophoto cells with data
  double stereo_seconds = 0, total_seconds = 0;
  std::string BriefReport() const;
};

// Orthophoto of one site from its pairs (any order). `roll`, `pitch` (rad):
// the body's attitude (level_from_body = RotationFromRollPitchYaw(roll, pitch, 0)).
// Throws std::invalid_argument on bad options; bad or empty pairs give an
// unusable summary and an empty raster.
MapRaster BuildGroundOrtho(const std::vector<StereoPair>& pairs, const NavcamModel& navcam, double roll, double pitch,
                           const GroundOrthoOptions& options, GroundOrthoSummary* summary = nullptr);

}  // namespace vloc::maploc
