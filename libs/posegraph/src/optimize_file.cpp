// OptimizeGraphFile: a graph file's poses through SolvePoseGraph.

#include <sstream>

#include "vloc/posegraph/graph_io.h"
#include "vloc/posegraph/mrpt_graph.h"
#include "vloc/posegraph/sesync_objective.h"

namespace vloc::posegraph {

std::string GraphFileReport::BriefReport() const {
  std::ostringstream os;
  os.precision(10);
  if (chi2_defined) os << "chi2 " << initial_chi2 << " -> " << final_chi2 << ", ";
  else os << "chi2 not defined (information matrices not positive definite), ";
  os << "SE-Sync objective " << initial_sesync << " -> "
     << final_sesync << ", " << solver.iterations << " iterations, " << solver.total_seconds << " s (chordal "
     << solver.initialisation_seconds << " s)";
  if (!solver.usable) os << "; NOT solved: " << solver.message;
  else os << "; " << certificate.message << (certificate.seconds > 0 ? " (checked in " : "")
          << (certificate.seconds > 0 ? std::to_string(certificate.seconds) + " s)" : "");
  return os.str();
}

namespace {

template <int D, class Graph>
GraphFileReport OptimizeImpl(Graph* graph, const SolverOptions& options, bool sesync_weights, bool chi2_defined) {
  GraphFileReport report;
  report.chi2_defined = chi2_defined;
  std::vector<mrpt::graphs::TNodeID> ids;
  PoseGraphProblem<D> problem = ProblemFromGraph(*graph, &ids);
  report.initial_chi2 = Cost(problem, nullptr);
  report.initial_sesync = SeSyncObjective(problem);
  PoseGraphProblem<D> solved = problem;
  SolverOptions solver_options = options;
  if (sesync_weights) {
    // Exactly SE-Sync's objective: its isotropic weights on the chordal rotation residual.
    UseSeSyncWeights(&solved);
    solver_options.rotation_residual = "chordal";
  }
  report.solver = SolvePoseGraph(&solved, solver_options);
  problem.poses = solved.poses;
  report.final_chi2 = Cost(problem, nullptr);
  report.final_sesync = SeSyncObjective(problem);
  // The certificate is for SE-Sync's objective: meaningful when that is what was solved.
  if (report.solver.usable && sesync_weights) report.certificate = CertifyGlobalOptimum(problem);
  else report.certificate.message = "no certificate (it is for SE-Sync's objective: read the file for it, --weights sesync)";
  if (report.solver.usable) PosesToGraph(problem, ids, graph);
  return report;
}

}  // namespace

GraphFileReport OptimizeGraphFile(GraphFile* file, const SolverOptions& options) {
  const bool sesync = file->information_use == InformationUse::kSeSyncBlocks;
  if (file->dimension == 2) return OptimizeImpl<2>(&file->graph2, options, sesync, file->num_indefinite == 0);
  return OptimizeImpl<3>(&file->graph3, options, sesync, file->num_indefinite == 0);
}

}  // namespace vloc::posegraph
