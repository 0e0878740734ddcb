// vloc_posegraph: optimises a pose-graph file (g2o SE2/SE3:QUAT, or MRPT/TORO
// text) and writes the result in the same format.
//   vloc_posegraph IN.g2o --out OUT.g2o [--weights file|sesync] [--init chordal|none]
//                  [--max-iterations N] [--threads N] [--linear-solver cholmod|eigen] [--verbose 1]
// --weights sesync solves SE-Sync's objective exactly (its isotropic weights
// from each edge's translation and rotation blocks: the measure of the
// published optima; a 6 x 6 information that is not positive definite is
// taken as it is when its blocks are); --weights file (the default) solves
// the file's chi2, and refuses such a matrix in one line. The output keeps the
// file's information matrices.
// Prints the chi2 (file weights) and SE-Sync's objective before and after,
// the iterations and the time, and with --weights sesync whether SE-Sync's
// certificate of global optimality holds. Exit code 0 when the solve is usable.

#include <omp.h>

#include <iostream>

#include "vloc/common/command_line.h"
#include "vloc/posegraph/graph_io.h"

namespace {

constexpr const char* kUsage =
    "usage: vloc_posegraph IN.g2o --out OUT.g2o [--weights file|sesync] [--init chordal|none] "
    "[--max-iterations N] [--threads N] [--linear-solver cholmod|eigen] [--verbose 1]\n";

}  // namespace

int main(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"out", "weights", "init", "max-iterations", "threads", "linear-solver", "verbose", "help"}, &error) ||
      args.positional().size() != 1 || !args.Has("out") || args.Has("help")) {
    if (!error.empty()) std::cerr << "vloc_posegraph: " << error << "\n";
    std::cerr << kUsage;
    return 1;
  }
  try {
    const std::string weights = args.Get("weights", "file");
    const std::string init = args.Get("init", "chordal");
    if ((weights != "file" && weights != "sesync") || (init != "chordal" && init != "none")) {
      std::cerr << "vloc_posegraph: --weights is file or sesync, --init is chordal or none\n" << kUsage;
      return 1;
    }
    vloc::posegraph::SolverOptions options;
    options.chordal_initialisation = init == "chordal";
    options.max_iterations = args.GetInt("max-iterations", options.max_iterations);
    options.num_threads = args.GetInt("threads", options.num_threads);
    options.verbose = args.GetInt("verbose", 0) != 0;
    options.linear_solver = args.Get("linear-solver", options.linear_solver);
    if (!options.Check(&error)) {
      std::cerr << "vloc_posegraph: " << error << "\n";
      return 1;
    }
    omp_set_num_threads(options.num_threads);  // CHOLMOD's and METIS' OpenMP too, not only the solver's loops
    vloc::posegraph::GraphFile file;
    const auto use = weights == "sesync" ? vloc::posegraph::InformationUse::kSeSyncBlocks
                                         : vloc::posegraph::InformationUse::kChi2;
    if (!vloc::posegraph::ReadGraphFile(args.positional()[0], &file, &error, use)) {
      std::cerr << "vloc_posegraph: " << error << "\n";
      return 1;
    }
    if (!file.repair_report.empty()) std::cerr << "vloc_posegraph: " << file.repair_report << "\n";
    std::cout << args.positional()[0] << ": " << vloc::posegraph::GraphFormatName(file.format) << ", "
              << file.dimension << "D, " << file.num_nodes() << " poses, " << file.num_edges() << " edges"
              << (file.had_vertices ? "" : " (no vertices: started from chained odometry)") << "\n";
    const auto report = vloc::posegraph::OptimizeGraphFile(&file, options);
    std::cout << report.BriefReport() << "\n";
    if (!report.solver.usable) return 1;
    if (!vloc::posegraph::WriteGraphFile(args.Get("out"), file, &error)) {
      std::cerr << "vloc_posegraph: " << error << "\n";
      return 1;
    }
    std::cout << "wrote " << args.Get("out") << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "vloc_posegraph: " << e.what() << "\n";
    return 1;
  }
}
