#pragma once
// Masked correlation building blocks of the map registration (internal).
#include <opencv2/core.hpp>

namespace vloc::maploc::internal {

// Difference-of-Gaussians of a band with holes: low pass (sigma_lp_px) then
// minus its own blur (sigma_hp_px), both normalised by the blurred mask so
// unseen cells do not pull the values toward 0. `mask`: CV_32F 0/1. The
// result is 0 where the mask is 0.
cv::Mat MaskedHighPass(const cv::Mat& band, const cv::Mat& mask, double sigma_hp_px, double sigma_lp_px);

// Standard deviation of `band` over mask > 0 (0 when fewer than 2 cells).
double MaskedStd(const cv::Mat& band, const cv::Mat& mask);

// ZNCC of the masked template at every placement inside `image` (result
// (W - w + 1) x (H - h + 1), CV_32F); placements where less than
// `min_overlap` of the template's mask falls on valid image cells, or with
// a flat image window, score -1. `image_valid`, `templ_mask`: CV_32F 0/1.
cv::Mat MaskedZncc(const cv::Mat& image, const cv::Mat& image_valid, const cv::Mat& templ, const cv::Mat& templ_mask,
                   double min_overlap);

// `src` rotated by `angle` (rad, counter-clockwise as seen on a north-up
// raster) about `centre` (px), same size.
cv::Mat RotateAbout(const cv::Mat& src, double angle, const cv::Point2d& centre, int interpolation);

}  // namespace vloc::maploc::internal
