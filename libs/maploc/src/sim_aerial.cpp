// The simulated terrain rendered from above (sim_aerial.h).
#include "vloc/maploc/sim_aerial.h"

#include <cmath>
#include <stdexcept>

namespace vloc::maploc {

namespace {

// Mean radiance and height over a cell from supersample^2 samples.
void SampleCell(const sim::Terrain& t, double x0, double y0, double cell, int n, float* gray, float* height) {
  double sum_l = 0, sum_z = 0;
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      const double x = x0 + (a + 0.5) * cell / n, y = y0 - (b + 0.5) * cell / n;
      sum_l += t.Radiance(x, y, cell / n);
      sum_z += t.Height(x, y);
    }
  *gray = static_cast<float>(sum_l / (n * n));
  *height = static_cast<float>(sum_z / (n * n));
}

}  // namespace

MapRaster RenderAerialMap(sim::Terrain* terrain, const sim::Region& region, const AerialRenderOptions& o) {
  if (!(o.m_per_px > 0) || o.supersample < 1 || !(region.x_max > region.x_min) || !(region.y_max > region.y_min))
    throw std::invalid_argument("RenderAerialMap: need a non-empty region, m_per_px > 0, supersample >= 1");
  const double old_azimuth = terrain->options().sun_azimuth_deg, old_elevation = terrain->options().sun_elevation_deg;
  terrain->SetSun(o.sun_azimuth_deg, o.sun_elevation_deg);
  MapRaster map;
  map.m_per_px = o.m_per_px;
  map.x_min = region.x_min;
  map.y_max = region.y_max;
  const int cols = static_cast<int>(std::ceil((region.x_max - region.x_min) / o.m_per_px));
  const int rows = static_cast<int>(std::ceil((region.y_max - region.y_min) / o.m_per_px));
  map.gray.create(rows, cols, CV_32F);
  map.height.create(rows, cols, CV_32F);
  map.valid.create(rows, cols, CV_8U);
  const double gain = 200.0 / terrain->options().albedo_mean;
#pragma omp parallel for schedule(dynamic, 8) num_threads(terrain->options().num_threads)
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double x0 = region.x_min + c * o.m_per_px, y0 = region.y_max - r * o.m_per_px;
      float l = 0, z = 0;
      SampleCell(*terrain, x0, y0, o.m_per_px, o.supersample, &l, &z);
      const bool inside = terrain->Contains(x0 + 0.5 * o.m_per_px, y0 - 0.5 * o.m_per_px);
      map.gray.at<float>(r, c) = inside ? static_cast<float>(std::min(255.0, gain * l)) : 0.f;
      map.height.at<float>(r, c) = inside ? z : 0.f;
      map.valid.at<uint8_t>(r, c) = inside ? 255 : 0;
    }
  terrain->SetSun(old_azimuth, old_elevation);
  if (!o.with_height) map.height.release();
  return map;
}

}  // namespace vloc::maploc
