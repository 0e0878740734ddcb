// traverse_graph: the traverse pose graph (MRPT) over every site.
//   traverse_graph --config config/procs/traverse_graph.yaml [--state-dir DIR] [--lcm-url URL]
#include <iostream>

#include "traverse_graph_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"traverse_graph", {"state-dir"}, true,
                                   "--config config/procs/traverse_graph.yaml [--state-dir DIR] [--lcm-url URL]"});
  if (!setup) return 1;
  std::string note;
  const auto loaded = vloc::LoadProcessOptions<vloc::TraverseGraphProcOptions>(
      *setup, [&](vloc::TraverseGraphProcOptions& o) { o.graph_path = vloc::ResolveStatePath(o.graph_path, setup->args, &note); });
  if (!loaded) return 1;
  const vloc::TraverseGraphProcOptions& options = *loaded;
  if (!note.empty()) LOG(WARNING) << "traverse_graph: " << note;
  vloc::TraverseGraphAdapter adapter(*setup->transport, options);
  std::string error;
  if (!adapter.Restore(&error)) {
    std::cerr << "traverse_graph: " << error << "\n";
    return 1;
  }
  LOG(INFO) << "traverse_graph: waiting for " << options.dr_channel << " and " << options.visual_channel;
  const int rc = vloc::RunUntilSignal(*setup->transport, 200);
  LOG(INFO) << "traverse_graph: " << adapter.StatusLine();
  return rc;
}
