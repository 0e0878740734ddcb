#pragma once
// Synthetic nadir imagery for the mosaic tests and benchmark: a textured
// ground image (north up) and frames rendered from a known position, height
// and yaw by an exact similarity, so every frame-to-frame transform is known.

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <vector>

#include "vloc/mosaic/uav_mosaicker.h"

namespace vloc::mosaic::testing {

struct SyntheticGround {
  cv::Mat image;        // BGR, north up
  double mpp = 0.05;    // m/px
  // ground px of world (east, north) metres; world (0,0) = image centre.
  cv::Point2d PixelOf(double east, double north) const {
    return {east / mpp + image.cols / 2.0, -north / mpp + image.rows / 2.0};
  }
};

// Multi-scale random texture with blobs and rectangles (fields, roofs).
inline SyntheticGround MakeGround(int size_px, double mpp, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat acc(size_px, size_px, CV_32FC3, cv::Scalar::all(0));
  for (int octave = 0; octave < 8; ++octave) {
    const int n = std::max(4, size_px >> (9 - octave));
    cv::Mat small(n, n, CV_32FC3);
    rng.fill(small, cv::RNG::UNIFORM, cv::Scalar::all(-1), cv::Scalar::all(1));
    cv::Mat up;
    cv::resize(small, up, acc.size(), 0, 0, cv::INTER_CUBIC);
    acc += up * (50.0 / (1 + 0.2 * octave));
  }
  cv::Mat img;
  acc.convertTo(img, CV_8UC3, 1.0, 128.0);
  const int shapes = size_px * size_px / 1500;
  for (int i = 0; i < shapes; ++i) {
    const cv::Point c(rng.uniform(0, size_px), rng.uniform(0, size_px));
    const cv::Scalar colour(rng.uniform(0, 255), rng.uniform(0, 255), rng.uniform(0, 255));
    if (i % 2) {
      cv::circle(img, c, rng.uniform(2, 14), colour, -1, cv::LINE_AA);
    } else {
      const cv::RotatedRect r(c, cv::Size2f(rng.uniform(4, 40), rng.uniform(4, 30)), rng.uniform(0, 180));
      cv::Point2f pts[4];
      r.points(pts);
      std::vector<cv::Point> poly(pts, pts + 4);
      cv::fillConvexPoly(img, poly, colour, cv::LINE_AA);
    }
  }
  return {img, mpp};
}

struct NadirCamera {
  cv::Size size{640, 360};
  double f = 500.0;    // px
  double cx() const { return (size.width - 1) / 2.0; }
  double cy() const { return (size.height - 1) / 2.0; }
};

// ground px = M * (u, v, 1) for a camera above (east, north) at height h with
// yaw (rad, counter-clockwise from north-up: image up = heading).
inline cv::Matx23d GroundFromView(const SyntheticGround& g, const NadirCamera& cam, double east, double north,
                                  double height, double yaw) {
  const double k = height / cam.f / g.mpp, c = std::cos(yaw), s = std::sin(yaw);
  const cv::Point2d o = g.PixelOf(east, north);
  // dx = (u - cx) k, dy = (v - cy) k in image axes; ground px: x = o.x + c dx + s dy, y = o.y - s dx + c dy.
  return {k * c, k * s, o.x - k * (c * cam.cx() + s * cam.cy()), -k * s, k * c, o.y - k * (-s * cam.cx() + c * cam.cy())};
}

inline cv::Mat RenderNadir(const SyntheticGround& g, const NadirCamera& cam, double east, double north, double height,
                           double yaw, double noise_sigma = 0.0, uint64_t noise_seed = 1) {
  cv::Mat out;
  cv::warpAffine(g.image, out, GroundFromView(g, cam, east, north, height, yaw), cam.size,
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  if (noise_sigma > 0) {
    cv::Mat noise(out.size(), CV_16SC3);
    cv::RNG rng(noise_seed);
    rng.fill(noise, cv::RNG::NORMAL, 0, noise_sigma);
    cv::Mat o16;
    out.convertTo(o16, CV_16SC3);
    o16 += noise;
    o16.convertTo(out, CV_8UC3);
  }
  return out;
}

// Mosaicker options for frames of `cam`, calibrated from config at `height` m.
inline MosaickerOptions OptionsForCamera(const NadirCamera& cam, double height) {
  MosaickerOptions o;
  o.camera.width = cam.size.width;
  o.camera.height = cam.size.height;
  o.camera.fx = o.camera.fy = cam.f;
  o.camera.cx = cam.cx();
  o.camera.cy = cam.cy();
  o.calibration.source = "config";
  o.calibration.height = height;
  return o;
}

// A simple truth trajectory: position (m), height (m), yaw (rad) at t (s).
struct TruthPose {
  double east, north, height, yaw;
};

}  // namespace vloc::mosaic::testing
