// vloc_eval: accuracy of a recorded run against the ground truth in its log.
//   vloc_eval LOG.lcmlog --out DIR [--terrain config/sim/terrain.yaml] [--navcam config/navcam.yaml]
//             [--ortho-m-per-px 0.08] [--scripts DIR] [--no-plots] [--quiet]
// Writes DIR/report.md, sites.csv, pairs.csv, uav.csv, with --terrain (a
// simulated run) DIR/ortho.png + ortho.pgw (the terrain under the traverse),
// with --terrain and --navcam DIR/tiepoints.csv (every tie point against the
// terrain: tie_truth.h) and shared_view.csv (shared_view.h), then runs scripts/plot_eval.py for the PNG plots;
// prints a short accuracy table.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "eval.h"
#include "ortho.h"
#include "shared_view.h"
#include "tie_truth.h"
#include "vloc/common/command_line.h"
#include "vloc/common/options.h"

namespace fs = std::filesystem;

// scripts/ next to the source tree: --scripts, $VLOC_SOURCE_DIR/scripts, or
// up from the executable (<build>/bin/vloc_eval -> <source>/scripts).
static std::string FindScripts(const vloc::CommandLine& args, const char* argv0) {
  if (args.Has("scripts")) return args.Get("scripts");
  if (const char* src = std::getenv("VLOC_SOURCE_DIR")) return std::string(src) + "/scripts";
  std::error_code ec;
  fs::path p = fs::canonical(fs::path("/proc/self/exe"), ec);
  if (ec) p = fs::absolute(argv0);
  for (fs::path dir = p.parent_path(); !dir.empty() && dir != dir.root_path(); dir = dir.parent_path())
    if (fs::exists(dir / "scripts" / "plot_eval.py")) return (dir / "scripts").string();
  return "scripts";
}

// Every TIE_POINTS set against the terrain of a simulated run (tiepoints.csv) and the view each pair of sites
// shares (shared_view.csv), and their summary lines (also appended to report.md).
static std::string CheckTiePointsAgainstTerrain(const vloc::eval::LogData& data, const std::string& terrain_config,
                                                const std::string& navcam_config, const std::string& out) {
  const YAML::Node root = vloc::LoadYamlFile(terrain_config);
  const auto terrain_options =
      vloc::LoadOptionsFile<vloc::sim::TerrainOptions>(terrain_config, root["terrain"] ? "terrain" : "");
  const auto navcam = vloc::LoadOptionsFile<vloc::NavcamModel>(navcam_config);
  const vloc::sim::Terrain terrain(terrain_options);
  std::vector<vloc::eval::TieTruthPoint> points;
  const auto rows = vloc::eval::CheckTiePoints(data.tie_points, data.gt, navcam, terrain, {}, &points);
  vloc::eval::WriteTieTruth(rows, points, out);
  const auto shared = vloc::eval::SharedViews(data.gt, data.tie_points.front().previous_pointing, navcam, terrain);
  vloc::eval::WriteSharedViews(shared, out);
  const std::string summary =
      vloc::eval::TieTruthSummary(rows) + vloc::eval::SharedViewSummary(shared, data.tie_points);
  std::ofstream(out + "/report.md", std::ios::app) << "\n" << summary;
  return summary;
}

int main(int argc, char** argv) {
  vloc::CommandLine args;
  std::string error;
  if (!args.Parse(argc, argv, {"out", "terrain", "navcam", "ortho-m-per-px", "scripts", "no-plots", "quiet", "help"}, &error) || args.Has("help") ||
      args.positional().size() != 1 || !args.Has("out")) {
    if (!error.empty()) std::cerr << "vloc_eval: " << error << "\n";
    std::cerr << "usage: vloc_eval LOG.lcmlog --out DIR [--terrain config/sim/terrain.yaml] [--navcam config/navcam.yaml]"
                 " [--ortho-m-per-px M]"
                 " [--scripts DIR] [--no-plots] [--quiet]\n";
    return 1;
  }
  const std::string out = args.Get("out");
  std::string read_problem;  // the log stopped early: report on what was read, then fail
  try {
    const vloc::eval::LogData data = vloc::eval::ReadLog(args.positional()[0], !args.Has("quiet"));
    if (data.messages == 0) throw std::runtime_error(data.read_problem);
    const vloc::eval::Summary summary = vloc::eval::Evaluate(data);
    if (summary.sites.empty() && data.uav_state.empty())
      throw std::runtime_error(args.positional()[0] + " holds " + std::to_string(data.messages) +
                               " messages but no rover sites with ground truth and no UAV_STATE: nothing to evaluate");
    read_problem = data.read_problem;
    vloc::eval::WriteOutputs(summary, out);
    std::filesystem::remove(out + "/ortho.png");  // a stale background must not show under another run
    std::filesystem::remove(out + "/ortho.pgw");
    if (args.Has("terrain") && !args.Has("no-plots") && !summary.sites.empty()) {
      vloc::eval::OrthoOptions ortho;
      ortho.terrain_config = args.Get("terrain");
      ortho.m_per_px = args.GetDouble("ortho-m-per-px", ortho.m_per_px);
      std::string ortho_error;
      if (!vloc::eval::WriteOrthoimage(summary, ortho, out, &ortho_error))
        std::cerr << "vloc_eval: no orthoimage under the map: " << ortho_error << "\n";
    }
    std::cout << vloc::eval::ShortTable(summary);
    if (args.Has("terrain") && args.Has("navcam") && !data.tie_points.empty())
      std::cout << CheckTiePointsAgainstTerrain(data, args.Get("terrain"), args.Get("navcam"), out);
    if (data.decode_failures)
      std::cerr << "vloc_eval: " << data.decode_failures << " messages could not be decoded (skipped)\n";
  } catch (const std::exception& e) {
    std::cerr << "vloc_eval: " << e.what() << "\n";
    return 1;
  }
  if (!args.Has("no-plots")) {
    const std::string script = FindScripts(args, argv[0]) + "/plot_eval.py";
    // Debian's python3 carries python3-numpy/-matplotlib (scripts/install_deps.sh);
    // a python3 earlier on PATH (pyenv, venv) may not. $VLOC_PYTHON overrides.
    std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
    if (const char* p = std::getenv("VLOC_PYTHON")) python = p;
    const std::string cmd = python + " '" + script + "' --out '" + out + "'";
    if (std::system(cmd.c_str()) != 0)
      std::cerr << "vloc_eval: plotting failed (" << cmd << "); the report and CSVs are written\n";
  }
  std::cout << "report: " << out << "/report.md\n";
  if (!read_problem.empty()) {
    std::cerr << "vloc_eval: " << read_problem << "\n";
    return 1;
  }
  return 0;
}
