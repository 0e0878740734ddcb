#pragma once
// Earlier sites for revisits (loop closure), as the feature front end's
// process keeps them: every processed site's DR pose, the images of the
// newest `max_sites_in_memory` archived sites in memory, older ones written
// to `cache_dir` (PNG) when it is set, else dropped (the index stays). A new
// site is matched against an archived site at least `min_site_gap` ids back
// whose best pose lies within `max_distance_m` (horizontal), nearest first.
// Best pose: the pose graph's optimised pose when it has the site, else the
// newest optimised earlier site chained with dead reckoning, else dead
// reckoning (the graph's poses predict a revisit far better than DR).
// No LCM here: the process's adapter feeds it and publishes the results.

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/pose.h"
#include "vloc/crosssite/frontend.h"

namespace vloc {

struct RevisitOptions {
  double max_distance_m = 0.0;   // m, revisit an earlier site this close (horizontal); 0 = no revisits
  int min_site_gap = 3;          // the earlier site is at least this many ids back
  int max_matches = 1;           // earlier sites matched per new site, nearest first
  int max_sites_in_memory = 3;   // archived sites whose images stay in memory
  std::string cache_dir;         // older sites' images go here (PNG); empty = dropped
};

// An earlier site chosen for a revisit.
struct Revisit {
  int site_id = 0;
  double distance_m = 0;         // m, horizontal, between the two best poses
  bool pose_from_graph = false;  // the earlier site's pose is the pose graph's (else dead reckoning)
};

class SiteArchive {
 public:
  // Creates cache_dir when revisits are on (logs an error if it cannot).
  explicit SiteArchive(RevisitOptions options);

  // The DR pose of a processed site.
  void SetDrPose(int site_id, const PoseWithCovariance& world_from_body);
  // The pose graph's optimised poses (replaces the previous set).
  void SetOptimised(std::map<int, PoseWithCovariance> world_from_body);
  // Archives a site's images, then moves the older ones out of memory.
  void Add(SiteImages site);
  // An archived site with its images (from memory or the cache), its pose
  // the archived DR pose; nullopt when unknown or its images are gone.
  std::optional<SiteImages> Restore(int site_id) const;
  // The best pose of a site (see above); nullopt when its DR pose is unknown.
  std::optional<PoseWithCovariance> BestPose(int site_id) const;
  // The archived sites to match the site `current_site_id` against.
  std::vector<Revisit> ChooseRevisits(int current_site_id) const;

  const RevisitOptions& options() const { return options_; }

 private:
  struct Archived {
    PoseWithCovariance dr;
    std::vector<StereoPair> pairs;  // in memory (empty when cached on disk or dropped)
    std::vector<StereoPair> meta;   // pair metadata without images, when on disk
    bool on_disk = false;
  };
  std::string CachePath(int site, int pair, const char* side) const;

  RevisitOptions options_;
  std::map<int, Archived> archive_;
  std::map<int, PoseWithCovariance> dr_;         // DR pose of every processed site
  std::map<int, PoseWithCovariance> optimised_;  // the pose graph's last poses
};

}  // namespace vloc
