#pragma once
// vloc_console's message -> JSON conversion (the browser's picture of each
// message) and the browser's commands -> messages. One adapter layer: the
// console server (libs/console) sees only JSON text.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "vloc/common/pose.h"
#include "vloc/frontend_status_t.hpp"
#include "vloc/localization_t.hpp"
#include "vloc/manual_tie_points_t.hpp"
#include "vloc/procman_order_t.hpp"
#include "vloc/procman_status_t.hpp"
#include "vloc/site_pose_t.hpp"
#include "vloc/tie_points_t.hpp"
#include "vloc/traverse_t.hpp"
#include "vloc/tunnel_status_t.hpp"
#include "vloc/uav_state_t.hpp"

namespace vloc {

// Position, heading and the horizontal (x, y) covariance of a pose.
nlohmann::json PoseJson(const PoseWithCovariance& pose);

nlohmann::json TraverseJson(const traverse_t& msg);
nlohmann::json SitePoseJson(const site_pose_t& msg);
nlohmann::json LocalizationJson(const localization_t& msg);
nlohmann::json FrontendStatusJson(const frontend_status_t& msg);
// The left-image observations of each point; with `previous_from_current`
// (the BA's relative pose) each point's 3-D residual in metres.
nlohmann::json TiePointsJson(const tie_points_t& msg, const std::optional<Pose3>& previous_from_current);
nlohmann::json ProcmanJson(const procman_status_t& msg);
nlohmann::json UavStateJson(const uav_state_t& msg);
// One end of an LCM tunnel (vloc_lcm_tunnel): link state, rates, queues, drops, latency, per channel.
nlohmann::json TunnelStatusJson(const tunnel_status_t& msg);

// A browser's {"type": "order", host, target, target_kind, action}; false
// and *error (one line) when a field is missing or unknown.
bool OrderFromJson(const nlohmann::json& command, int64_t utime, procman_order_t* order, std::string* error);
// A browser's {"type": "manual_tie", previous_site, current_site, points:
// [{previous_pair, previous_u, previous_v, current_pair, current_u, current_v}]}.
bool ManualTiesFromJson(const nlohmann::json& command, int64_t utime, int max_points, manual_tie_points_t* ties,
                        std::string* error);

}  // namespace vloc
