// traverse_graph: the traverse pose graph (MRPT) over every site.
//   traverse_graph --config config/procs/traverse_graph.yaml [--lcm-url URL]
#include <iostream>

#include "traverse_graph_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(argc, argv,
                                  {"traverse_graph", {}, false, "[--config config/procs/traverse_graph.yaml]"});
  if (!setup) return 1;
  vloc::TraverseGraphProcOptions options;
  try {
    std::string echo;
    options = vloc::LoadOptions<vloc::TraverseGraphProcOptions>(setup->config, setup->config_path, &echo);
    LOG(INFO) << "traverse_graph options:\n" << echo;
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
