#pragma once
// LCM side of the absolute localization against an aerial map: the Navcam
// stereo pairs of a site (NAVCAM_STEREO, stereo_image_t) are collected
// until the site's panorama is complete; its predicted pose is the pose
// graph's (TRAVERSE, traverse_t: optimised pose with marginal covariance)
// or, before the graph has the site, dead reckoning (SITE_POSE_DR). The
// site's ground orthophoto is registered to the map (libs/maploc) and a
// usable fix is published as SITE_POSE_FIX (site_pose_t, source
// SOURCE_MAP_FIX = 4, world_from_body with covariance), which
// traverse_graph adds as an absolute fix. "No fix" is logged with its reason.

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/maploc/ground_ortho.h"
#include "vloc/maploc/map_raster.h"
#include "vloc/maploc/map_registration.h"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/traverse_t.hpp"

namespace vloc {

struct MapLocalizerProcOptions {
  std::string navcam_config = "config/navcam.yaml";  // Navcam calibration (rig + mast)
  std::string map_path = "";                         // GeoTIFF (grey [+ height band]) or PNG/JPEG + world file
  std::vector<double> map_offset_xy = {0.0, 0.0};    // m, subtracted from the map's coordinates (-> world frame)
  std::vector<double> map_geographic_origin = {};    // [lat, lon] deg: the map's coordinates are WGS84 degrees (the
                                                     // UAV mosaic's world file) and this point is the world origin
  double map_m_per_px = 0.0;                         // m, resample the map to this cell size on load (0 = the file's)
  bool reload_map_on_change = true;                  // re-read map_path when the file changes (a mosaic being updated)
  double wait_for_map_s = 0.0;                       // s, wait this long at start for map_path to appear (0 = not)
  std::string stereo_channel = "NAVCAM_STEREO";      // stereo_image_t in
  std::string traverse_channel = "TRAVERSE";         // traverse_t in: predicted pose + covariance
  std::string dr_channel = "SITE_POSE_DR";           // site_pose_t in: prior before the graph has the site
  std::string fix_channel = "SITE_POSE_FIX";         // site_pose_t out
  int fix_every = 1;                                 // attempt a fix at sites whose id is a multiple of this
  int queue_capacity = 100;                          // messages per subscription queue
  maploc::GroundOrthoOptions ortho;                  // m_per_px is replaced by the map's
  maploc::RegistrationOptions registration;

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
  // How the map file's coordinates become world metres.
  maploc::MapGeoreference Georeference() const;
};

// site_pose_t::source of a map fix (site_pose_t's constants stop at 3; the
// type is shipped, so the value is defined here rather than in the .lcm).
inline constexpr int8_t kSourceMapFix = 4;

class MapLocalizerAdapter {
 public:
  MapLocalizerAdapter(Transport& transport, const MapLocalizerProcOptions& options, const NavcamModel& navcam,
                      maploc::MapRaster map);
  // Re-reads the map when its file changed (called between messages).
  void OnIdle();
  std::string StatusLine() const;

 private:
  void OnStereo(const stereo_image_t& msg);
  void OnTraverse(const traverse_t& msg);
  void OnDeadReckoning(const site_pose_t& msg);
  void ProcessReadySites();
  void LocaliseSite(int site_id, std::vector<StereoPair> pairs, const PoseWithCovariance& prior);

  Transport& transport_;
  MapLocalizerProcOptions options_;
  NavcamModel navcam_;
  maploc::MapRaster map_;
  int64_t map_mtime_ = 0;
  std::map<int, std::vector<StereoPair>> pairs_;      // per site, until its panorama is complete
  std::map<int, int> expected_pairs_;                 // per site
  std::map<int, PoseWithCovariance> graph_poses_, dr_poses_;
  int newest_site_ = -1;
  std::shared_ptr<SubscriptionStats> stereo_stats_, traverse_stats_, dr_stats_;
  int64_t fixes_ = 0, no_fixes_ = 0, skipped_pairs_ = 0;
  std::string last_result_ = "none yet";
};

}  // namespace vloc
