#pragma once
// Normalised cross-correlation of a small template at every position of a
// small search window: what cv::matchTemplate(image, templ, result,
// cv::TM_CCOEFF_NORMED) computes, with its handling of flat windows, summed
// directly. OpenCV correlates through DFTs of the whole window, which on the
// front end's small windows costs 2.7-3.5x this: the LSM start search (53 x
// 11 px over +-4 px) and the tile registration (48 x 4 px tiles over the DR
// gate; bench_frontend BM_TemplateNcc). The values agree with OpenCV's to
// its float rounding (~1e-5), not bit for bit (README, "Where the front
// end's time goes").

#include <opencv2/core.hpp>

namespace vloc {

// result: CV_32FC1 of (image.cols - templ.cols + 1) x (image.rows - templ.rows + 1); image and templ both
// CV_8UC1 or both CV_32FC1, templ no larger than image. A flat template gives 1 everywhere (as OpenCV).
void MatchTemplateNcc(const cv::Mat& image, const cv::Mat& templ, cv::Mat* result);

}  // namespace vloc
