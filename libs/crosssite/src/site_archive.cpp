#include "vloc/crosssite/site_archive.h"

#include <algorithm>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include <glog/logging.h>

namespace vloc {

SiteArchive::SiteArchive(RevisitOptions options) : options_(std::move(options)) {
  if (options_.max_distance_m > 0 && !options_.cache_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options_.cache_dir, ec);
    if (ec)
      LOG(ERROR) << "site_cache_dir " << options_.cache_dir << ": " << ec.message()
                 << "; older sites cannot be revisited (fix the path or its permissions)";
  }
}

std::string SiteArchive::CachePath(int site, int pair, const char* side) const {
  return options_.cache_dir + "/site" + std::to_string(site) + "_pair" + std::to_string(pair) + "_" + side + ".png";
}

void SiteArchive::SetDrPose(int site_id, const PoseWithCovariance& world_from_body) { dr_[site_id] = world_from_body; }

void SiteArchive::SetOptimised(std::map<int, PoseWithCovariance> world_from_body) {
  optimised_ = std::move(world_from_body);
}

void SiteArchive::Add(SiteImages site) {
  Archived& a = archive_[site.site_id];
  a.dr = site.world_from_body;
  a.pairs = std::move(site.pairs);
  // Older sites leave memory: to the cache folder, or gone (index kept).
  int in_memory = 0;
  for (auto it = archive_.rbegin(); it != archive_.rend(); ++it) {
    Archived& old = it->second;
    if (old.pairs.empty()) continue;
    if (++in_memory <= options_.max_sites_in_memory) continue;
    bool written = !options_.cache_dir.empty();
    for (const StereoPair& p : old.pairs) {
      if (!written) break;
      written = cv::imwrite(CachePath(p.site_id, p.pair_index, "left"), p.left) &&
                cv::imwrite(CachePath(p.site_id, p.pair_index, "right"), p.right);
    }
    if (written) {
      old.meta = old.pairs;
      for (StereoPair& m : old.meta) m.left = m.right = cv::Mat();
      old.on_disk = true;
    } else if (!options_.cache_dir.empty()) {
      LOG(ERROR) << "cannot write site " << it->first << "'s images to " << options_.cache_dir
                 << "; that site cannot be revisited (check the folder and free space)";
    }
    old.pairs.clear();
  }
}

std::optional<SiteImages> SiteArchive::Restore(int site_id) const {
  const auto it = archive_.find(site_id);
  if (it == archive_.end()) return std::nullopt;
  SiteImages s;
  s.site_id = site_id;
  s.world_from_body = it->second.dr;
  if (!it->second.pairs.empty()) {
    s.pairs = it->second.pairs;  // cv::Mat headers: shared, not copied
    return s;
  }
  if (!it->second.on_disk) return std::nullopt;
  for (StereoPair p : it->second.meta) {
    p.left = cv::imread(CachePath(site_id, p.pair_index, "left"), cv::IMREAD_UNCHANGED);
    p.right = cv::imread(CachePath(site_id, p.pair_index, "right"), cv::IMREAD_UNCHANGED);
    if (p.left.empty() || p.right.empty()) {
      LOG(ERROR) << "site " << site_id << " pair " << p.pair_index << ": cached images missing in "
                 << options_.cache_dir << "; not revisited";
      return std::nullopt;
    }
    s.pairs.push_back(std::move(p));
  }
  return s;
}

std::optional<PoseWithCovariance> SiteArchive::BestPose(int site_id) const {
  if (const auto it = optimised_.find(site_id); it != optimised_.end()) return it->second;
  const auto dr = dr_.find(site_id);
  if (dr == dr_.end()) return std::nullopt;
  // The newest earlier site the graph has, carried forward by dead reckoning.
  for (auto it = optimised_.rbegin(); it != optimised_.rend(); ++it) {
    if (it->first >= site_id) continue;
    const auto base = dr_.find(it->first);
    if (base == dr_.end()) continue;
    PoseWithCovariance p;
    p.utime = dr->second.utime;
    p.pose = it->second.pose * base->second.pose.inverse() * dr->second.pose;
    const Matrix6d growth = dr->second.covariance - base->second.covariance;
    p.covariance = it->second.covariance;
    for (int k = 0; k < 6; ++k) p.covariance(k, k) += std::max(growth(k, k), 0.0);
    return p;
  }
  return dr->second;
}

std::vector<Revisit> SiteArchive::ChooseRevisits(int current_site_id) const {
  std::vector<Revisit> out;
  if (options_.max_distance_m <= 0) return out;
  const auto here = BestPose(current_site_id);
  if (!here) return out;
  std::vector<std::pair<double, int>> candidates;  // distance, site
  for (const auto& [id, a] : archive_) {
    if (current_site_id - id < options_.min_site_gap) continue;
    const auto there = BestPose(id);
    if (!there) continue;
    const double d = (there->pose.translation() - here->pose.translation()).head<2>().norm();
    if (d <= options_.max_distance_m) candidates.emplace_back(d, id);
  }
  std::sort(candidates.begin(), candidates.end());
  if (candidates.size() > static_cast<size_t>(options_.max_matches))
    candidates.resize(static_cast<size_t>(options_.max_matches));
  for (const auto& [d, id] : candidates) out.push_back({id, d, optimised_.count(id) > 0});
  return out;
}

}  // namespace vloc
