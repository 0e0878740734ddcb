#include "console_adapter.h"

#include <glog/logging.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "console_json.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_rover.h"
#include "vloc/stereo_image_t.hpp"

namespace vloc {

using nlohmann::json;

namespace {

// The prefixes of the picture's per-site keys (TrimSites drops a site's all).
const char* const kSiteKeys[] = {"dr", "visual", "localization", "frontend", "tie_points", "images"};

std::string SiteKey(const char* prefix, int site) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%s/%09d", prefix, site);
  return buf;
}

// The site of a per-site picture key ("<prefix>/<site>" for a prefix of kSiteKeys), -1 for any other key.
int SiteOfKey(const std::string& key) {
  for (const char* prefix : kSiteKeys) {
    const size_t n = std::strlen(prefix);
    if (key.size() > n + 1 && key.compare(0, n, prefix) == 0 && key[n] == '/') return std::atoi(key.c_str() + n + 1);
  }
  return -1;
}

int64_t WallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

json Refused(const std::string& why) { return {{"ok", false}, {"error", why}}; }

}  // namespace

void OrthoimageOptions::Visit(OptionsReader& r) {
  r.Optional("path", &path, "PNG / JPEG orthoimage under the map (\"\" = none)");
  r.Optional("x_min_m", &x_min_m, "m, world x of its west edge", Finite());
  r.Optional("y_max_m", &y_max_m, "m, world y of its north edge", Finite());
  r.Optional("m_per_px", &m_per_px, "m per pixel", InOpen(0, 1e4));
}

bool OrthoimageOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void ConsoleProcOptions::Visit(OptionsReader& r) {
  r.Child("server", [&](OptionsReader& c) { server.Visit(c); });
  r.Optional("traverse_channel", &traverse_channel, "traverse_t in", NonEmpty());
  r.Optional("dr_channel", &dr_channel, "site_pose_t in (dead reckoning)", NonEmpty());
  r.Optional("visual_channel", &visual_channel, "localization_t in (BA results)", NonEmpty());
  r.Optional("frontend_status_channel", &frontend_status_channel, "frontend_status_t in", NonEmpty());
  r.Optional("tie_points_channel", &tie_points_channel, "tie_points_t in", NonEmpty());
  r.Optional("stereo_channel", &stereo_channel, "stereo_image_t in (\"\" = no images)");
  r.Optional("procman_status_channel", &procman_status_channel, "procman_status_t in", NonEmpty());
  r.Optional("tunnel_status_channel", &tunnel_status_channel, "tunnel_status_t in (\"\" = none)");
  r.Optional("uav_state_channel", &uav_state_channel, "uav_state_t in", NonEmpty());
  r.Optional("uav_mosaic_channel", &uav_mosaic_channel, "image_t in (JPEG mosaic preview)", NonEmpty());
  r.Optional("orders_channel", &orders_channel, "procman_order_t out", NonEmpty());
  r.Optional("manual_ties_channel", &manual_ties_channel, "manual_tie_points_t out", NonEmpty());
  r.Optional("max_sites", &max_sites, "sites whose poses and statuses are kept", AtLeast(1));
  r.Optional("image_sites_kept", &image_sites_kept, "newest sites whose left images are kept", AtLeast(2));
  r.Optional("max_uav_states", &max_uav_states, "UAV states kept for the plots", AtLeast(1));
  r.Optional("max_manual_points", &max_manual_points, "picks in one manual tie-point command", AtLeast(1));
  r.Optional("tie_point_sites_kept", &tie_point_sites_kept, "newest sites whose tie points are kept", AtLeast(1));
  r.Optional("max_launchers", &max_launchers, "launchers whose process tables are kept", AtLeast(1));
  r.Optional("welcome_max_bytes", &welcome_max_bytes, "bytes a newly opened page is sent, newest sites first",
             AtLeast(65536));
  r.Child("orthoimage", [&](OptionsReader& c) { orthoimage.Visit(c); });
  r.Relation("welcome_max_bytes", welcome_max_bytes <= server.max_client_buffer_bytes / 2,
             "must be <= server.max_client_buffer_bytes / 2");
}

bool ConsoleProcOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

ConsoleAdapter::ConsoleAdapter(Transport& transport, ConsoleServer& server, const ConsoleProcOptions& options)
    : transport_(transport), server_(server), options_(options) {
  server_.SetWelcomeHandler([this] { return Welcome(); });
  server_.SetCommandHandler([this](const json& c, bool may_act) { return OnCommand(c, may_act); });
  server_.SetApiHandler([this](const std::string& rest, const std::map<std::string, std::string>& q, HttpReply* r) {
    return OnApi(rest, q, r);
  });
}

template <class Msg>
void ConsoleAdapter::Watch(const std::string& channel, std::function<void(const Msg&)> handle, int queue) {
  stats_.push_back(vloc::Subscribe<Msg>(
      transport_, channel, [handle = std::move(handle)](const std::string&, const Msg& m) { handle(m); }, queue));
}

void ConsoleAdapter::Subscribe() {
  SubscribeRover();
  SubscribeUav();
  Watch<procman_status_t>(options_.procman_status_channel, [this](const procman_status_t& m) { OnProcmanStatus(m); });
  if (!options_.tunnel_status_channel.empty())
    Watch<tunnel_status_t>(options_.tunnel_status_channel, [this](const tunnel_status_t& m) {
      Post("tunnel/" + m.name, TunnelStatusJson(m));
      KeepNewest(&tunnels_, "tunnel/", m.name, "tunnel_gone");
    });
}

void ConsoleAdapter::OnProcmanStatus(const procman_status_t& m) {
  const std::string id = m.host + ":" + std::to_string(m.launcher_pid);
  Post("procman/" + id, ProcmanJson(m));
  KeepNewest(&launchers_, "procman/", id, "procman_gone");
}

void ConsoleAdapter::KeepNewest(std::map<std::string, int64_t>* heard, const std::string& prefix,
                                const std::string& key, const char* gone_type) {
  (*heard)[key] = ++heard_;
  while (static_cast<int>(heard->size()) > options_.max_launchers) {
    const auto oldest = std::min_element(heard->begin(), heard->end(),
                                         [](const auto& a, const auto& b) { return a.second < b.second; });
    picture_.erase(prefix + oldest->first);
    server_.Broadcast(
        json{{"type", gone_type}, {"key", oldest->first}}.dump(-1, ' ', false, json::error_handler_t::replace));
    heard->erase(oldest);
  }
}

void ConsoleAdapter::SubscribeRover() {
  const ConsoleProcOptions& o = options_;
  Watch<traverse_t>(o.traverse_channel, [this](const traverse_t& m) {
    json j = TraverseJson(m);
    j["console_us"] = WallMicros();  // the page measures receipt -> drawn from it
    Post("traverse", j);
  });
  Watch<site_pose_t>(o.dr_channel, [this](const site_pose_t& m) { PostSite("dr", m.site_id, SitePoseJson(m)); });
  Watch<localization_t>(o.visual_channel, [this](const localization_t& m) { OnLocalization(m); });
  Watch<frontend_status_t>(o.frontend_status_channel, [this](const frontend_status_t& m) {
    PostSite("frontend", m.current_site_id, FrontendStatusJson(m));
  });
  Watch<tie_points_t>(o.tie_points_channel, [this](const tie_points_t& m) { OnTiePoints(m); });
  if (o.stereo_channel.empty()) return;
  Watch<stereo_image_t>(
      o.stereo_channel,
      [this](const stereo_image_t& m) {
        CheckStereoPairIndex(m);  // a pair index beyond num_pairs would add a kept image per index
        OnLeftImage(m.site_id, m.pair_index, m.left);
      },
      kStereoQueue);
}

void ConsoleAdapter::SubscribeUav() {
  Watch<uav_state_t>(options_.uav_state_channel, [this](const uav_state_t& m) {
    const std::string text = UavStateJson(m).dump();
    server_.Broadcast(text);
    uav_states_.push_back(text);
    while (static_cast<int>(uav_states_.size()) > options_.max_uav_states) uav_states_.pop_front();
  });
  Watch<image_t>(
      options_.uav_mosaic_channel,
      [this](const image_t& m) {
        if (m.encoding != image_t::ENCODING_JPEG) throw std::invalid_argument("the mosaic preview is not JPEG");
        uav_mosaic_jpeg_.assign(m.data.begin(), m.data.end());
        Post("uav_mosaic",
             {{"type", "uav_mosaic"}, {"seq", ++uav_mosaic_seq_}, {"width", m.width}, {"height", m.height}});
      },
      kMosaicQueue);
}

void ConsoleAdapter::OnLocalization(const localization_t& m) {
  PostSite("localization", m.site_id, LocalizationJson(m));
  if (m.status == localization_t::STATUS_OK)
    relative_poses_[m.site_id] = PoseFromMessage(m.relative_pose).pose;
  else
    relative_poses_.erase(m.site_id);
  RefreshTiePoints(m.site_id);
}

bool ConsoleAdapter::LoadOrthoimage(std::string* error) {
  const OrthoimageOptions& o = options_.orthoimage;
  if (o.path.empty()) return true;
  const cv::Mat image = cv::imread(o.path, cv::IMREAD_UNCHANGED);
  std::ifstream in(o.path, std::ios::binary);
  orthoimage_bytes_.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (image.empty() || orthoimage_bytes_.empty())
    return Fail(error, "orthoimage '" + o.path + "' is not a readable PNG or JPEG image (fix orthoimage.path)");
  orthoimage_type_ = orthoimage_bytes_.rfind("\x89PNG", 0) == 0 ? "image/png" : "image/jpeg";
  picture_["orthoimage"] = json{{"type", "orthoimage"},   {"x_min", o.x_min_m},  {"y_max", o.y_max_m},
                                {"m_per_px", o.m_per_px}, {"width", image.cols}, {"height", image.rows}}
                               .dump();
  return true;
}

void ConsoleAdapter::Post(const std::string& key, const json& j) {
  std::string text = j.dump(-1, ' ', false, json::error_handler_t::replace);
  server_.Broadcast(text);
  picture_[key] = std::move(text);
}

void ConsoleAdapter::PostSite(const char* prefix, int site, const json& j) {
  Post(SiteKey(prefix, site), j);
  sites_.insert(site);
  TrimSites();
}

void ConsoleAdapter::TrimSites() {
  while (static_cast<int>(sites_.size()) > options_.max_sites) {
    for (const char* prefix : kSiteKeys) picture_.erase(SiteKey(prefix, *sites_.begin()));
    sites_.erase(sites_.begin());
  }
}

void ConsoleAdapter::OnLeftImage(int site, int pair, const image_t& left) {
  if (left.width <= 0 || left.height <= 0 || left.data.empty()) throw std::invalid_argument("empty left image");
  KeptImage& kept = left_images_[site][pair];
  kept.message = left;
  kept.served.clear();
  if (left.encoding == image_t::ENCODING_PNG || left.encoding == image_t::ENCODING_JPEG) {
    kept.served.assign(left.data.begin(), left.data.end());
    kept.type = left.encoding == image_t::ENCODING_PNG ? "image/png" : "image/jpeg";
  }
  while (static_cast<int>(left_images_.size()) > options_.image_sites_kept) {
    picture_.erase(SiteKey("images", left_images_.begin()->first));
    left_images_.erase(left_images_.begin());
  }
  json pairs = json::array();
  for (const auto& [index, image] : left_images_[site])
    pairs.push_back({{"pair", index}, {"width", image.message.width}, {"height", image.message.height}});
  PostSite("images", site, {{"type", "images"}, {"site", site}, {"pairs", std::move(pairs)}});
}

void ConsoleAdapter::OnTiePoints(const tie_points_t& msg) {
  tie_points_[msg.current_site_id] = msg;
  while (static_cast<int>(tie_points_.size()) > options_.tie_point_sites_kept) {
    picture_.erase(SiteKey("tie_points", tie_points_.begin()->first));
    tie_points_.erase(tie_points_.begin());
  }
  RefreshTiePoints(msg.current_site_id);
}

void ConsoleAdapter::RefreshTiePoints(int current_site) {
  const auto it = tie_points_.find(current_site);
  if (it == tie_points_.end()) return;
  const auto rel = relative_poses_.find(current_site);
  const std::optional<Pose3> relative = rel == relative_poses_.end() ? std::nullopt : std::optional<Pose3>(rel->second);
  PostSite("tie_points", current_site, TiePointsJson(it->second, relative));
}

std::set<int> ConsoleAdapter::WelcomeSites(size_t budget) const {
  std::set<int> chosen;
  size_t used = 0;
  for (auto site = sites_.rbegin(); site != sites_.rend(); ++site) {
    size_t bytes = 0;
    for (const char* prefix : kSiteKeys)
      if (const auto it = picture_.find(SiteKey(prefix, *site)); it != picture_.end()) bytes += it->second.size();
    if (used + bytes > budget) break;
    used += bytes;
    chosen.insert(*site);
  }
  return chosen;
}

std::vector<std::string> ConsoleAdapter::Welcome() const {
  // The page's whole picture within welcome_max_bytes: what is not per site
  // first, the UAV history (newest states), then the newest sites.
  size_t budget = static_cast<size_t>(options_.welcome_max_bytes);
  for (const auto& [key, text] : picture_)
    if (SiteOfKey(key) < 0) budget -= std::min(budget, text.size());
  size_t first = uav_states_.size(), history_bytes = 0;  // the newest states within half the budget
  while (first > 0 && history_bytes + uav_states_[first - 1].size() + 1 < budget / 2)
    history_bytes += uav_states_[--first].size() + 1;
  const size_t states = uav_states_.size() - first;
  std::string history;
  history.reserve(history_bytes);
  for (size_t i = first; i < uav_states_.size(); ++i) history += (i > first ? "," : "") + uav_states_[i];
  budget -= std::min(budget, history.size());
  const std::set<int> sites = WelcomeSites(budget);
  std::vector<std::string> out;
  out.push_back(json{{"type", "hello"},
                     {"uav_states", states},
                     {"sites", sites.size()},
                     {"sites_not_sent", sites_.size() - sites.size()}}
                    .dump());
  for (const auto& [key, text] : picture_) {
    const int site = SiteOfKey(key);
    if (site < 0 || sites.count(site)) out.push_back(text);
  }
  if (states) out.push_back("{\"type\":\"uav_history\",\"states\":[" + history + "]}");
  return out;
}

json ConsoleAdapter::OnCommand(const json& command, bool may_act) {
  const std::string type = command.value("type", std::string());
  if (type == "auth") return {{"ok", true}, {"may_act", may_act}};
  if (type != "order" && type != "manual_tie") return Refused("unknown command type '" + type + "'");
  if (!may_act) {
    ++refused_;
    return Refused("this console only watches: a valid token is needed to act");
  }
  return Act(command);
}

json ConsoleAdapter::Act(const json& command) {
  std::string error;
  if (command["type"] == "order") {
    procman_order_t order;
    if (!OrderFromJson(command, WallMicros(), &order, &error)) return Refused(error);
    if (!Publish(transport_, options_.orders_channel, order)) return Refused("the order could not be sent");
    ++orders_sent_;
    LOG(INFO) << "console: order " << command.value("action", "") << " " << command.value("target", "") << " on host '"
              << command.value("host", "") << "' sent";
    return {{"ok", true}};
  }
  manual_tie_points_t ties;
  if (!ManualTiesFromJson(command, WallMicros(), options_.max_manual_points, &ties, &error)) return Refused(error);
  if (!Publish(transport_, options_.manual_ties_channel, ties)) return Refused("the tie points could not be sent");
  ++manual_sent_;
  LOG(INFO) << "console: " << ties.num_points << " manual tie points for sites " << ties.previous_site_id << " -> "
            << ties.current_site_id << " sent";
  return {{"ok", true}, {"points", ties.num_points}};
}

bool ConsoleAdapter::OnApi(const std::string& rest, const std::map<std::string, std::string>& query, HttpReply* reply) {
  if (rest == "image") return ImageReply(query, reply);
  if (rest == "orthoimage" && !orthoimage_bytes_.empty()) {
    *reply = {200, orthoimage_type_, orthoimage_bytes_};
    return true;
  }
  if (rest == "uav_mosaic" && !uav_mosaic_jpeg_.empty()) {
    *reply = {200, "image/jpeg", uav_mosaic_jpeg_};
    return true;
  }
  if (rest == "status") {
    const ConsoleServerStats& s = server_.stats();
    *reply = {200, "application/json",
              json{{"clients", server_.num_clients()},
                   {"http_requests", s.http_requests},
                   {"http_rejected", s.http_rejected},
                   {"dropped_slow", s.clients_dropped_slow},
                   {"connections_refused", s.connections_refused},
                   {"messages_bad", s.messages_bad},
                   {"hosts_refused", s.hosts_refused},
                   {"origins_refused", s.origins_refused},
                   {"auth_failures", s.auth_failures},
                   {"auth_locked_out", s.auth_locked_out},
                   {"orders_sent", orders_sent_},
                   {"manual_sent", manual_sent_},
                   {"refused", refused_}}
                  .dump()};
    return true;
  }
  return false;
}

bool ConsoleAdapter::ImageReply(const std::map<std::string, std::string>& query, HttpReply* reply) {
  int site = -1, pair = -1;
  try {
    site = std::stoi(query.at("site"));
    pair = std::stoi(query.at("pair"));
  } catch (const std::exception&) {
    *reply = {400, "text/plain", "image needs ?site=<id>&pair=<index>\n"};
    return true;
  }
  const auto s = left_images_.find(site);
  if (s == left_images_.end() || !s->second.count(pair)) return false;
  KeptImage& kept = s->second.at(pair);
  if (kept.served.empty()) {
    std::vector<uchar> bytes;
    cv::imencode(".png", ImageFromMessage(kept.message), bytes);  // throws on bad pixels: 500, logged
    kept.served.assign(bytes.begin(), bytes.end());
    kept.type = "image/png";
  }
  *reply = {200, kept.type, kept.served};
  return true;
}

std::string ConsoleAdapter::StatusLine() const {
  const ConsoleServerStats& s = server_.stats();
  return "browsers " + std::to_string(s.clients_opened) + " opened (" + std::to_string(s.clients_dropped_slow) +
         " dropped as too slow), HTTP requests " + std::to_string(s.http_requests) + " (" +
         std::to_string(s.http_rejected) + " refused), orders sent " + std::to_string(orders_sent_) +
         ", manual tie sets sent " + std::to_string(manual_sent_) + ", refused commands " + std::to_string(refused_) +
         "; " + SubscriptionSummary(stats_);
}

}  // namespace vloc
