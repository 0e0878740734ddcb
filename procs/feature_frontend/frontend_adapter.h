#pragma once
// LCM adapter of the feature front end: collects each site's stereo pairs
// and DR pose, runs vloc::CrossSiteFrontend when a site's imaging is done
// and the previous site is known, and publishes TIE_POINTS and
// FRONTEND_STATUS. Only the previous site's images are kept once a site
// pair has been processed.

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/crosssite/frontend.h"
#include "vloc/frontend_status_t.hpp"
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
  int queue_capacity = 64;                            // messages queued per subscription
  bool publish_unusable = false;                      // publish TIE_POINTS also when the status is not OK
  NavcamModel navcam;                                 // calibration (include ../navcam.yaml)
  FrontendOptions frontend;                           // the pipeline

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

frontend_status_t FrontendStatusToMessage(const FrontendSummary& summary, int64_t utime, int previous_site_id,
                                          int current_site_id);

class FeatureFrontendAdapter {
 public:
  FeatureFrontendAdapter(const FeatureFrontendProcOptions& options, Transport& transport);

  // Subscribes the three input channels.
  void Subscribe();

  void OnStereo(const StereoPair& pair);
  void OnSiteEvent(const SiteEvent& event);
  void OnSitePoseDr(int site_id, const PoseWithCovariance& world_from_body);

  int sites_processed() const { return sites_processed_; }
  std::optional<int> previous_site_id() const;

 private:
  struct Collecting {
    std::map<int, StereoPair> pairs;  // by pair_index
    int num_pairs = 0;                // expected (from the pairs or IMAGING_DONE)
    bool imaging_done = false;
    std::optional<PoseWithCovariance> dr_pose;
  };
  bool Complete(const Collecting& c) const;
  void TryProcess();
  void Process(int site_id, Collecting& site);

  FeatureFrontendProcOptions options_;
  Transport& transport_;
  CrossSiteFrontend frontend_;
  std::map<int, Collecting> collecting_;
  std::optional<SiteImages> previous_;
  int sites_processed_ = 0;
  std::vector<std::shared_ptr<SubscriptionStats>> stats_;
};

}  // namespace vloc
