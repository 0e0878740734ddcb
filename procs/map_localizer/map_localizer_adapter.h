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
//
// State a message can add is bounded: a repeated pair (same site and
// pair_index) replaces the earlier copy, pair_index lies below num_pairs and
// num_pairs below max_pairs_per_site; at most max_sites_waiting sites wait
// for their panorama or prior, and graph / dead-reckoning poses are kept for
// the newest site_window sites (KeepNewestSites).

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/rate_limited_log.h"
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
  bool reload_map_on_change = true;                  // re-read map_path when the file changes (a mosaic being updated),
                                                     // the newest sites without a fix tried again on it
  double wait_for_map_s = 0.0;                       // s, sites wait this long for a map_path not there yet (0 = not)
  std::string stereo_channel = "NAVCAM_STEREO";      // stereo_image_t in
  std::string traverse_channel = "TRAVERSE";         // traverse_t in: predicted pose + covariance
  std::string dr_channel = "SITE_POSE_DR";           // site_pose_t in: prior before the graph has the site
  std::string fix_channel = "SITE_POSE_FIX";         // site_pose_t out
  int fix_every = 1;                                 // attempt a fix at sites whose id is a multiple of this
  int queue_capacity = 100;                          // messages per subscription queue
  int max_pairs_per_site = 32;                       // a site's num_pairs above this is refused (a full 360 x
                                                     // 3-tier panorama is about 30 pairs)
  int max_sites_waiting = 3;                         // sites (of the fix_every ones) collecting pairs or waiting for
                                                     // a prior; an older one is dropped when a newer one exceeds this
  int site_window = 64;                              // sites whose graph / DR poses (and "localised") are remembered:
                                                     // the newest ids
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
  // Without a map (LoadMap not called or `map` empty), sites collect and
  // wait for it (max_sites_waiting); OnIdle reads map_path once it is there.
  MapLocalizerAdapter(Transport& transport, const MapLocalizerProcOptions& options, const NavcamModel& navcam,
                      maploc::MapRaster map = maploc::MapRaster());
  // Reads map_path now: false with `error` when it cannot be read.
  bool LoadMap(std::string* error);
  // Reads the map when its file appeared or changed (called between messages).
  void OnIdle();
  bool HasMap() const { return !map_.gray.empty(); }
  // The map's size, cell size, heights and extent, for a log line.
  std::string MapDescription() const;
  std::string StatusLine() const;

 private:
  void OnStereo(const stereo_image_t& msg);
  void OnTraverse(const traverse_t& msg);
  void OnDeadReckoning(const site_pose_t& msg);
  void ProcessReadySites();
  void LocaliseSite(int site_id, std::vector<StereoPair> pairs, const PoseWithCovariance& prior);
  // The site's ground orthophoto registered to the map: true when a fix
  // was published.
  bool RegisterSite(int site_id, const maploc::MapRaster& ortho, const maploc::GroundOrthoSummary& ortho_summary,
                    const PoseWithCovariance& prior);
  // The sites without a fix tried again on the map just read.
  void RetrySites();
  // The map file read into map_ when it is there; false (map_ kept) when it is not or cannot be read.
  bool ReadMap();
  // `map` the one sites are registered to (the orthophoto's cell size follows it).
  void UseMap(maploc::MapRaster map);

  Transport& transport_;
  MapLocalizerProcOptions options_;
  NavcamModel navcam_;
  maploc::MapRaster map_;
  int64_t map_mtime_ = 0;
  struct WaitingSite {
    std::map<int, StereoPair> pairs;  // by pair_index: a repeated pair replaces the earlier copy
    int num_pairs = 0;                // from the site's first pair; later pairs must agree
  };
  // Stores a graph or DR pose of a site within the window; false if implausible.
  bool KeepPose(int site_id, const PoseWithCovariance& pose, std::map<int, PoseWithCovariance>* poses);
  void DropSite(std::map<int, WaitingSite>::iterator it, const std::string& why);

  std::map<int, WaitingSite> waiting_;                // per site, until its panorama and prior are in
  struct SiteToRetry {
    maploc::MapRaster ortho;  // its ground orthophoto (the panorama's product: no need to keep the images)
    maploc::GroundOrthoSummary ortho_summary;
    PoseWithCovariance prior;
  };
  // The newest max_sites_waiting sites a map still being written (reload_map_on_change) gave no fix:
  // a mosaic that did not reach them yet, or reached only their edge.
  std::map<int, SiteToRetry> to_retry_;
  std::map<int, PoseWithCovariance> graph_poses_, dr_poses_;  // the newest site_window sites
  std::set<int> localised_;                           // sites done (newest site_window): later pairs ignored
  int newest_site_ = -1;
  std::shared_ptr<SubscriptionStats> stereo_stats_, traverse_stats_, dr_stats_;
  int64_t fixes_ = 0, no_fixes_ = 0, skipped_pairs_ = 0;
  int64_t pairs_replaced_ = 0, pairs_after_done_ = 0, sites_dropped_ = 0, pose_sites_seen_ = 0;
  RateLimitedLog repeat_log_, after_done_log_;
  std::string last_result_ = "none yet";
};

}  // namespace vloc
