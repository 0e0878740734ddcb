#include "console_json.h"

#include <cmath>

#include "vloc/lcm_io/convert.h"

namespace vloc {

using nlohmann::json;

namespace {

// JSON has no NaN: a non-finite number becomes null.
json Num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// The field `key` of `j` as a finite number within [lo, hi].
bool GetNumber(const json& j, const char* key, double lo, double hi, double* value, std::string* error) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number() || !std::isfinite(it->get<double>()) || it->get<double>() < lo ||
      it->get<double>() > hi) {
    *error = std::string("'") + key + "' must be a number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
    return false;
  }
  *value = it->get<double>();
  return true;
}

bool GetInt(const json& j, const char* key, int lo, int hi, int* value, std::string* error) {
  double v = 0;
  if (!GetNumber(j, key, lo, hi, &v, error)) return false;
  if (v != std::floor(v)) {
    *error = std::string("'") + key + "' must be an integer";
    return false;
  }
  *value = static_cast<int>(v);
  return true;
}

bool GetString(const json& j, const char* key, std::string* value, std::string* error) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_string()) {
    *error = std::string("'") + key + "' must be a string";
    return false;
  }
  *value = it->get<std::string>();
  return true;
}

// Finds `name` in the list; its index or -1.
int IndexOf(const std::string& name, std::initializer_list<const char*> names) {
  int i = 0;
  for (const char* n : names) {
    if (name == n) return i;
    ++i;
  }
  return -1;
}

json Observation(const tie_observation_t& o) { return {{"pair", o.pair_index}, {"u", o.u}, {"v", o.v}}; }

}  // namespace

json PoseJson(const PoseWithCovariance& p) {
  const Eigen::Vector3d t = p.pose.translation();
  const Eigen::Matrix3d r = p.pose.linear();
  return {{"x", Num(t.x())},
          {"y", Num(t.y())},
          {"z", Num(t.z())},
          {"yaw", Num(std::atan2(r(1, 0), r(0, 0)))},
          {"cxx", Num(p.covariance(0, 0))},
          {"cxy", Num(p.covariance(0, 1))},
          {"cyy", Num(p.covariance(1, 1))}};
}

json TraverseJson(const traverse_t& m) {
  json sites = json::array();
  for (int i = 0; i < m.num_sites; ++i) {
    json s = PoseJson(PoseFromMessage(m.poses[i]));
    s["id"] = m.site_ids[i];
    sites.push_back(std::move(s));
  }
  return {{"type", "traverse"},
          {"utime", m.utime},
          {"sites", std::move(sites)},
          {"edges", m.num_edges},
          {"visual_edges", m.num_visual_edges},
          {"loop_edges", m.num_loop_edges},
          {"final_chi2", Num(m.final_chi2)},
          {"solve_seconds", Num(m.solve_seconds)}};
}

json SitePoseJson(const site_pose_t& m) {
  static const char* kSources[] = {"truth", "dr", "visual", "optimized"};
  json j = PoseJson(PoseFromMessage(m.pose));
  j["type"] = "site_pose";
  j["site"] = m.site_id;
  j["utime"] = m.utime;
  j["source"] = m.source >= 0 && m.source <= 3 ? kSources[m.source] : "unknown";
  return j;
}

json LocalizationJson(const localization_t& m) {
  static const char* kStatus[] = {"ok", "too few points", "ill conditioned", "not converged", "bad input"};
  json j = PoseJson(PoseFromMessage(m.pose));
  j.update({{"type", "localization"},
            {"site", m.site_id},
            {"reference", m.reference_site_id},
            {"status", m.status >= 0 && m.status <= 4 ? kStatus[m.status] : "unknown"},
            {"ok", m.status == 0},
            {"message", m.message},
            {"used", m.num_tie_points_used},
            {"rejected", m.num_tie_points_rejected},
            {"observations", m.num_observations},
            {"initial_rms_px", Num(m.initial_rms_px)},
            {"final_rms_px", Num(m.final_rms_px)},
            {"iterations", m.iterations},
            {"solve_seconds", Num(m.solve_seconds)},
            {"utime", m.utime}});
  return j;
}

json FrontendStatusJson(const frontend_status_t& m) {
  static const char* kStatus[] = {"ok", "no overlap", "low texture", "too few points", "missing input", "error"};
  json stages = json::array();
  for (int i = 0; i < m.num_stages; ++i)
    stages.push_back({{"name", m.stage_names[i]}, {"count", m.stage_counts[i]}, {"seconds", Num(m.stage_seconds[i])}});
  return {{"type", "frontend_status"},
          {"previous", m.previous_site_id},
          {"current", m.current_site_id},
          {"status", m.status >= 0 && m.status <= 5 ? kStatus[m.status] : "unknown"},
          {"ok", m.status == 0},
          {"message", m.message},
          {"stages", std::move(stages)},
          {"total_seconds", Num(m.total_seconds)},
          {"utime", m.utime}};
}

json TiePointsJson(const tie_points_t& m, const std::optional<Pose3>& previous_from_current) {
  json points = json::array();
  for (const tie_point_t& p : m.points) {
    json j = {{"id", p.id}};
    for (const tie_observation_t& o : p.observations) {
      if (o.camera != tie_observation_t::CAMERA_LEFT) continue;
      j[o.site_role == tie_observation_t::SITE_PREVIOUS ? "previous" : "current"] = Observation(o);
    }
    if (previous_from_current) {
      const Eigen::Vector3d a(p.p_previous[0], p.p_previous[1], p.p_previous[2]);
      const Eigen::Vector3d b(p.p_current[0], p.p_current[1], p.p_current[2]);
      j["residual_m"] = Num((a - *previous_from_current * b).norm());
    }
    points.push_back(std::move(j));
  }
  return {{"type", "tie_points"},
          {"previous", m.previous_site_id},
          {"current", m.current_site_id},
          {"points", std::move(points)},
          {"utime", m.utime}};
}

json ProcmanJson(const procman_status_t& m) {
  static const char* kStates[] = {"stopped", "starting", "running", "stopping", "backoff", "exited", "gave up"};
  json procs = json::array();
  for (const proc_status_t& p : m.procs)
    procs.push_back({{"name", p.name},
                     {"group", p.group},
                     {"pid", p.pid},
                     {"state", p.state >= 0 && p.state <= 6 ? kStates[p.state] : "unknown"},
                     {"restarts", p.restarts},
                     {"last_exit_code", p.last_exit_code},
                     {"cpu_percent", Num(p.cpu_percent)},
                     {"rss_bytes", p.rss_bytes},
                     {"uptime_seconds", Num(p.uptime_seconds)}});
  return {
      {"type", "procman"}, {"host", m.host}, {"pid", m.launcher_pid}, {"utime", m.utime}, {"procs", std::move(procs)}};
}

json UavStateJson(const uav_state_t& m) {
  static const char* kStatus[] = {"calibrating", "tracking", "lost", "recovered"};
  return {{"type", "uav_state"},
          {"utime", m.utime},
          {"frame", m.frame_index},
          {"status", m.status >= 0 && m.status <= 3 ? kStatus[m.status] : "unknown"},
          {"message", m.message},
          {"height", Num(m.height)},
          {"height_raw", Num(m.height_raw)},
          {"east", Num(m.route_local[0])},
          {"north", Num(m.route_local[1])},
          {"px", Num(m.route_px[0])},
          {"py", Num(m.route_px[1])},
          {"gps_aided", m.gps_aided != 0},
          {"inliers", m.num_inliers},
          {"matches", m.num_matches}};
}

json TunnelStatusJson(const tunnel_status_t& m) {
  static const char* kPriority[] = {"urgent", "normal", "bulk"};
  json channels = json::array();
  for (const tunnel_channel_status_t& c : m.channels)
    channels.push_back({{"channel", c.channel},
                        {"priority", c.priority >= 0 && c.priority <= 2 ? kPriority[c.priority] : "unknown"},
                        {"queued", c.queued_messages},
                        {"queued_bytes", c.queued_bytes},
                        {"sent", c.sent},
                        {"received", c.received},
                        {"dropped", c.dropped},
                        {"latency_max_ms", Num(c.latency_max_ms)}});
  return {{"type", "tunnel"},
          {"utime", m.utime},
          {"name", m.name},
          {"peer", m.peer_name},
          {"endpoint", m.endpoint},
          {"connected", m.connected != 0},
          {"connects", m.connects},
          {"seconds_since_peer", Num(m.seconds_since_peer)},
          {"tx_bytes_per_s", Num(m.tx_bytes_per_s)},
          {"rx_bytes_per_s", Num(m.rx_bytes_per_s)},
          {"cap_bytes_per_s", Num(m.bandwidth_cap_bytes_per_s)},
          {"queued", m.queued_messages},
          {"queued_bytes", m.queued_bytes},
          {"queued_bytes_high_water", m.queued_bytes_high_water},
          {"in_flight_bytes", m.in_flight_bytes},
          {"resent_frames", m.resent_frames},
          {"dropped", m.dropped_queue_full + m.dropped_too_large + m.dropped_too_many_channels},
          {"dropped_queue_full", m.dropped_queue_full},
          {"dropped_too_large", m.dropped_too_large},
          {"dropped_too_many_channels", m.dropped_too_many_channels},
          {"refused_from_peer", m.refused_from_peer},
          {"rejected_frames", m.rejected_frames},
          {"latency_samples", m.latency_samples},
          {"latency_median_ms", Num(m.latency_median_ms)},
          {"latency_max_ms", Num(m.latency_max_ms)},
          {"channels", std::move(channels)}};
}

bool OrderFromJson(const json& c, int64_t utime, procman_order_t* order, std::string* error) {
  std::string host, target, kind, action;
  if (!GetString(c, "host", &host, error) || !GetString(c, "target", &target, error) ||
      !GetString(c, "target_kind", &kind, error) || !GetString(c, "action", &action, error))
    return false;
  const int kind_index = IndexOf(kind, {"process", "group"});
  const int action_index = IndexOf(action, {"start", "stop", "restart"});
  if (target.empty() || kind_index < 0 || action_index < 0) {
    *error = "order needs a target, target_kind process|group and action start|stop|restart";
    return false;
  }
  order->utime = utime;
  order->host = host;
  order->target = target;
  order->target_kind = static_cast<int8_t>(kind_index);
  order->action = static_cast<int8_t>(action_index);
  return true;
}

bool ManualTiesFromJson(const json& c, int64_t utime, int max_points, manual_tie_points_t* t, std::string* error) {
  if (!GetInt(c, "previous_site", 0, 1 << 30, &t->previous_site_id, error) ||
      !GetInt(c, "current_site", 0, 1 << 30, &t->current_site_id, error))
    return false;
  if (t->current_site_id <= t->previous_site_id) return (*error = "current_site must be after previous_site", false);
  const auto points = c.find("points");
  if (points == c.end() || !points->is_array() || points->empty() || static_cast<int>(points->size()) > max_points)
    return (*error = "points must be a list of 1 to " + std::to_string(max_points) + " picks", false);
  constexpr double kMaxPx = 100000;
  for (const json& p : *points) {
    int pp = 0, cp = 0;
    double pu = 0, pv = 0, cu = 0, cv = 0;
    if (!p.is_object() || !GetInt(p, "previous_pair", 0, 1000, &pp, error) ||
        !GetNumber(p, "previous_u", 0, kMaxPx, &pu, error) || !GetNumber(p, "previous_v", 0, kMaxPx, &pv, error) ||
        !GetInt(p, "current_pair", 0, 1000, &cp, error) || !GetNumber(p, "current_u", 0, kMaxPx, &cu, error) ||
        !GetNumber(p, "current_v", 0, kMaxPx, &cv, error))
      return (*error = "pick " + std::to_string(t->previous_pair.size()) + ": " + *error, false);
    t->previous_pair.push_back(pp), t->previous_u.push_back(pu), t->previous_v.push_back(pv);
    t->current_pair.push_back(cp), t->current_u.push_back(cu), t->current_v.push_back(cv);
  }
  t->utime = utime;
  t->num_points = static_cast<int32_t>(t->previous_pair.size());
  const auto source = c.find("source");
  t->source = source != c.end() && source->is_string() ? source->get<std::string>().substr(0, 64) : "vloc_console";
  return true;
}

}  // namespace vloc
