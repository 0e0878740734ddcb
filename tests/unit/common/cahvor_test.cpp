// vloc::CahvModel (CAHV, CAHVOR, CAHVORE) and the linearisation of a pair
// to common CAHV models: round trips over the whole image, CAHV against the
// pinhole it equals, CAHVORE reducing to CAHVOR, the rectified pair's rows,
// and the linearisation error of the Curiosity labels' models (the sol60
// frame's CAHVOR, typed in from its label here; all the shared labels in
// pds_label_test when ../shared/data is present).

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "vloc/common/cahvor.h"

namespace vloc {
namespace {

// NLA_402815759EDR_F0050104NCAM00451M1 (sol 60, left Navcam string A):
// GEOMETRIC_CAMERA_MODEL_PARMS, in ROVER_NAV_FRAME.
CahvModel Sol60Navcam() {
  CahvModel m;
  m.kind = CahvKind::kCahvor;
  m.c = {0.75256, 0.788509, -2.00864};
  m.a = Eigen::Vector3d(-0.964222, 0.184182, -0.190622).normalized();
  m.h = {-714.321, -1112.04, -102.306};
  m.v = {-719.106, 130.979, 1106.97};
  m.o = Eigen::Vector3d(-0.966697, 0.167968, -0.193047).normalized();
  m.r = {0.000274, -0.004951, 0.021485};
  return m;
}

// A CAHVORE with the Navcam's geometry and a wide-angle lens's distortion
// and pupil (the size of MSL Hazcam values), linearity `l`.
CahvModel SyntheticCahvore(double l) {
  CahvModel m = Sol60Navcam();
  m.kind = CahvKind::kCahvore;
  m.r = {-1.5e-3, -0.08, 0.02};
  m.e = {0.0, 0.004, -0.002};
  m.linearity = l;
  return m;
}

double Percentile(std::vector<double> v, double pct) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(pct / 100 * (v.size() - 1) + 0.5))];
}

// Largest |Project(BackProject(px).At(range)) - px| over a 33 x 33 grid of
// a 1024 x 1024 image and three ranges.
double RoundTripMax(const CahvModel& m) {
  double worst = 0;
  for (double range : {1.0, 10.0, 1000.0})
    for (int j = 0; j <= 32; ++j)
      for (int i = 0; i <= 32; ++i) {
        const Eigen::Vector2d px(i * 1023.0 / 32, j * 1023.0 / 32);
        const auto ray = m.BackProject(px);
        EXPECT_TRUE(ray) << px.transpose();
        if (!ray) return 1e9;
        const auto back = m.Project(ray->At(range));
        EXPECT_TRUE(back) << px.transpose();
        if (!back) return 1e9;
        worst = std::max(worst, (*back - px).norm());
      }
  return worst;
}

TEST(Cahv, EqualsThePinholeItIsMadeFrom) {
  PinholeCamera pin;
  pin.fx = 1200, pin.fy = 1190, pin.cx = 500.3, pin.cy = 520.7;
  const Pose3 ref_from_camera = MakePose(0.4, -0.2, 1.9, 0.3, -0.1, 2.0);
  const CahvModel m = CahvModel::FromPinhole(pin, ref_from_camera);
  std::string why;
  ASSERT_TRUE(m.Check(&why)) << why;
  EXPECT_NEAR(m.hs(), 1200, 1e-9);
  EXPECT_NEAR(m.vc(), 520.7, 1e-9);
  for (const Eigen::Vector3d& p_cam : {Eigen::Vector3d(0.3, -0.2, 4.0), Eigen::Vector3d(-1, 2, 7), Eigen::Vector3d(0, 0, 1)}) {
    const auto px = m.Project(ref_from_camera * p_cam);
    ASSERT_TRUE(px);
    EXPECT_NEAR((*px - *pin.ProjectIdeal(p_cam)).norm(), 0, 1e-9);
  }
  EXPECT_TRUE(m.ReferenceFromCamera().isApprox(ref_from_camera, 1e-12));
  EXPECT_FALSE(m.Project(ref_from_camera * Eigen::Vector3d(0, 0, -1))) << "behind the camera";
}

TEST(Cahvor, RoundTripUnderAMicroPixelOverTheImage) {
  const double cahv = RoundTripMax(Sol60Navcam().LinearPart());
  const double cahvor = RoundTripMax(Sol60Navcam());
  std::cout << "round trip max: CAHV " << cahv << " px, CAHVOR (sol60 Navcam) " << cahvor << " px\n";
  EXPECT_LT(cahv, 1e-6);
  EXPECT_LT(cahvor, 1e-6);
}

TEST(Cahvore, RoundTripUnderAMicroPixelForEveryLinearity) {
  for (double l : {1.0, 0.5, 0.0, -0.3}) {
    const double worst = RoundTripMax(SyntheticCahvore(l));
    std::cout << "round trip max: CAHVORE linearity " << l << ": " << worst << " px\n";
    EXPECT_LT(worst, 1e-6) << "linearity " << l;
  }
}

TEST(Cahvore, PerspectiveWithoutPupilShiftIsCahvor) {
  CahvModel e = SyntheticCahvore(1.0);
  e.e.setZero();
  CahvModel r = e;
  r.kind = CahvKind::kCahvor;
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(-5, 1, -1), Eigen::Vector3d(-3, 2.5, 0.5), Eigen::Vector3d(-9, -1, -2)}) {
    const auto pe = e.Project(p), pr = r.Project(p);
    ASSERT_TRUE(pe && pr);
    EXPECT_NEAR((*pe - *pr).norm(), 0, 1e-9);
  }
}

TEST(Cahvore, MovingPupilMakesRangeMatterNear) {
  // The pupil moves along O with the ray's angle: a near and a far point on
  // one ray of the model land on the same pixel, but not a ray from C.
  const CahvModel m = SyntheticCahvore(0.5);
  const auto ray = m.BackProject(Eigen::Vector2d(30, 40));
  ASSERT_TRUE(ray);
  EXPECT_GT((ray->origin - m.c).norm(), 2e-5) << "a corner ray starts off C";
  EXPECT_NEAR((*m.Project(ray->At(0.5)) - *m.Project(ray->At(500))).norm(), 0, 1e-6);
}

TEST(Cahv, CheckNamesWhatIsWrong) {
  CahvModel m = Sol60Navcam();
  std::string why;
  EXPECT_TRUE(m.Check(&why)) << why;
  m.a *= 2;
  EXPECT_FALSE(m.Check(&why));
  EXPECT_NE(why.find("A is not a unit"), std::string::npos) << why;
  m = Sol60Navcam();
  m.h = m.a * 500;
  EXPECT_FALSE(m.Check(&why));
  m = Sol60Navcam();
  m.o = -m.o;
  EXPECT_FALSE(m.Check(&why));
  m = Sol60Navcam();
  m.r[1] = NAN;
  EXPECT_FALSE(m.Check(&why));
}

// The linearisation's error: how far each raw pixel lies from where the
// camera's linear (CAHV) part puts its ray, over the image (every 8 px).
struct LinearisationError {
  double max_px = 0, p95_px = 0;
};
LinearisationError MeasureLinearisation(const CahvModel& m, int width, int height) {
  const CahvModel lin = m.LinearPart();
  std::vector<double> err;
  for (int y = 0; y < height; y += 8)
    for (int x = 0; x < width; x += 8) {
      const auto ray = m.BackProject(Eigen::Vector2d(x, y));
      if (!ray) continue;
      const auto px = lin.Project(ray->At(1000));
      if (px) err.push_back((*px - Eigen::Vector2d(x, y)).norm());
    }
  return {Percentile(err, 100), Percentile(err, 95)};
}

TEST(LineariseStereoPair, RowsAgreeAndTheMapsInvertTheRays) {
  // The Navcam pair: the right camera 0.424 m along the left's H' (MSL
  // Navcam baseline), toed in by 1 degree about V', the same lens.
  const CahvModel left = Sol60Navcam();
  CahvModel right = left;
  const Eigen::Vector3d hp = (left.h - left.hc() * left.a) / left.hs();
  const Eigen::Vector3d vp = (left.v - left.vc() * left.a) / left.vs();
  const Eigen::Matrix3d toe = Eigen::AngleAxisd(-M_PI / 180, vp.normalized()).toRotationMatrix();
  right.c = left.c + 0.424 * hp;
  right.a = toe * left.a, right.h = toe * left.h, right.v = toe * left.v, right.o = toe * left.o;

  const RectifiedStereoPair rect = LineariseStereoPair(left, right, cv::Size(1024, 1024));
  EXPECT_TRUE(rect.left.a.isApprox(rect.right.a) && rect.left.h.isApprox(rect.right.h) && rect.left.v.isApprox(rect.right.v));
  // Every point seen by both lands on one row of both rectified images.
  double worst_dy = 0;
  for (double range : {2.0, 10.0, 100.0})
    for (int j = 0; j <= 16; ++j)
      for (int i = 0; i <= 16; ++i) {
        const auto ray = left.BackProject(Eigen::Vector2d(i * 64.0, j * 64.0));
        ASSERT_TRUE(ray);
        const Eigen::Vector3d p = ray->At(range);
        const auto l = rect.left.Project(p), r = rect.right.Project(p);
        if (l && r) worst_dy = std::max(worst_dy, std::abs(l->y() - r->y()));
      }
  EXPECT_LT(worst_dy, 1e-9);
  // Rectified pixel -> raw pixel (the map) -> ray -> rectified pixel.
  cv::Mat mx, my;
  RectificationMaps(left, rect.left, rect.size, 1000, &mx, &my);
  double worst = 0;
  int inside = 0;
  for (int y = 0; y < 1024; y += 31)
    for (int x = 0; x < 1024; x += 31) {
      const Eigen::Vector2d raw(mx.at<float>(y, x), my.at<float>(y, x));
      if (raw.x() < 0 || raw.y() < 0 || raw.x() > 1023 || raw.y() > 1023) continue;
      ++inside;
      const auto back = rect.left.Project(left.BackProject(raw)->At(1000));
      ASSERT_TRUE(back);
      worst = std::max(worst, (*back - Eigen::Vector2d(x, y)).norm());
    }
  EXPECT_GT(inside, 900);
  EXPECT_LT(worst, 1e-3) << "the map is stored as float: 1e-4 px of 1024";
  const LinearisationError e = MeasureLinearisation(left, 1024, 1024);
  std::cout << "sol60 Navcam CAHVOR -> CAHV: distortion the rectification removes: max " << e.max_px << " px, p95 "
            << e.p95_px << " px; rectified rows agree within " << worst_dy << " px\n";
  EXPECT_GT(e.max_px, 0.5) << "string A's Navcam lens has a few px of distortion at the corners";
  EXPECT_LT(e.max_px, 20.0);
}

TEST(LineariseStereoPair, CahvoreRowsAgreeFarAndTheNearErrorIsThePupil) {
  const CahvModel left = SyntheticCahvore(0.5);
  CahvModel right = left;
  right.c += 0.2 * (left.h - left.hc() * left.a).normalized();
  const RectifiedStereoPair rect = LineariseStereoPair(left, right, cv::Size(1024, 1024));
  // Through the rectified (single-centre) models the rows agree exactly;
  // the rectified images, though, are warped at one range, and a near
  // point's ray from the moving pupil misses that warp by the pupil shift.
  cv::Mat lx, ly, rx, ry;
  RectificationMaps(left, rect.left, rect.size, 1000, &lx, &ly);
  RectificationMaps(right, rect.right, rect.size, 1000, &rx, &ry);
  for (double range : {1.0, 1000.0}) {
    std::vector<double> dy;
    for (int j = 1; j < 16; ++j)
      for (int i = 1; i < 16; ++i) {
        const auto ray = left.BackProject(Eigen::Vector2d(i * 64.0, j * 64.0));
        const Eigen::Vector3d p = ray->At(range);
        // Where the point appears in each raw image, then in its rectified
        // image through the inverse of the warp (the linear model of the
        // ray from C at the warp's range).
        const auto lraw = left.Project(p), rraw = right.Project(p);
        if (!lraw || !rraw) continue;
        const auto lrect = rect.left.Project(left.BackProject(*lraw)->At(1000));
        const auto rrect = rect.right.Project(right.BackProject(*rraw)->At(1000));
        if (lrect && rrect) dy.push_back(std::abs(lrect->y() - rrect->y()));
      }
    std::cout << "CAHVORE (linearity 0.5) rectified pair, points at " << range << " m: |dy| max "
              << Percentile(dy, 100) << " px, p95 " << Percentile(dy, 95) << " px\n";
    if (range > 100) {
      EXPECT_LT(Percentile(dy, 100), 0.01);
    }
  }
}

TEST(LineariseStereoPair, RefusesCoincidentCentres) {
  EXPECT_THROW(LineariseStereoPair(Sol60Navcam(), Sol60Navcam(), cv::Size(1024, 1024)), std::invalid_argument);
}

}  // namespace
}  // namespace vloc
