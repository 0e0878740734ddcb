#pragma once
// A PDS3 camera product as the tools take it (vloc_stereo, vloc_match):
// the image and its label, from any of the forms the archives and the
// public galleries serve:
//   X.IMG              the label attached, or a detached X.LBL beside it
//   X.LBL              with the .IMG its ^IMAGE names, else a browse image
//                      beside it (X.jpg / X.png / X.IMG.png, ...M1.LBL ->
//                      ...M_.jpg)
//   X.jpg / X.png      a browse image, with its label X.LBL (X.IMG.png ->
//                      X.LBL, ...M_.jpg -> ...M1.LBL) beside it
// and a stereo pair of them rectified epipolarly through their camera
// models (JPL's marscahv: LineariseStereoPair + RectificationMaps).

#include <string>

#include <opencv2/core.hpp>

#include "vloc/common/cahvor.h"
#include "vloc/common/pds_label.h"

namespace vloc {

struct PdsProduct {
  PdsCameraLabel label;
  std::string label_path;  // the file the label was read from
  std::string image_path;  // the file the pixels were read from
  cv::Mat image;           // CV_8UC1 (16-bit data scaled: 12-bit / 16, else / 256; colour browse images made grey)
};

// True for a path ReadPdsProduct takes as a PDS product: .IMG / .LBL, or an
// image file with a label beside it.
bool IsPdsProductPath(const std::string& path);

// The browse image beside a detached label, or "".
std::string FindPdsBrowseImage(const std::string& label_path);

// Reads a product (see above). False with one line in *error naming the
// file and the keyword (or the missing file). Image sizes over
// max_image_side are refused before decoding.
bool ReadPdsProduct(const std::string& path, PdsProduct* out, std::string* error, int max_image_side = 16384);

// A stereo pair after epipolar rectification.
struct RectifiedPdsPair {
  bool linearised = false;       // false: the models were already a common CAHV pair, images kept as they are
  CahvKind raw_kind[2] = {CahvKind::kCahv, CahvKind::kCahv};  // the input models' kinds (left, right)
  RectifiedStereoPair models;    // the common CAHV pair (the input models when !linearised)
  cv::Mat left, right;           // CV_8UC1, rectified (0 where no raw pixel)
  double max_model_row_error_px = 0;  // px, largest row difference the rectified models give a point seen by
                                      // both (over a grid of the left image at range_m): ~0 by construction
  double max_raw_row_error_px = 0;    // px, the same through the raw models (what rectification removes)
};

// Rectifies `left` and `right` (CV_8UC1, the sizes the models are for)
// through their models unless they already share A, H and V (CAHV with
// the same vectors within 1e-9): bilinear resampling; CAHVORE's rays are
// taken at range_m. False with one line in *error when the models cannot
// make a stereo pair (centres coincide, axes opposed).
bool RectifyPdsPair(const CahvModel& left_model, const CahvModel& right_model, const cv::Mat& left,
                    const cv::Mat& right, double range_m, RectifiedPdsPair* out, std::string* error);

// What the tools do with two products: reads both (ReadPdsProduct) and,
// when `rectify`, rectifies them (RectifyPdsPair at range_m); otherwise the
// images are kept as read (linearised false, no row errors). False with one
// line in *error naming the file and the keyword.
bool ReadPdsStereoPair(const std::string& left_path, const std::string& right_path, bool rectify, double range_m,
                       RectifiedPdsPair* out, std::string* error);

// The pair's rectification as YAML lines (the tools print it):
// rectification: {linearised: ..., raw_row_error_max_px: ..., model_row_error_max_px: ..., raw_models: [...]}
std::string DescribeRectification(const RectifiedPdsPair& pair);

// Writes PREFIX_left.png and PREFIX_right.png; false with one line in *error.
bool WriteRectifiedPair(const RectifiedPdsPair& pair, const std::string& prefix, std::string* error);

}  // namespace vloc
