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
  vloc::TraverseGraphProcOptions options;
  try {
    std::string echo;
    options = vloc::LoadOptions<vloc::TraverseGraphProcOptions>(setup->config, setup->config_path, &echo);
    LOG(INFO) << "traverse_graph options:\n" << echo;
    std::string note;
    options.graph_path = vloc::ResolveStatePath(options.graph_path, setup->args, &note);
    if (!note.empty()) LOG(WARNING) << "traverse_graph: " << note;
  } catch (const vloc::ConfigError& e) {
    std::cerr << "traverse_graph: " << e.what() << "\n";
    return 1;
  }
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
