#pragma once
// LCM adapter of the feature front end: collects each site's stereo pairs
// and DR pose, runs vloc::CrossSiteFrontend when a site's imaging is done
// and the previous site is known, and publishes TIE_POINTS and
// FRONTEND_STATUS. Only the newest site pair's images are kept once it has
// been processed (for an operator's manual tie points, MANUAL_TIE_POINTS:
// OnManualTies), unless revisits are on (loop_max_distance_m > 0):
// then earlier sites go to a vloc::SiteArchive (libs/crosssite, which
// chooses the revisits), and for each revisit the front end also runs on
// (earlier, new) and publishes TIE_POINTS / FRONTEND_STATUS with
// previous_site_id = the earlier site.

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/common/image_header.h"
#include "vloc/crosssite/frontend.h"
#include "vloc/crosssite/site_archive.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"

namespace vloc {

class OptionsReader;

struct FeatureFrontendProcOptions {
  std::string stereo_channel = "NAVCAM_STEREO";       // subscribed: stereo_image_t
  std::string site_channel = "ROVER_SITE";            // subscribed: site_event_t
  std::string dr_channel = "SITE_POSE_DR";            // subscribed: site_pose_t (dead reckoning)
  std::string tie_points_channel = "TIE_POINTS";      // published: tie_points_t
  std::string status_channel = "FRONTEND_STATUS";     // published: frontend_status_t
  int queue_capacity = 64;                            // stereo pairs (about 2 MB each) queued while a pair is matched
  bool publish_unusable = false;                      // publish TIE_POINTS also when the status is not OK
  NavcamModel navcam;                                 // calibration (include ../navcam.yaml)
  FrontendOptions frontend;                           // the pipeline
  std::string traverse_channel = "TRAVERSE";          // subscribed: traverse_t, optimised poses for revisits (empty = none)
  double loop_max_distance_m = 0.0;                   // m, revisit when this close to an earlier site (0 = off)
  int loop_min_site_gap = 3;                          // the earlier site is at least this many ids back (>= 2)
  int loop_max_matches = 1;                           // earlier sites matched per new site, nearest first
  double loop_max_position_sigma_fraction = 3.0;      // regions.max_position_sigma_fraction of the revisit front end
  int max_sites_in_memory = 3;                        // earlier sites whose images stay in memory for revisits
  std::string site_cache_dir;                         // older sites' images go here (PNG); empty = dropped
  std::string manual_ties_channel = "MANUAL_TIE_POINTS";  // subscribed: manual_tie_points_t (operator's clicks; "" = off)
  int max_pairs_per_site = 32;                        // a pair saying more pairs than this is refused, IMAGING_DONE's
                                                      // count capped (a full 360 x 3-tier panorama is about 30)
  int max_sites_collecting = 8;                       // sites waiting for their images at once; beyond, the oldest goes
  ImageLimits stereo_image_limits = NavcamImageLimits();  // stereo_channel's PNG/JPEG images: larger refused before decoding

  // 4096 x 4096 px (a Navcam image is 1024 x 1024), 100 JPEG scans.
  static ImageLimits NavcamImageLimits() { return ImageLimits{4096, 4096, int64_t(4096) * 4096, 100}; }

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// The revisit options of the process options.
RevisitOptions RevisitOptionsOf(const FeatureFrontendProcOptions& options);

class FeatureFrontendAdapter {
 public:
  FeatureFrontendAdapter(const FeatureFrontendProcOptions& options, Transport& transport);

  // Subscribes the three input channels.
  void Subscribe();

  void OnStereo(const StereoPair& pair);
  void OnSiteEvent(const SiteEvent& event);
  void OnSitePoseDr(int site_id, const PoseWithCovariance& world_from_body);
  // The pose graph's optimised poses (all sites of one TRAVERSE message).
  void OnTraverse(std::map<int, PoseWithCovariance> optimised);
  // An operator's clicks for a site pair whose images are still kept (the
  // newest two sites, or archived ones): refined (CrossSiteFrontend::RunManual)
  // and published as TIE_POINTS + FRONTEND_STATUS; else FRONTEND_STATUS
  // MISSING_INPUT saying why.
  void OnManualTies(int previous_site_id, int current_site_id, const std::vector<ManualTie>& ties, int64_t utime);
  int manual_published() const { return manual_published_; }

  int loops_tried() const { return loops_tried_; }
  int loops_published() const { return loops_published_; }

  int sites_processed() const { return sites_processed_; }
  int sites_dropped() const { return sites_dropped_; }
  // Sites matched and what the subscriptions received, for the closing log line.
  std::string StatusLine() const;
  std::optional<int> previous_site_id() const;

 private:
  struct Collecting {
    std::map<int, StereoPair> pairs;  // by pair_index
    int num_pairs = 0;                // expected (from the pairs or IMAGING_DONE)
    bool imaging_done = false;
    std::optional<PoseWithCovariance> dr_pose;
  };
  bool Complete(const Collecting& c) const;
  // "k of n pairs (missing i, j), with/no dead-reckoning pose".
  static std::string DescribeInput(const Collecting& c);
  // Logs why the site is dropped and publishes FRONTEND_STATUS MISSING_INPUT naming what is missing.
  void ReportDropped(int site_id, const Collecting& c, const std::string& why);
  void TryProcess();
  void Process(int site_id, Collecting& site);
  void TryRevisits(const SiteImages& current);
  // The images of `site_id` if still kept (newest two sites, or the archive).
  std::optional<SiteImages> KeptSite(int site_id);
  void RunPair(const CrossSiteFrontend& frontend, const SiteImages& previous, const SiteImages& current,
               const char* what);

  FeatureFrontendProcOptions options_;
  Transport& transport_;
  CrossSiteFrontend frontend_;
  CrossSiteFrontend loop_frontend_;  // regions allowed to grow more (graph-predicted revisits)
  std::map<int, Collecting> collecting_;
  static constexpr int kSmallMessageQueue = 1000;  // site events, DR poses, traverses: small, and none may be lost
  std::optional<SiteImages> previous_;
  std::optional<SiteImages> before_previous_;          // the site before previous_ (manual tie points), revisits off
  SiteArchive archive_;                                // sites before previous_, poses (revisits on)
  int sites_processed_ = 0, loops_tried_ = 0, loops_published_ = 0;
  int manual_published_ = 0;               // manual tie-point sets published as TIE_POINTS
  int sites_dropped_ = 0;                  // incomplete sites reported MISSING_INPUT and dropped
  std::vector<std::shared_ptr<SubscriptionStats>> stats_;
};

}  // namespace vloc
