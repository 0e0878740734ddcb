// vloc_console: the operator's web console. Serves procs/vloc_console/web
// and bridges LCM to the browsers over a WebSocket (map, images and tie
// points, UAV, processes); acting commands (process orders, manual tie
// points) need the token when one is set.
//   vloc_console [--config config/procs/vloc_console.yaml] [--lcm-url URL] [--bind ADDR] [--port N]
//                [--token T | $VLOC_CONSOLE_TOKEN] [--web-root DIR]
#include <cstdlib>
#include <iostream>

#include "console_adapter.h"
#include "vloc/common/logging.h"
#include "vloc/common/options.h"
#include "vloc/lcm_io/process.h"

namespace {

// Command-line overrides of the server options.
void ApplyOverrides(const vloc::CommandLine& args, vloc::ConsoleProcOptions& o) {
  if (args.Has("bind")) o.server.bind_address = args.Get("bind");
  if (args.Has("port")) o.server.port = args.GetInt("port", o.server.port);
  if (args.Has("web-root")) o.server.web_root = args.Get("web-root");
  if (const char* env = std::getenv("VLOC_CONSOLE_TOKEN")) o.server.token = env;
  if (args.Has("token")) o.server.token = args.Get("token");
}

}  // namespace

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  auto setup = vloc::SetupProcess(
      argc, argv,
      {"vloc_console",
       {"bind", "port", "token", "web-root"},
       false,
       "[--config config/procs/vloc_console.yaml] [--bind ADDR] [--port N] [--token T] [--web-root DIR] "
       "[--lcm-url URL]"});
  if (!setup) return 1;
  const auto loaded = vloc::LoadProcessOptions<vloc::ConsoleProcOptions>(
      *setup, [&](vloc::ConsoleProcOptions& o) { ApplyOverrides(setup->args, o); });
  if (!loaded) return 1;
  vloc::ConsoleServer server(loaded->server);
  vloc::ConsoleAdapter adapter(*setup->transport, server, *loaded);
  std::string error;
  if (!adapter.LoadOrthoimage(&error) || !server.Start(&error)) {
    std::cerr << "vloc_console: " << error << "\n";
    return 1;
  }
  adapter.Subscribe();
  LOG(INFO) << "vloc_console: serving http://" << loaded->server.bind_address << ":" << server.port() << "/ ("
            << (loaded->server.token.empty() ? "no token" : "token required to act") << ")";
  const int rc = vloc::RunUntilSignal(*setup->transport, 5, [&] { server.Poll(); });
  LOG(INFO) << "vloc_console: " << adapter.StatusLine();
  return rc;
}
