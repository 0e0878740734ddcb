// The lens self-calibrated from a survey's own height ties (survey_runner.h, lens_search.h).
#include <fstream>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "vloc/mosaic/survey_runner.h"

namespace vloc::mosaic {

bool SelfCalibrateLens(const SurveyOptions& options, const std::vector<std::string>& paths, std::ostream* out,
                       std::ostream* err, PinholeCamera* camera, LensSearch* search) {
  SurveyOptions first = options;
  first.keep_height_observations = true;
  first.oblique_fallback = false;
  SurveyRunner run(first, nullptr, err);
  if (!run.LoadPhotos(paths) || !run.ChooseCamera() || !run.ChooseFirstHeight()) return false;
  run.RegisterAll();
  const HeightObservations* observations = run.mosaicker().height_observations();
  *camera = run.mosaicker_options().camera;
  *search = SearchRadialDistortion(*observations, *camera, first.mosaicker.height_graph);
  if (!search->ok) {
    if (err)
      *err << "uav_mosaic_files: the lens cannot be self-calibrated: " << search->why
           << (first.mosaicker.height_graph.ties <= 0 ? " (height_graph.ties is 0 in the settings)" : "") << "\n";
    return false;
  }
  if (out) {
    *out << "lens self-calibration: " << run.registered() << " of " << run.frames().size() << " photos registered, "
         << search->pairs << " height links and ties re-measured (" << search->dropped << " outliers left out); tie "
         << "residual RMS (sigmas) by k1:";
    for (const cv::Point2d& c : search->curve) *out << " " << c.x << ":" << std::setprecision(3) << c.y;
    *out << std::setprecision(6) << "\nlens self-calibration: k1 " << search->k1 << " (residual " << search->residual
         << " sigmas; " << search->residual_as_run << " at the run's k1 " << camera->k1 << ")\n";
  }
  camera->k1 = search->k1;
  return true;
}

bool WriteCameraFile(const std::string& path, const PinholeCamera& camera, const std::string& comment,
                     std::string* error) {
  std::ofstream f(path);
  if (!f) {
    *error = "cannot write " + path;
    return false;
  }
  std::istringstream lines(comment);
  for (std::string line; std::getline(lines, line);) f << "# " << line << "\n";
  f << std::setprecision(10) << "width: " << camera.width << "\nheight: " << camera.height << "\nfx: " << camera.fx
    << "\nfy: " << camera.fy << "\ncx: " << camera.cx << "\ncy: " << camera.cy << "\nk1: " << camera.k1
    << "\nk2: " << camera.k2 << "\np1: " << camera.p1 << "\np2: " << camera.p2 << "\nk3: " << camera.k3 << "\n";
  if (!f) *error = "cannot write " + path;
  return static_cast<bool>(f);
}

}  // namespace vloc::mosaic
