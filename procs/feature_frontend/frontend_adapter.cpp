#include "frontend_adapter.h"

#include <glog/logging.h>

#include <algorithm>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_image.h"
#include "vloc/lcm_io/convert_frontend.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/manual_tie_points_t.hpp"
#include "vloc/site_event_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/tie_points_t.hpp"
#include "vloc/traverse_t.hpp"

namespace vloc {

void FeatureFrontendProcOptions::Visit(OptionsReader& r) {
  r.Optional("stereo_channel", &stereo_channel, "subscribed stereo_image_t channel", NonEmpty());
  r.Optional("site_channel", &site_channel, "subscribed site_event_t channel", NonEmpty());
  r.Optional("dr_channel", &dr_channel, "subscribed dead-reckoning site_pose_t channel", NonEmpty());
  r.Optional("tie_points_channel", &tie_points_channel, "published tie_points_t channel", NonEmpty());
  r.Optional("status_channel", &status_channel, "published frontend_status_t channel", NonEmpty());
  r.Optional("queue_capacity", &queue_capacity, "messages queued per subscription", AtLeast(1));
  r.Optional("publish_unusable", &publish_unusable, "publish tie points also when the status is not OK");
  r.Child("navcam", [&](OptionsReader& c) { navcam.Visit(c); });
  r.Child("frontend", [&](OptionsReader& c) { frontend.Visit(c); });
  r.Optional("traverse_channel", &traverse_channel, "subscribed traverse_t channel (optimised poses), empty = none");
  r.Optional("loop_max_distance_m", &loop_max_distance_m,
             "m, also match a new site against an earlier site this close (0 = off)", NonNegative());
  r.Optional("loop_min_site_gap", &loop_min_site_gap,
             "revisited site at least this many ids back (adjacent sites are matched anyway)", AtLeast(2));
  r.Optional("loop_max_matches", &loop_max_matches, "earlier sites matched per new site, nearest first", AtLeast(1));
  r.Optional("loop_max_position_sigma_fraction", &loop_max_position_sigma_fraction,
             "regions.max_position_sigma_fraction of the revisit front end", Positive());
  r.Optional("max_sites_in_memory", &max_sites_in_memory, "earlier sites whose images stay in memory", NonNegative());
  r.Optional("site_cache_dir", &site_cache_dir, "older sites' images are written here (PNG); empty = dropped");
  r.Optional("manual_ties_channel", &manual_ties_channel, "subscribed manual_tie_points_t channel (\"\" = off)");
  r.Optional("max_pairs_per_site", &max_pairs_per_site, "a site's num_pairs above this is refused",
             InRange(1, kMaxPairsPerSite));
  r.Optional("max_sites_collecting", &max_sites_collecting, "sites collecting images at once; beyond, the oldest goes",
             AtLeast(1));
  r.Child("stereo_image_limits", [&](OptionsReader& c) { stereo_image_limits.Visit(c); });
}

bool FeatureFrontendProcOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {

FrontendOptions LoopFrontendOptions(const FeatureFrontendProcOptions& o) {
  FrontendOptions f = o.frontend;
  f.regions.max_position_sigma_fraction = o.loop_max_position_sigma_fraction;
  return f;
}

}  // namespace

RevisitOptions RevisitOptionsOf(const FeatureFrontendProcOptions& o) {
  return RevisitOptions{o.loop_max_distance_m, o.loop_min_site_gap, o.loop_max_matches, o.max_sites_in_memory,
                        o.site_cache_dir};
}

FeatureFrontendAdapter::FeatureFrontendAdapter(const FeatureFrontendProcOptions& options, Transport& transport)
    : options_(options),
      transport_(transport),
      frontend_(options.navcam, options.frontend),
      loop_frontend_(options.navcam, LoopFrontendOptions(options)),
      archive_(RevisitOptionsOf(options)) {}

void FeatureFrontendAdapter::Subscribe() {
  stats_.push_back(vloc::Subscribe<stereo_image_t>(
      transport_, options_.stereo_channel,
      [this](const std::string&, const stereo_image_t& m) {
        // Colour pairs arrive grey here (BGR -> luminance, the conversion
        // CrossSiteFrontend's Prepare applies to colour): the front end matches
        // on luminance only and publishes no image, so colour would triple the
        // memory of the collecting sites and the site cache without changing a
        // tie point.
        OnStereo(StereoPairFromMessage(m, options_.stereo_image_limits));
      },
      options_.queue_capacity));
  stats_.push_back(vloc::Subscribe<site_event_t>(
      transport_, options_.site_channel,
      [this](const std::string&, const site_event_t& m) { OnSiteEvent(SiteEventFromMessage(m)); },
      kSmallMessageQueue));
  stats_.push_back(vloc::Subscribe<site_pose_t>(
      transport_, options_.dr_channel,
      [this](const std::string&, const site_pose_t& m) {
        if (m.source != site_pose_t::SOURCE_DEAD_RECKONING) {
          LOG(WARNING) << options_.dr_channel << ": site " << m.site_id << " pose has source " << int(m.source)
                       << ", not dead reckoning; used anyway";
        }
        OnSitePoseDr(m.site_id, PoseFromMessage(m.pose));
      },
      kSmallMessageQueue));
  if (options_.loop_max_distance_m > 0 && !options_.traverse_channel.empty())
    stats_.push_back(vloc::Subscribe<traverse_t>(
        transport_, options_.traverse_channel,
        [this](const std::string&, const traverse_t& m) {
          std::map<int, PoseWithCovariance> poses;
          for (int i = 0; i < m.num_sites && i < static_cast<int>(m.poses.size()); ++i)
            poses[m.site_ids[i]] = PoseFromMessage(m.poses[i]);
          OnTraverse(std::move(poses));
        },
        kSmallMessageQueue));
  if (!options_.manual_ties_channel.empty())
    stats_.push_back(vloc::Subscribe<manual_tie_points_t>(
        transport_, options_.manual_ties_channel,
        [this](const std::string&, const manual_tie_points_t& m) {
          LOG(INFO) << "manual tie points from " << m.source << ": " << m.num_points << " for sites "
                    << m.previous_site_id << " -> " << m.current_site_id;
          OnManualTies(m.previous_site_id, m.current_site_id, ManualTiesFromMessage(m), m.utime);
        },
        kSmallMessageQueue));
}

std::optional<SiteImages> FeatureFrontendAdapter::KeptSite(int site_id) {
  if (previous_ && previous_->site_id == site_id) return previous_;
  if (before_previous_ && before_previous_->site_id == site_id) return before_previous_;
  if (options_.loop_max_distance_m > 0) return archive_.Restore(site_id);
  return std::nullopt;
}

void FeatureFrontendAdapter::OnManualTies(int previous_site_id, int current_site_id, const std::vector<ManualTie>& ties,
                                          int64_t utime) {
  std::optional<SiteImages> previous = KeptSite(previous_site_id), current = KeptSite(current_site_id);
  if (!previous || !current) {
    FrontendSummary summary;
    summary.status = FrontendStatus::kMissingInput;
    summary.message = "manual tie points for sites " + std::to_string(previous_site_id) + " -> " +
                      std::to_string(current_site_id) + ": the images of site " +
                      std::to_string(previous ? current_site_id : previous_site_id) +
                      " are no longer kept (only the newest two sites are, unless revisits are on)";
    LOG(WARNING) << summary.message;
    Publish(transport_, options_.status_channel,
            FrontendStatusToMessage(summary, utime, previous_site_id, current_site_id));
    return;
  }
  const FrontendResult r = frontend_.RunManual(*previous, *current, ties);
  LOG(INFO) << "manual sites " << previous_site_id << " -> " << current_site_id << ": " << r.summary.BriefReport();
  if (r.summary.IsUsable()) {
    Publish(transport_, options_.tie_points_channel, TiePointsToMessage(r.tie_points));
    ++manual_published_;
  }
  Publish(transport_, options_.status_channel,
          FrontendStatusToMessage(r.summary, r.tie_points.utime, previous_site_id, current_site_id));
}

void FeatureFrontendAdapter::OnTraverse(std::map<int, PoseWithCovariance> optimised) {
  archive_.SetOptimised(std::move(optimised));
}

std::optional<int> FeatureFrontendAdapter::previous_site_id() const {
  if (!previous_) return std::nullopt;
  return previous_->site_id;
}

void FeatureFrontendAdapter::OnStereo(const StereoPair& pair) {
  if (previous_ && pair.site_id <= previous_->site_id) {
    LOG(WARNING) << "stereo pair " << pair.pair_index << " of site " << pair.site_id
                 << " arrived after that site was processed; ignored";
    return;
  }
  if (pair.num_pairs > options_.max_pairs_per_site)
    throw std::invalid_argument("stereo pair " + std::to_string(pair.pair_index) + " of site " +
                                std::to_string(pair.site_id) + " says " + std::to_string(pair.num_pairs) +
                                " pairs, more than max_pairs_per_site " + std::to_string(options_.max_pairs_per_site));
  Collecting& c = collecting_[pair.site_id];
  c.pairs[pair.pair_index] = pair;  // a repeated pair replaces the earlier copy
  c.num_pairs = std::max(c.num_pairs, pair.num_pairs);
  TryProcess();
}

void FeatureFrontendAdapter::OnSiteEvent(const SiteEvent& event) {
  if (event.event != SiteEventType::kImagingDone) return;
  if (previous_ && event.site_id <= previous_->site_id) return;
  Collecting& c = collecting_[event.site_id];
  c.imaging_done = true;
  if (event.num_pairs > 0) c.num_pairs = std::min(event.num_pairs, options_.max_pairs_per_site);
  TryProcess();
}

void FeatureFrontendAdapter::OnSitePoseDr(int site_id, const PoseWithCovariance& world_from_body) {
  if (site_id < 0) throw std::invalid_argument("dead-reckoning pose of a negative site id " + std::to_string(site_id));
  if (previous_ && site_id <= previous_->site_id) return;
  collecting_[site_id].dr_pose = world_from_body;
  TryProcess();
}

std::string FeatureFrontendAdapter::DescribeInput(const Collecting& c) {
  std::ostringstream out;
  out << c.pairs.size() << " of " << (c.num_pairs > 0 ? std::to_string(c.num_pairs) : std::string("?")) << " pairs";
  std::string missing;
  for (int i = 0; i < c.num_pairs && i < kMaxPairsPerSite; ++i)
    if (!c.pairs.count(i)) missing += (missing.empty() ? "" : ", ") + std::to_string(i);
  if (!missing.empty()) out << " (missing " << missing << ")";
  out << ", " << (c.dr_pose ? "with" : "no") << " dead-reckoning pose";
  return out.str();
}

void FeatureFrontendAdapter::ReportDropped(int site_id, const Collecting& c, const std::string& why) {
  const std::string message = "site " + std::to_string(site_id) + ": " + DescribeInput(c) + "; " + why + "; dropped";
  LOG(WARNING) << message;
  ++sites_dropped_;
  FrontendSummary summary;
  summary.status = FrontendStatus::kMissingInput;
  summary.message = message;
  const int64_t utime = c.pairs.empty() ? 0 : c.pairs.rbegin()->second.utime;
  Publish(transport_, options_.status_channel,
          FrontendStatusToMessage(summary, utime, previous_ ? previous_->site_id : -1, site_id));
}

bool FeatureFrontendAdapter::Complete(const Collecting& c) const {
  if (!c.dr_pose || c.pairs.empty()) return false;
  return c.imaging_done || (c.num_pairs > 0 && static_cast<int>(c.pairs.size()) >= c.num_pairs);
}

void FeatureFrontendAdapter::TryProcess() {
  // Sites in order; a site waits for the ones before it, until a later site
  // is complete: then an earlier incomplete one never will be (its DR pose
  // or images were lost, or its id was corrupt) and is dropped.
  while (!collecting_.empty()) {
    auto it = collecting_.begin();
    if (it->second.imaging_done && it->second.pairs.empty() && std::next(it) != collecting_.end()) {
      // Imaging is done, the rover has moved on to a later site, and not one pair came (lost on the link, or a
      // camera fault): nothing will complete it.
      ReportDropped(it->first, it->second, "imaging done but none of its images arrived before site " +
                                               std::to_string(std::next(it)->first) + " began");
      collecting_.erase(it);
      continue;
    }
    if (!Complete(it->second)) {
      const auto later = std::find_if(std::next(it), collecting_.end(),
                                      [this](const auto& kv) { return Complete(kv.second); });
      if (later == collecting_.end() && static_cast<int>(collecting_.size()) <= options_.max_sites_collecting) return;
      ReportDropped(it->first, it->second,
                    later == collecting_.end() ? "too many sites wait"
                                               : "incomplete while site " + std::to_string(later->first) + " is complete");
      collecting_.erase(it);
      continue;
    }
    const int site_id = it->first;
    Collecting site = std::move(it->second);
    collecting_.erase(it);
    Process(site_id, site);
  }
}

void FeatureFrontendAdapter::Process(int site_id, Collecting& c) {
  SiteImages site;
  site.site_id = site_id;
  site.world_from_body = *c.dr_pose;
  for (auto& [index, pair] : c.pairs) site.pairs.push_back(std::move(pair));
  if (c.num_pairs > 0 && static_cast<int>(site.pairs.size()) < c.num_pairs)
    LOG(WARNING) << "site " << site_id << ": imaging done with " << DescribeInput(c) << "; using what arrived";
  if (!previous_) {
    LOG(INFO) << "site " << site_id << ": first site (" << site.pairs.size()
              << " pairs) kept as the previous site; nothing to match yet";
    previous_ = std::move(site);
    return;
  }
  RunPair(frontend_, *previous_, site, "sites");
  ++sites_processed_;
  archive_.SetDrPose(previous_->site_id, previous_->world_from_body);
  archive_.SetDrPose(site_id, site.world_from_body);
  if (options_.loop_max_distance_m > 0) {
    TryRevisits(site);
    archive_.Add(std::move(*previous_));
  } else {
    before_previous_ = std::move(previous_);
  }
  previous_ = std::move(site);  // without revisits the site before before_previous_ is released here
}

void FeatureFrontendAdapter::RunPair(const CrossSiteFrontend& frontend, const SiteImages& previous,
                                     const SiteImages& current, const char* what) {
  const FrontendResult r = frontend.Run(previous, current);
  LOG(INFO) << what << " " << previous.site_id << " -> " << current.site_id << ": " << r.summary.BriefReport();
  const bool publish = r.summary.IsUsable() || (options_.publish_unusable && !r.tie_points.points.empty());
  if (publish) Publish(transport_, options_.tie_points_channel, TiePointsToMessage(r.tie_points));
  if (publish && current.site_id - previous.site_id > 1) ++loops_published_;
  Publish(transport_, options_.status_channel,
          FrontendStatusToMessage(r.summary, r.tie_points.utime, previous.site_id, current.site_id));
}

void FeatureFrontendAdapter::TryRevisits(const SiteImages& current) {
  const auto here = archive_.BestPose(current.site_id);
  if (!here) return;
  for (const Revisit& r : archive_.ChooseRevisits(current.site_id)) {
    std::optional<SiteImages> earlier = archive_.Restore(r.site_id);
    if (!earlier) {
      LOG(INFO) << "site " << current.site_id << " is " << r.distance_m << " m from site " << r.site_id
                << " but that site's images are no longer kept (set site_cache_dir); not revisited";
      continue;
    }
    ++loops_tried_;
    LOG(INFO) << "site " << current.site_id << ": revisit of site " << r.site_id << " (" << r.distance_m
              << " m apart, poses from " << (r.pose_from_graph ? "the pose graph" : "dead reckoning") << ")";
    earlier->world_from_body = *archive_.BestPose(r.site_id);
    SiteImages now;
    now.site_id = current.site_id;
    now.world_from_body = *here;
    now.pairs = current.pairs;  // shared image buffers
    RunPair(loop_frontend_, *earlier, now, "revisit");
  }
}

std::string FeatureFrontendAdapter::StatusLine() const {
  return "site pairs matched " + std::to_string(sites_processed_) + ", incomplete sites dropped " +
         std::to_string(sites_dropped_) + ", revisits published " +
         std::to_string(loops_published_) + ", manual tie sets published " + std::to_string(manual_published_) + "; " +
         SubscriptionSummary(stats_);
}

}  // namespace vloc
