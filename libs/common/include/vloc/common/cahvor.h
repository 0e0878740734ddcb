#pragma once
// The camera models of JPL's planetary cameras (MER, MSL, M2020 Navcam and
// Hazcam products carry them in their PDS labels), beside vloc's pinhole:
//
//   CAHV    Yakimovsky & Cunningham, "A system for extracting
//           three-dimensional measurements from a stereo pair of TV
//           cameras", CGIP 7 (1978): a linear (pinhole) model as four
//           vectors. C: the centre (m); A: the unit axis; H = hs H' + hc A and
//           V = vs V' + vc A (px). A point P lands on
//             x = (P - C).H / (P - C).A,   y = (P - C).V / (P - C).A.
//   CAHVOR  Gennery, "Least-squares camera calibration including lens
//           distortion and automatic editing of calibration points", in
//           Calibration and Orientation of Cameras in Computer Vision,
//           Springer 2001: CAHV plus radial distortion about the optical
//           axis O with R = (r0, r1, r2). With p = P - C, zeta = p.O,
//           lambda = p - zeta O, tau = |lambda|^2 / zeta^2 and
//           mu = r0 + r1 tau + r2 tau^2, the point is projected by CAHV as
//           p' = p + mu lambda.
//   CAHVORE Gennery, "Generalized camera calibration including fish-eye
//           lenses", IJCV 68(3) (2006): CAHVOR plus a moving entrance pupil
//           (E = (e0, e1, e2): the pupil sits at C + s O with
//           s = (theta / sin(theta) - 1)(e0 + e1 theta^2 + e2 theta^4) for a
//           ray theta off O) and a linearity L between fisheye (0) and
//           perspective (1): chi = tan(L theta) / L (L > 0), sin(L theta) / L
//           (L < 0), theta (L = 0); the distorted chi' = chi (1 + r0 + r1 chi^2
//           + r2 chi^4) is what CAHV projects.
//
// The iterations (CAHVOR's back-projection: Newton on the quintic in
// 1 - mu; CAHVORE's projection: Newton on theta; its back-projection:
// Newton on chi) follow JPL's cmod library (Litwin) as ported in NASA-AMMOS
// CameraModelUtilsJS and the NASA Vision Workbench's CAHVORModel /
// CAHVOREModel, with tolerances tight enough for a 1e-9 px round trip.
//
// Frames: a model lives in its REFERENCE frame (for MSL: the rover
// navigation frame, x forward, y right, z down); pixels are (sample, line)
// = (x right, y down) from the centre of the first pixel, as in the labels.
//
// Epipolar rectification (what JPL's marscahv does): LineariseStereoPair
// replaces a pair of CAHVOR/CAHVORE models by two CAHV models with the same
// A, H and V and their own centres; RectificationMaps gives cv::remap
// tables from each raw image to its rectified image.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "vloc/common/camera.h"
#include "vloc/common/pose.h"

namespace vloc {

enum class CahvKind { kCahv, kCahvor, kCahvore };

// "CAHV", "CAHVOR", "CAHVORE".
const char* CahvKindName(CahvKind kind);

// A ray out of a camera: where it starts (the entrance pupil: C, except for
// CAHVORE) and its unit direction, in the model's reference frame.
struct CameraRay {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();     // m
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  // unit
  Eigen::Vector3d At(double range) const { return origin + range * direction; }
};

// One CAHV / CAHVOR / CAHVORE camera. Fields a kind does not use are ignored
// (CAHV: O, R, E, linearity; CAHVOR: E, linearity).
struct CahvModel {
  CahvKind kind = CahvKind::kCahv;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();       // m, centre (entrance pupil on the axis)
  Eigen::Vector3d a = Eigen::Vector3d::UnitX();      // unit, camera axis
  Eigen::Vector3d h = Eigen::Vector3d(0, 1000, 0);   // px, horizontal: hs H' + hc A
  Eigen::Vector3d v = Eigen::Vector3d(0, 0, 1000);   // px, vertical: vs V' + vc A
  Eigen::Vector3d o = Eigen::Vector3d::UnitX();      // unit, optical axis of the distortion
  Eigen::Vector3d r = Eigen::Vector3d::Zero();       // radial distortion r0, r1, r2
  Eigen::Vector3d e = Eigen::Vector3d::Zero();       // m, entrance-pupil terms e0, e1, e2
  double linearity = 1.0;                            // CAHVORE: 1 perspective, 0 fisheye, else general

  // Finite vectors, A and O unit (within 1e-6, then normalised by the
  // reader), hs, vs > 1 px, H' and V' not parallel, O within 90 degrees of A.
  bool Check(std::string* error) const;

  // Derived CAHV quantities (Yakimovsky & Cunningham): focal lengths and
  // principal point, px.
  double hs() const;
  double vs() const;
  double hc() const;
  double vc() const;

  // Pixel of a point in the reference frame; nullopt behind the camera, at
  // its centre, or (CAHVORE) beyond the angle the linearity allows.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_ref) const;
  // The ray of a pixel; nullopt when the distortion cannot be inverted there
  // (far outside the calibrated field).
  std::optional<CameraRay> BackProject(const Eigen::Vector2d& px) const;

  // The CAHV part alone (C, A, H, V): the linear model of the same camera.
  CahvModel LinearPart() const;
  // The frame of the linear part: camera z = A, x = H', y = A x H'
  // (orthonormal: V' = y up to the model's skew), in the reference frame.
  Pose3 ReferenceFromCamera() const;
  // A CAHV model equal to a pinhole camera placed by ref_from_camera.
  static CahvModel FromPinhole(const PinholeCamera& pinhole, const Pose3& ref_from_camera);
};

// Two CAHV models with the same A, H and V (only C differs): a row of one
// image is the same row of the other for every point (epipolar-rectified).
struct RectifiedStereoPair {
  CahvModel left, right;
  cv::Size size;  // px, of both rectified images
};

// Linearises a pair (any kinds) to a common CAHV pair, as marscahv does:
// H' along the baseline C_right - C_left (the sign of the left H'), A the
// mean of both axes made perpendicular to it, V' = A x H'; hs and vs the
// means of both models', and hc, vc putting A at the centre of a rectified
// image of `size`. Throws std::invalid_argument for a pair whose centres
// coincide or whose axes are opposed.
RectifiedStereoPair LineariseStereoPair(const CahvModel& left, const CahvModel& right, cv::Size size);

// cv::remap tables (CV_32FC1) from a raw image of `raw` to the rectified
// image of `rectified` (size `size`): map(x, y) is the raw pixel the
// rectified pixel's ray falls on, -1 where there is none. Rays are taken at
// `range_m` (only CAHVORE's moving pupil makes the range matter).
void RectificationMaps(const CahvModel& raw, const CahvModel& rectified, cv::Size size, double range_m, cv::Mat* map_x,
                       cv::Mat* map_y);

}  // namespace vloc
