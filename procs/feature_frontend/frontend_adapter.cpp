#include "frontend_adapter.h"

#include <glog/logging.h>

#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/site_event_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/tie_points_t.hpp"

namespace vloc {

void FeatureFrontendProcOptions::Visit(OptionsReader& r) {
  r.Optional("stereo_channel", &stereo_channel, "subscribed stereo_image_t channel");
  r.Optional("site_channel", &site_channel, "subscribed site_event_t channel");
  r.Optional("dr_channel", &dr_channel, "subscribed dead-reckoning site_pose_t channel");
  r.Optional("tie_points_channel", &tie_points_channel, "published tie_points_t channel");
  r.Optional("status_channel", &status_channel, "published frontend_status_t channel");
  r.Optional("queue_capacity", &queue_capacity, "messages queued per subscription");
  r.Optional("publish_unusable", &publish_unusable, "publish tie points also when the status is not OK");
  r.Child("navcam", [&](OptionsReader& c) { navcam.Visit(c); });
  r.Child("frontend", [&](OptionsReader& c) { frontend.Visit(c); });
}

bool FeatureFrontendProcOptions::Check(std::string* error) const {
  if (stereo_channel.empty() || site_channel.empty() || dr_channel.empty() || tie_points_channel.empty() ||
      status_channel.empty())
    return Fail(error, "channel names must not be empty");
  if (queue_capacity < 1) return Fail(error, "queue_capacity must be >= 1");
  return navcam.Check(error) && frontend.Check(error);
}

frontend_status_t FrontendStatusToMessage(const FrontendSummary& s, int64_t utime, int previous_site_id,
                                          int current_site_id) {
  frontend_status_t m;
  m.utime = utime;
  m.previous_site_id = previous_site_id;
  m.current_site_id = current_site_id;
  switch (s.status) {
    case FrontendStatus::kOk: m.status = frontend_status_t::STATUS_OK; break;
    case FrontendStatus::kNoOverlap: m.status = frontend_status_t::STATUS_NO_OVERLAP; break;
    case FrontendStatus::kLowTexture: m.status = frontend_status_t::STATUS_LOW_TEXTURE; break;
    case FrontendStatus::kTooFewPoints: m.status = frontend_status_t::STATUS_TOO_FEW_POINTS; break;
    case FrontendStatus::kMissingInput: m.status = frontend_status_t::STATUS_MISSING_INPUT; break;
    case FrontendStatus::kError: m.status = frontend_status_t::STATUS_ERROR; break;
  }
  m.message = s.message;
  m.num_stages = static_cast<int32_t>(s.stages.size());
  for (const auto& st : s.stages) {
    m.stage_names.push_back(st.name);
    m.stage_counts.push_back(st.count);
    m.stage_seconds.push_back(st.seconds);
  }
  m.total_seconds = s.total_seconds;
  return m;
}

FeatureFrontendAdapter::FeatureFrontendAdapter(const FeatureFrontendProcOptions& options, Transport& transport)
    : options_(options), transport_(transport), frontend_(options.navcam, options.frontend) {}

void FeatureFrontendAdapter::Subscribe() {
  stats_.push_back(vloc::Subscribe<stereo_image_t>(
      transport_, options_.stereo_channel,
      [this](const std::string&, const stereo_image_t& m) { OnStereo(StereoPairFromMessage(m)); },
      options_.queue_capacity));
  stats_.push_back(vloc::Subscribe<site_event_t>(
      transport_, options_.site_channel,
      [this](const std::string&, const site_event_t& m) { OnSiteEvent(SiteEventFromMessage(m)); },
      options_.queue_capacity));
  stats_.push_back(vloc::Subscribe<site_pose_t>(
      transport_, options_.dr_channel,
      [this](const std::string&, const site_pose_t& m) {
        if (m.source != site_pose_t::SOURCE_DEAD_RECKONING) {
          LOG(WARNING) << options_.dr_channel << ": site " << m.site_id << " pose has source " << int(m.source)
                       << ", not dead reckoning; used anyway";
        }
        OnSitePoseDr(m.site_id, PoseFromMessage(m.pose));
      },
      options_.queue_capacity));
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
  Collecting& c = collecting_[pair.site_id];
  c.pairs[pair.pair_index] = pair;
  c.num_pairs = std::max(c.num_pairs, pair.num_pairs);
  TryProcess();
}

void FeatureFrontendAdapter::OnSiteEvent(const SiteEvent& event) {
  if (event.event != SiteEventType::kImagingDone) return;
  if (previous_ && event.site_id <= previous_->site_id) return;
  Collecting& c = collecting_[event.site_id];
  c.imaging_done = true;
  if (event.num_pairs > 0) c.num_pairs = event.num_pairs;
  TryProcess();
}

void FeatureFrontendAdapter::OnSitePoseDr(int site_id, const PoseWithCovariance& world_from_body) {
  if (previous_ && site_id <= previous_->site_id) return;
  collecting_[site_id].dr_pose = world_from_body;
  TryProcess();
}

bool FeatureFrontendAdapter::Complete(const Collecting& c) const {
  if (!c.dr_pose || c.pairs.empty()) return false;
  return c.imaging_done || (c.num_pairs > 0 && static_cast<int>(c.pairs.size()) >= c.num_pairs);
}

void FeatureFrontendAdapter::TryProcess() {
  // Sites in order; a site waits for the ones before it.
  while (!collecting_.empty()) {
    auto it = collecting_.begin();
    if (!Complete(it->second)) return;
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
    LOG(WARNING) << "site " << site_id << ": imaging done with " << site.pairs.size() << " of " << c.num_pairs
                 << " pairs; using what arrived";
  if (!previous_) {
    LOG(INFO) << "site " << site_id << ": first site (" << site.pairs.size()
              << " pairs) kept as the previous site; nothing to match yet";
    previous_ = std::move(site);
    return;
  }
  const FrontendResult r = frontend_.Run(*previous_, site);
  ++sites_processed_;
  LOG(INFO) << "sites " << previous_->site_id << " -> " << site_id << ": " << r.summary.BriefReport();
  if (r.summary.IsUsable() || (options_.publish_unusable && !r.tie_points.points.empty())) {
    Publish(transport_, options_.tie_points_channel, TiePointsToMessage(r.tie_points));
  }
  Publish(transport_, options_.status_channel,
          FrontendStatusToMessage(r.summary, r.tie_points.utime, previous_->site_id, site_id));
  previous_ = std::move(site);  // the older site's images are released here
}

}  // namespace vloc
