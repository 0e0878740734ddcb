#include "vloc/features/tile_registration.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "vloc/common/options.h"
#include "vloc/features/template_ncc.h"

namespace vloc {

void TileRegistrationOptions::Visit(OptionsReader& r) {
  r.Optional("reduction", &reduction, "both images are reduced by this factor before correlation", AtLeast(1));
  r.Optional("tile_px", &tile_px, "px (reduced), width of a correlated tile", AtLeast(8));
  r.Optional("tile_height_px", &tile_height_px, "px (reduced), height of a correlated tile (0 = tile_px)",
             Is(0) || AtLeast(3));
  r.Optional("min_coverage", &min_coverage, "fraction of a tile that must be valid", InLeftOpen(0, 1));
  r.Optional("min_tile_std", &min_tile_std, "grey level, flatter tiles are not searched");
  r.Optional("min_ncc", &min_ncc, "correlation peak needed", InRange(-1, 1));
  r.Optional("min_peak_margin", &min_peak_margin, "peak minus the best score away from it", NonNegative());
}

bool TileRegistrationOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {

// Vertex of the parabola through (-1, a), (0, b), (1, c).
double ParabolaPeak(double a, double b, double c) {
  const double den = a - 2 * b + c;
  if (std::abs(den) < 1e-12) return 0;
  return std::clamp(0.5 * (a - c) / den, -0.5, 0.5);
}

}  // namespace

std::vector<TileMatch> RegisterTiles(const cv::Mat& moving, const cv::Mat& moving_mask, const cv::Mat& fixed,
                                     double search_radius_px, const TileRegistrationOptions& o) {
  std::vector<TileMatch> out;
  if (moving.empty() || fixed.empty() || moving.type() != CV_8UC1 || fixed.type() != CV_8UC1) return out;
  const double f = o.reduction;
  cv::Mat m, fx, mask;
  cv::resize(moving, m, cv::Size(), 1 / f, 1 / f, cv::INTER_AREA);
  cv::resize(fixed, fx, cv::Size(), 1 / f, 1 / f, cv::INTER_AREA);
  if (moving_mask.empty()) {
    mask = cv::Mat(m.size(), CV_32F, cv::Scalar(1));
  } else {
    cv::Mat mf;
    moving_mask.convertTo(mf, CV_32F, 1.0 / 255);
    cv::resize(mf, mask, m.size(), 0, 0, cv::INTER_AREA);
  }
  m.convertTo(m, CV_32F);
  fx.convertTo(fx, CV_32F);
  const int T = o.tile_px, TH = o.tile_height_px > 0 ? o.tile_height_px : o.tile_px, R = std::max(1, static_cast<int>(std::ceil(search_radius_px / f)));
  for (int y = 0; y + TH <= m.rows; y += std::max(1, TH / 2)) {
    for (int x = 0; x + T <= m.cols; x += T / 2) {
      const cv::Rect tile(x, y, T, TH);
      if (cv::mean(mask(tile))[0] < o.min_coverage) continue;
      cv::Scalar mean, stddev;
      cv::meanStdDev(m(tile), mean, stddev);
      if (stddev[0] < o.min_tile_std) continue;
      const cv::Rect search = cv::Rect(x - R, y - R, T + 2 * R, TH + 2 * R) & cv::Rect(0, 0, fx.cols, fx.rows);
      if (search.width < T + 2 || search.height < TH + 2) continue;
      cv::Mat score;
      MatchTemplateNcc(fx(search), m(tile), &score);
      double best;
      cv::Point peak;
      cv::minMaxLoc(score, nullptr, &best, nullptr, &peak);
      if (!(best >= o.min_ncc)) continue;
      // A peak on the border of the search may be the slope of one outside.
      if (peak.x == 0 || peak.y == 0 || peak.x == score.cols - 1 || peak.y == score.rows - 1) continue;
      cv::Mat away = score.clone();
      cv::rectangle(away, cv::Rect(peak.x - 2, peak.y - 2, 5, 5), cv::Scalar(-2), cv::FILLED);
      double second;
      cv::minMaxLoc(away, nullptr, &second);
      if (best - second < o.min_peak_margin) continue;
      const float* r0 = score.ptr<float>(peak.y);
      const double sx = ParabolaPeak(r0[peak.x - 1], r0[peak.x], r0[peak.x + 1]);
      const double sy = ParabolaPeak(score.at<float>(peak.y - 1, peak.x), r0[peak.x], score.at<float>(peak.y + 1, peak.x));
      TileMatch tm;
      const double cx = x + 0.5 * T, cy = y + 0.5 * TH;  // reduced px, tile centre (pixel-edge convention)
      tm.moving_px = Eigen::Vector2d(cx * f - 0.5, cy * f - 0.5);
      tm.fixed_px = Eigen::Vector2d((search.x + peak.x + sx + 0.5 * T) * f - 0.5,
                                    (search.y + peak.y + sy + 0.5 * TH) * f - 0.5);
      tm.ncc = best;
      tm.margin = best - second;
      out.push_back(tm);
    }
  }
  return out;
}

}  // namespace vloc
