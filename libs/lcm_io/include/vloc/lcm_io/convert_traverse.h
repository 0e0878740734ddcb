#pragma once
// The traverse pose graph (libs/posegraph) -> TRAVERSE.

#include "vloc/posegraph/traverse_graph.h"
#include "vloc/traverse_t.hpp"

namespace vloc {

// The graph's current state as traverse_t: every site's optimised
// world_from_body (with its covariance) in the graph's order, the newest
// measurement time as utime, and the summary's edge counts, chi2 and time.
traverse_t TraverseToMessage(const posegraph::TraverseGraph& graph, const posegraph::PoseGraphSummary& summary);

}  // namespace vloc
