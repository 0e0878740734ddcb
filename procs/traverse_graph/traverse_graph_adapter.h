#pragma once
// LCM side of the traverse pose graph: SITE_POSE_DR (site_pose_t),
// SITE_POSE_VISUAL (localization_t, only STATUS_OK results, relative_pose =
// reference_from_current) and optionally SITE_POSE_FIX (site_pose_t,
// absolute world_from_body fixes) in; TRAVERSE (traverse_t) out after every
// update. The graph is saved (MRPT text format + vloc metadata) after every
// update to graph_path and reloaded from it on start. A SITE_POSE_DR for
// site 0 while the graph holds more than one site starts a new traverse (the
// old file is kept as graph_path + ".previous").

#include <memory>
#include <string>

#include "vloc/common/options.h"
#include "vloc/lcm_io/transport.h"
#include "vloc/lcm_io/typed.h"
#include "vloc/localization_t.hpp"
#include "vloc/posegraph/traverse_graph.h"
#include "vloc/site_pose_t.hpp"
#include "vloc/traverse_t.hpp"

namespace vloc {

struct TraverseGraphProcOptions {
  std::string dr_channel = "SITE_POSE_DR";          // site_pose_t in: dead-reckoning pose per site
  std::string visual_channel = "SITE_POSE_VISUAL";  // localization_t in: cross-site BA results
  std::string fix_channel = "SITE_POSE_FIX";        // site_pose_t in: absolute fixes ("" = none)
  std::string traverse_channel = "TRAVERSE";        // traverse_t out
  std::string graph_path = "";                      // file the graph is saved to / reloaded from ("" = none)
  bool load_on_start = true;                        // reload graph_path when it exists
  int queue_capacity = 100;                         // messages per subscription queue
  posegraph::PoseGraphOptions graph;                // the pose graph (map `graph`)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

class TraverseGraphAdapter {
 public:
  TraverseGraphAdapter(Transport& transport, const TraverseGraphProcOptions& options);
  // Loads graph_path when configured and present; publishes it. False with
  // *error when the file exists but cannot be read (the process stops).
  bool Restore(std::string* error);
  std::string StatusLine() const;
  const posegraph::TraverseGraph& graph() const { return graph_; }

 private:
  void Update(const posegraph::AddResult& added, const std::string& what);

  Transport& transport_;
  TraverseGraphProcOptions options_;
  posegraph::TraverseGraph graph_;
  std::shared_ptr<SubscriptionStats> dr_stats_, visual_stats_, fix_stats_;
  int64_t updates_ = 0, visual_skipped_ = 0, rejected_ = 0;
};

}  // namespace vloc
