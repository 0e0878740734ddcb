#pragma once
// LCM side of the cross-site bundle adjustment: TIE_POINTS (tie_points_t)
// and SITE_POSE_DR (site_pose_t) in, SITE_POSE_VISUAL (localization_t) out.
//
// The chain of sites: the previous site's pose held fixed is this process's
// own latest estimate of that site (the BA result, or the chained dead
// reckoning when the BA failed there) when it has one, else the pose in the
// tie-point message. The initial value of the current site is that
// previous pose composed with the dead-reckoning motion between the two
// sites (from SITE_POSE_DR of both sites when received, else from the
// message's two poses; for a revisit, a non-adjacent pair, always the
// message's poses: feature_frontend sets them from the pose graph). On failure the published pose is that chained
// dead-reckoning pose with the current site's DR covariance. Both maps keep
// the newest site_window sites only (a flood of site ids stays bounded).

#include <map>
#include <memory>
#include <string>

#include "vloc/ba/crosssite_ba.h"
#include "vloc/common/camera.h"
#include "vloc/lcm_io/rate_limited_log.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/tie_points_t.hpp"

namespace vloc {

struct CrossSiteBaProcOptions {
  std::string navcam_config = "config/navcam.yaml";     // Navcam calibration (rig + mast)
  std::string tie_points_channel = "TIE_POINTS";         // tie_points_t in
  std::string dr_channel = "SITE_POSE_DR";               // site_pose_t in
  std::string visual_channel = "SITE_POSE_VISUAL";       // localization_t out
  bool chain_previous = true;                            // hold the previous site at our own estimate (see above)
  int queue_capacity = 1000;                             // messages per subscription queue (tie points queue while a BA solves)
  std::string state_path = "crosssite_ba.state";         // site estimates kept across restarts; relative = in --state-dir
                                                         // or $VLOC_LOG_DIR; "" = none
  int site_window = 1000;                                // sites whose DR pose and estimate are kept (newest ids;
                                                         // older revisits take the message's poses)
  CrossSiteBaOptions ba;                                 // the adjustment (map `ba`)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

class CrossSiteBaAdapter {
 public:
  CrossSiteBaAdapter(Transport& transport, const CrossSiteBaProcOptions& options, const NavcamModel& navcam);
  int64_t solved() const { return solved_; }
  int64_t failed() const { return failed_; }
  std::string StatusLine() const;

  // Reloads the site estimates and DR poses saved at `path` (resolved
  // state_path; "" = none), and saves there after every site from then on.
  // A missing file is a fresh start; an unreadable one is an error (a last
  // line cut short by a crash is dropped with a warning).
  bool Restore(const std::string& path, std::string* error);

  // Prepares the set as the chain says, solves it and remembers the result.
  CrossSiteBaSummary Process(TiePointSet set);

 private:
  // The answer to a message that cannot be converted: BAD_INPUT with the DR pose.
  CrossSiteBaSummary BadMessage(const tie_points_t& msg, const std::string& why);

  Transport& transport_;
  CrossSiteBaProcOptions options_;
  NavcamModel navcam_;
  std::map<int, PoseWithCovariance> dr_poses_;    // SITE_POSE_DR per site (newest site_window)
  std::map<int, PoseWithCovariance> estimates_;   // our latest estimate per site (newest site_window)
  void KeepWindow();
  // The state file is a journal: each new pose is appended as one line (a
  // later line for a site replaces an earlier one), and the file is rewritten
  // whole once it holds twice the lines of the state (or a new traverse
  // starts): a message costs one line, and the file at most 4 site_window + 16 lines.
  void SaveSite(const std::map<int, PoseWithCovariance>& map, int site);
  void RewriteState();

  std::string state_path_;                        // resolved; "" = state not kept
  size_t state_lines_ = 0;                        // lines in the state file
  std::shared_ptr<SubscriptionStats> tie_stats_, dr_stats_;
  int64_t solved_ = 0, failed_ = 0;
  RateLimitedLog window_log_;
};

}  // namespace vloc
