#include "traverse_graph_adapter.h"

#include <glog/logging.h>

#include <filesystem>

#include "vloc/lcm_io/convert.h"
#include "vloc/lcm_io/convert_traverse.h"

namespace vloc {

void TraverseGraphProcOptions::Visit(OptionsReader& r) {
  r.Optional("dr_channel", &dr_channel, "site_pose_t in: dead reckoning per site", NonEmpty());
  r.Optional("visual_channel", &visual_channel, "localization_t in: BA results", NonEmpty());
  r.Optional("fix_channel", &fix_channel, "site_pose_t in: absolute fixes, empty = none");
  r.Optional("traverse_channel", &traverse_channel, "traverse_t out", NonEmpty());
  r.Optional("graph_path", &graph_path, "graph file saved after each update, reloaded on start");
  r.Optional("load_on_start", &load_on_start, "reload graph_path when it exists");
  r.Optional("queue_capacity", &queue_capacity, "messages per subscription queue", AtLeast(1));
  r.Child("graph", [this](OptionsReader& c) { graph.Visit(c); });
}

bool TraverseGraphProcOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

TraverseGraphAdapter::TraverseGraphAdapter(Transport& transport, const TraverseGraphProcOptions& options)
    : transport_(transport), options_(options), graph_(options.graph) {
  dr_stats_ = Subscribe<site_pose_t>(
      transport_, options_.dr_channel,
      [this](const std::string&, const site_pose_t& m) {
        // Site 0 again while the graph holds a traverse: a new run. The saved
        // graph (reloaded on start) belongs to the previous one: set it aside.
        if (m.site_id == 0 && graph_.num_sites() > 1) {
          LOG(WARNING) << "dead reckoning of site 0 while the graph holds " << graph_.num_sites()
                       << " sites: a new traverse; starting a new graph"
                       << (options_.graph_path.empty() ? "" : " (old one kept as " + options_.graph_path + ".previous)");
          if (!options_.graph_path.empty()) {
            std::error_code ec;
            std::filesystem::rename(options_.graph_path, options_.graph_path + ".previous", ec);
          }
          graph_ = posegraph::TraverseGraph(options_.graph);
        }
        const auto added = graph_.AddDeadReckoning(m.site_id, PoseFromMessage(m.pose));
        Update(added, "dead reckoning of site " + std::to_string(m.site_id));
      },
      options_.queue_capacity);
  visual_stats_ = Subscribe<localization_t>(
      transport_, options_.visual_channel,
      [this](const std::string&, const localization_t& m) {
        if (m.status != localization_t::STATUS_OK) {
          ++visual_skipped_;
          LOG(INFO) << "site " << m.site_id << ": BA status " << int(m.status) << " (" << m.message
                    << "); no visual edge, dead reckoning stands";
          return;
        }
        PoseWithCovariance relative = PoseFromMessage(m.relative_pose);
        relative.utime = m.utime;
        const auto added = graph_.AddRelative(m.reference_site_id, m.site_id, relative);
        Update(added, "visual edge " + std::to_string(m.reference_site_id) + "->" + std::to_string(m.site_id));
      },
      options_.queue_capacity);
  if (!options_.fix_channel.empty())
    fix_stats_ = Subscribe<site_pose_t>(
        transport_, options_.fix_channel,
        [this](const std::string&, const site_pose_t& m) {
          const auto added = graph_.AddAbsoluteFix(m.site_id, PoseFromMessage(m.pose));
          Update(added, "absolute fix of site " + std::to_string(m.site_id));
        },
        options_.queue_capacity);
}

bool TraverseGraphAdapter::Restore(std::string* error) {
  if (options_.graph_path.empty() || !options_.load_on_start) return true;
  if (!std::filesystem::exists(options_.graph_path)) {
    LOG(INFO) << "no saved graph at " << options_.graph_path << "; starting a new traverse";
    return true;
  }
  if (!graph_.Load(options_.graph_path, error)) {
    if (error) *error += " (move or delete the file to start a new traverse)";
    return false;
  }
  const auto summary = graph_.Optimize();
  LOG(INFO) << "reloaded " << options_.graph_path << ": " << summary.BriefReport();
  Publish(transport_, options_.traverse_channel, TraverseToMessage(graph_, summary));
  return true;
}

void TraverseGraphAdapter::Update(const posegraph::AddResult& added, const std::string& what) {
  if (!added.accepted) {
    ++rejected_;
    LOG(WARNING) << what << ": " << added.message;
    return;
  }
  if (added.pending) LOG(INFO) << what << ": " << added.message;
  if (!added.changed) return;
  const auto summary = graph_.Optimize();
  ++updates_;
  LOG(INFO) << what << ": " << summary.BriefReport();
  Publish(transport_, options_.traverse_channel, TraverseToMessage(graph_, summary));
  if (!options_.graph_path.empty()) {
    std::string error;
    if (!graph_.Save(options_.graph_path, &error)) LOG(ERROR) << error;
  }
}

std::string TraverseGraphAdapter::StatusLine() const {
  return std::to_string(updates_) + " updates, " + std::to_string(graph_.num_sites()) + " sites, " +
         std::to_string(visual_skipped_) + " failed BA results skipped, " + std::to_string(rejected_) +
         " measurements rejected; last: " + graph_.last_summary().BriefReport() + "; " +
         SubscriptionSummary({dr_stats_, visual_stats_, fix_stats_});
}

}  // namespace vloc
