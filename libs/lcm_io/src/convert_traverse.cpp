#include "vloc/lcm_io/convert_traverse.h"

#include "vloc/lcm_io/convert.h"

namespace vloc {

traverse_t TraverseToMessage(const posegraph::TraverseGraph& graph, const posegraph::PoseGraphSummary& summary) {
  traverse_t msg;
  msg.utime = graph.newest_utime();
  for (const auto& site : graph.Sites()) {
    msg.site_ids.push_back(site.site_id);
    pose_t pose = PoseToMessage(site.world_from_body, "world", "body");
    msg.poses.push_back(pose);
  }
  msg.num_sites = static_cast<int32_t>(msg.site_ids.size());
  msg.num_edges = summary.num_edges;
  msg.num_visual_edges = summary.num_visual_edges;
  msg.num_loop_edges = summary.num_loop_edges;
  msg.initial_chi2 = summary.initial_chi2;
  msg.final_chi2 = summary.final_chi2;
  msg.iterations = summary.iterations;
  msg.solve_seconds = summary.total_seconds;
  return msg;
}

}  // namespace vloc
