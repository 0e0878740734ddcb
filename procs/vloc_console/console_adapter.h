#pragma once
// vloc_console's LCM side: every channel an operator watches in, JSON to the
// browsers (through vloc::ConsoleServer); the browsers' acting commands out
// as PROCMAN_ORDERS (procman_order_t) and MANUAL_TIE_POINTS
// (manual_tie_points_t). It keeps the current picture (sites, statuses,
// tie points, the newest sites' left images, the UAV route) bounded, and
// sends it to each browser that connects.

#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vloc/common/pose.h"
#include "vloc/console/console_server.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/image_t.hpp"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/tunnel_status_t.hpp"
#include "vloc/tie_points_t.hpp"

namespace vloc {

class OptionsReader;

// An aerial orthoimage under the traverse map (north up, pixel (0, 0) at the
// north-west corner).
struct OrthoimageOptions {
  std::string path;       // PNG / JPEG file ("" = none)
  double x_min_m = 0;     // m, world x (east) of the image's west edge
  double y_max_m = 0;     // m, world y (north) of the image's north edge
  double m_per_px = 0.2;  // m per pixel

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct ConsoleProcOptions {
  ConsoleServerOptions server;                              // HTTP / WebSocket server (map `server`)
  std::string traverse_channel = "TRAVERSE";                // traverse_t in
  std::string dr_channel = "SITE_POSE_DR";                  // site_pose_t in
  std::string visual_channel = "SITE_POSE_VISUAL";          // localization_t in
  std::string frontend_status_channel = "FRONTEND_STATUS";  // frontend_status_t in
  std::string tie_points_channel = "TIE_POINTS";            // tie_points_t in
  std::string stereo_channel = "NAVCAM_STEREO";             // stereo_image_t in (left images shown; "" = none)
  std::string procman_status_channel = "PROCMAN_STATUS";    // procman_status_t in
  std::string tunnel_status_channel = "TUNNEL_STATUS";      // tunnel_status_t in (vloc_lcm_tunnel; "" = none)
  std::string uav_state_channel = "UAV_STATE";              // uav_state_t in
  std::string uav_mosaic_channel = "UAV_MOSAIC";            // image_t in (JPEG preview)
  std::string orders_channel = "PROCMAN_ORDERS";            // procman_order_t out
  std::string manual_ties_channel = "MANUAL_TIE_POINTS";    // manual_tie_points_t out
  int max_sites = 5000;                                     // sites whose poses and statuses are kept
  int image_sites_kept = 3;                                 // newest sites whose left images are kept
  int max_uav_states = 5000;                                // UAV states kept for the route and height plots
  int max_manual_points = 200;                              // picks in one manual tie-point command
  int tie_point_sites_kept = 10;                            // newest sites whose tie points are kept and sent
  int max_launchers = 32;                                   // launchers (host, pid) whose process tables are kept,
                                                            // and tunnel ends (by name) whose links are kept
  int64_t welcome_max_bytes = 4 << 20;                      // bytes a newly opened page is sent (newest sites first)
  OrthoimageOptions orthoimage;                             // drawn under the map (map `orthoimage`)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

class ConsoleAdapter {
 public:
  ConsoleAdapter(Transport& transport, ConsoleServer& server, const ConsoleProcOptions& options);
  void Subscribe();
  // Loads the orthoimage when one is configured; false and *error when it cannot be read.
  bool LoadOrthoimage(std::string* error);
  std::string StatusLine() const;

  // What a browser that connects now is sent first.
  std::vector<std::string> Welcome() const;
  nlohmann::json OnCommand(const nlohmann::json& command, bool may_act);
  bool OnApi(const std::string& rest, const std::map<std::string, std::string>& query, HttpReply* reply);

 private:
  static constexpr int kQueue = 1000;      // small messages, none may be lost
  static constexpr int kStereoQueue = 64;  // stereo pairs (about 2 MB each)
  static constexpr int kMosaicQueue = 4;   // only the newest preview matters
  // Subscribes `handle` to `channel` through the validated decode (typed.h).
  template <class Msg>
  void Watch(const std::string& channel, std::function<void(const Msg&)> handle, int queue = kQueue);
  void SubscribeRover();
  void SubscribeUav();
  void OnLocalization(const localization_t& msg);
  // Sends `j` to the browsers and keeps it under `key` for later ones.
  void Post(const std::string& key, const nlohmann::json& j);
  // The same for a per-site key ("<prefix>/<site>"); the oldest sites beyond max_sites are dropped.
  void PostSite(const char* prefix, int site, const nlohmann::json& j);
  void TrimSites();
  void OnProcmanStatus(const procman_status_t& msg);
  // Keeps `key` (under `prefix`) as heard now; the longest silent beyond max_launchers is dropped (`gone_type` sent).
  void KeepNewest(std::map<std::string, int64_t>* heard, const std::string& prefix, const std::string& key,
                  const char* gone_type);
  // The per-site keys a new page gets: the newest sites' first, within welcome_max_bytes.
  std::set<int> WelcomeSites(size_t budget) const;
  // Keeps a left image as it came: PNG / JPEG bytes are served as they are,
  // raw pixels are encoded to PNG when first asked for.
  void OnLeftImage(int site, int pair, const image_t& left);
  void OnTiePoints(const tie_points_t& msg);
  void RefreshTiePoints(int current_site);
  bool ImageReply(const std::map<std::string, std::string>& query, HttpReply* reply);
  nlohmann::json Act(const nlohmann::json& command);

  Transport& transport_;
  ConsoleServer& server_;
  ConsoleProcOptions options_;
  std::map<std::string, std::string> picture_;         // key -> JSON text, the current picture
  std::set<int> sites_;                                // sites with per-site keys in the picture
  std::map<std::string, int64_t> launchers_;           // procman key -> when last heard (message count)
  std::map<std::string, int64_t> tunnels_;             // tunnel end name -> when last heard (message count)
  int64_t heard_ = 0;                                   // launcher and tunnel messages so far
  struct KeptImage {
    image_t message;     // as received
    std::string served;  // the bytes served (PNG / JPEG); "" until first asked for raw pixels
    std::string type;    // their MIME type
  };
  std::map<int, std::map<int, KeptImage>> left_images_;  // site -> pair -> left image (newest sites)
  std::map<int, tie_points_t> tie_points_;  // by current site (newest pairs)
  std::map<int, Pose3> relative_poses_;     // BA previous_from_current by current site
  std::deque<std::string> uav_states_;
  std::string uav_mosaic_jpeg_;
  std::string orthoimage_bytes_, orthoimage_type_;
  int64_t uav_mosaic_seq_ = 0;
  int64_t orders_sent_ = 0, manual_sent_ = 0, refused_ = 0;
  std::vector<std::shared_ptr<SubscriptionStats>> stats_;
};

}  // namespace vloc
