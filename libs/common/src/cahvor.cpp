#include "vloc/common/cahvor.h"

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "vloc/common/options.h"

namespace vloc {

namespace {

constexpr double kEpsilon = 1e-15;
constexpr int kMaxNewton = 100;

bool Finite(const Eigen::Vector3d& x) { return x.allFinite(); }

// CAHV's image of a vector p from the centre (Yakimovsky & Cunningham).
std::optional<Eigen::Vector2d> CahvImage(const CahvModel& m, const Eigen::Vector3d& p) {
  const double alpha = p.dot(m.a);
  if (!(alpha > kEpsilon * p.norm()) || !(alpha > 0)) return std::nullopt;
  return Eigen::Vector2d(p.dot(m.h) / alpha, p.dot(m.v) / alpha);
}

// CAHV's ray of a pixel: (V - y A) x (H - x A), pointing along A.
std::optional<Eigen::Vector3d> CahvDirection(const CahvModel& m, const Eigen::Vector2d& px) {
  Eigen::Vector3d d = (m.v - px.y() * m.a).cross(m.h - px.x() * m.a);
  const double n = d.norm();
  if (!(n > kEpsilon)) return std::nullopt;
  d /= n;
  if (m.v.cross(m.h).dot(m.a) < 0) d = -d;
  return d;
}

// CAHVOR (Gennery 2001): p' = p + mu lambda.
std::optional<Eigen::Vector2d> ProjectCahvor(const CahvModel& m, const Eigen::Vector3d& p) {
  const double zeta = p.dot(m.o);
  if (!(zeta > 0)) return std::nullopt;
  const Eigen::Vector3d lambda = p - zeta * m.o;
  const double tau = lambda.squaredNorm() / (zeta * zeta);
  const double mu = m.r[0] + tau * (m.r[1] + tau * m.r[2]);
  return CahvImage(m, p + mu * lambda);
}

// The inverse: from the distorted CAHV ray rr, solve k5 u^5 + k3 u^3 + k1 u
// = 1 for u = 1 - mu by Newton (cmod_cahvor_2d_to_3d), then rr - mu lambda.
std::optional<Eigen::Vector3d> UndistortCahvor(const CahvModel& m, const Eigen::Vector3d& rr) {
  const double omega = rr.dot(m.o);
  if (!(omega * omega > kEpsilon)) return std::nullopt;
  const Eigen::Vector3d lambda = rr - omega * m.o;
  const double tau = lambda.squaredNorm() / (omega * omega);
  const double k1 = 1 + m.r[0], k3 = m.r[1] * tau, k5 = m.r[2] * tau * tau;
  double u = 1 - (m.r[0] + k3 + k5);
  bool converged = false;
  for (int i = 0; i < kMaxNewton && !converged; ++i) {
    const double u2 = u * u;
    const double poly = ((k5 * u2 + k3) * u2 + k1) * u - 1;
    const double deriv = (5 * k5 * u2 + 3 * k3) * u2 + k1;
    if (!(deriv > kEpsilon)) return std::nullopt;  // distortion too negative: no unique inverse
    const double du = poly / deriv;
    u -= du;
    converged = std::abs(du) <= 1e-15 * std::max(1.0, std::abs(u));
  }
  if (!converged || !std::isfinite(u)) return std::nullopt;
  const Eigen::Vector3d d = rr - (1 - u) * lambda;
  const double n = d.norm();
  if (!(n > kEpsilon)) return std::nullopt;
  return d / n;
}

// chi of an angle theta off O for the linearity L (Gennery 2006, eq. for
// the generalised projection), and its inverse.
double ChiOfTheta(double linearity, double theta) {
  if (linearity > kEpsilon) return std::tan(linearity * theta) / linearity;
  if (linearity < -kEpsilon) return std::sin(linearity * theta) / linearity;
  return theta;
}
double ThetaOfChi(double linearity, double chi) {
  if (linearity > kEpsilon) return std::atan(linearity * chi) / linearity;
  if (linearity < -kEpsilon) return std::asin(std::clamp(linearity * chi, -1.0, 1.0)) / linearity;
  return chi;
}

// The entrance pupil's shift along O for a ray theta off O.
double PupilShift(const CahvModel& m, double theta) {
  const double t2 = theta * theta;
  const double s = std::sin(theta);
  if (std::abs(theta) < 1e-8) return 0.0;  // theta / sin(theta) - 1 -> theta^2 / 6
  return (theta / s - 1.0) * (m.e[0] + m.e[1] * t2 + m.e[2] * t2 * t2);
}

// CAHVORE (Gennery 2006): theta by Newton on
//   zeta sin(theta) - lambda cos(theta) - (theta - sin(theta)) E(theta) = 0
// (the point lies on the ray from the shifted pupil), then chi, the radial
// distortion chi' = chi (1 + mu), and CAHV of O + chi' lambda / |lambda|.
std::optional<Eigen::Vector2d> ProjectCahvore(const CahvModel& m, const Eigen::Vector3d& p) {
  const double zeta = p.dot(m.o);
  const Eigen::Vector3d lambda_v = p - zeta * m.o;
  const double lambda = lambda_v.norm();
  double theta = std::atan2(lambda, zeta);
  bool converged = false;
  for (int n = 0; n < kMaxNewton && !converged; ++n) {
    const double c = std::cos(theta), s = std::sin(theta);
    const double t2 = theta * theta, t3 = t2 * theta, t4 = t2 * t2;
    const double e_theta = m.e[0] + m.e[1] * t2 + m.e[2] * t4;
    const double upsilon = zeta * c + lambda * s - (1.0 - c) * e_theta - (theta - s) * (2.0 * m.e[1] * theta + 4.0 * m.e[2] * t3);
    if (!(std::abs(upsilon) > kEpsilon)) return std::nullopt;
    const double dtheta = ((zeta * s - lambda * c) - (theta - s) * e_theta) / upsilon;
    theta -= dtheta;
    converged = std::abs(dtheta) <= 1e-15 * std::max(1.0, std::abs(theta));
  }
  if (!converged || !std::isfinite(theta) || !(theta >= 0)) return std::nullopt;
  if (theta * std::abs(m.linearity) > M_PI / 2) return std::nullopt;
  if (theta < 1e-12) return CahvImage(m, p);  // on the axis
  const double chi = ChiOfTheta(m.linearity, theta);
  const double chi2 = chi * chi;
  const double mu = m.r[0] + m.r[1] * chi2 + m.r[2] * chi2 * chi2;
  return CahvImage(m, m.o + chi * (1.0 + mu) * lambda_v / lambda);
}

// The inverse (cmod_cahvore_2d_to_3d, general): chi' of the CAHV ray, chi
// by Newton on chi (1 + r0) + r1 chi^3 + r2 chi^5 = chi', theta of chi, the
// ray sin(theta) lambda' / |lambda'| + cos(theta) O from the shifted pupil.
std::optional<CameraRay> BackProjectCahvore(const CahvModel& m, const Eigen::Vector2d& px) {
  const double avh = m.a.dot(m.v.cross(m.h));
  if (!(std::abs(avh) > kEpsilon)) return std::nullopt;
  const Eigen::Vector3d rp = (m.v - px.y() * m.a).cross(m.h - px.x() * m.a) / avh;
  const double zetap = rp.dot(m.o);
  if (!(std::abs(zetap) > kEpsilon)) return std::nullopt;
  const Eigen::Vector3d lambdap = rp - zetap * m.o;
  const double chip = lambdap.norm() / zetap;
  CameraRay ray;
  if (chip < 1e-12) {
    ray.origin = m.c;
    ray.direction = m.o;
    return ray;
  }
  double chi = chip;
  bool converged = false;
  for (int n = 0; n < kMaxNewton && !converged; ++n) {
    const double chi2 = chi * chi, chi4 = chi2 * chi2;
    const double deriv = 1.0 + m.r[0] + 3.0 * m.r[1] * chi2 + 5.0 * m.r[2] * chi4;
    if (!(std::abs(deriv) > kEpsilon)) return std::nullopt;
    const double dchi = ((1.0 + m.r[0]) * chi + m.r[1] * chi2 * chi + m.r[2] * chi4 * chi - chip) / deriv;
    chi -= dchi;
    converged = std::abs(dchi) <= 1e-15 * std::max(1.0, std::abs(chi));
  }
  if (!converged || !std::isfinite(chi) || !(chi > 0)) return std::nullopt;
  if (m.linearity < -kEpsilon && std::abs(m.linearity * chi) > 1) return std::nullopt;
  const double theta = ThetaOfChi(m.linearity, chi);
  ray.origin = m.c + PupilShift(m, theta) * m.o;
  ray.direction = (std::sin(theta) * lambdap.normalized() + std::cos(theta) * m.o).normalized();
  return ray;
}

}  // namespace

const char* CahvKindName(CahvKind kind) {
  switch (kind) {
    case CahvKind::kCahv: return "CAHV";
    case CahvKind::kCahvor: return "CAHVOR";
    case CahvKind::kCahvore: return "CAHVORE";
  }
  return "?";
}

bool CahvModel::Check(std::string* error) const {
  const std::string name = CahvKindName(kind);
  if (!Finite(c) || !Finite(a) || !Finite(h) || !Finite(v) || !Finite(o) || !Finite(r) || !Finite(e) ||
      !std::isfinite(linearity))
    return Fail(error, name + " model: a component is not finite");
  if (std::abs(a.norm() - 1) > 1e-6) return Fail(error, name + " model: A is not a unit vector");
  if (!(hs() > 1) || !(vs() > 1)) return Fail(error, name + " model: H or V is (nearly) parallel to A (hs, vs must be > 1 px)");
  const Eigen::Vector3d hp = (h - hc() * a) / hs(), vp = (v - vc() * a) / vs();
  if (std::abs(hp.dot(vp)) > 0.5) return Fail(error, name + " model: H' and V' are nearly parallel");
  if (kind != CahvKind::kCahv) {
    if (std::abs(o.norm() - 1) > 1e-6) return Fail(error, name + " model: O is not a unit vector");
    if (!(o.dot(a) > 0)) return Fail(error, name + " model: O points away from A");
  }
  if (kind == CahvKind::kCahvore && !(linearity >= -1 && linearity <= 2))
    return Fail(error, name + " model: linearity must be in [-1, 2]");
  return true;
}

double CahvModel::hc() const { return a.dot(h); }
double CahvModel::vc() const { return a.dot(v); }
double CahvModel::hs() const { return a.cross(h).norm(); }
double CahvModel::vs() const { return a.cross(v).norm(); }

std::optional<Eigen::Vector2d> CahvModel::Project(const Eigen::Vector3d& p_ref) const {
  const Eigen::Vector3d p = p_ref - c;
  switch (kind) {
    case CahvKind::kCahv: return CahvImage(*this, p);
    case CahvKind::kCahvor: return ProjectCahvor(*this, p);
    case CahvKind::kCahvore: return ProjectCahvore(*this, p);
  }
  return std::nullopt;
}

std::optional<CameraRay> CahvModel::BackProject(const Eigen::Vector2d& px) const {
  if (kind == CahvKind::kCahvore) return BackProjectCahvore(*this, px);
  const std::optional<Eigen::Vector3d> d = CahvDirection(*this, px);
  if (!d) return std::nullopt;
  CameraRay ray;
  ray.origin = c;
  if (kind == CahvKind::kCahv) {
    ray.direction = *d;
    return ray;
  }
  const std::optional<Eigen::Vector3d> u = UndistortCahvor(*this, *d);
  if (!u) return std::nullopt;
  ray.direction = *u;
  return ray;
}

CahvModel CahvModel::LinearPart() const {
  CahvModel m;
  m.kind = CahvKind::kCahv;
  m.c = c, m.a = a, m.h = h, m.v = v, m.o = a;
  return m;
}

Pose3 CahvModel::ReferenceFromCamera() const {
  const Eigen::Vector3d z = a.normalized();
  const Eigen::Vector3d x = (h - hc() * a).normalized();
  const Eigen::Vector3d y = z.cross(x).normalized();
  Eigen::Matrix3d rot;
  rot << y.cross(z), y, z;  // x = y x z: H' made orthogonal, the frame right-handed
  return MakePose(rot, c);
}

CahvModel CahvModel::FromPinhole(const PinholeCamera& pin, const Pose3& ref_from_camera) {
  const Eigen::Matrix3d rot = ref_from_camera.linear();
  CahvModel m;
  m.kind = CahvKind::kCahv;
  m.c = ref_from_camera.translation();
  m.a = rot.col(2);
  m.h = pin.fx * rot.col(0) + pin.cx * m.a;
  m.v = pin.fy * rot.col(1) + pin.cy * m.a;
  m.o = m.a;
  return m;
}

RectifiedStereoPair LineariseStereoPair(const CahvModel& left, const CahvModel& right, cv::Size size) {
  const Eigen::Vector3d baseline = right.c - left.c;
  if (!(baseline.norm() > 1e-9)) throw std::invalid_argument("LineariseStereoPair: the two centres coincide");
  if (!(left.a.dot(right.a) > 0)) throw std::invalid_argument("LineariseStereoPair: the two axes are opposed");
  // H' along the baseline, signed like the left camera's H'.
  Eigen::Vector3d hp = baseline.normalized();
  if (hp.dot(left.h - left.hc() * left.a) < 0) hp = -hp;
  // A: the mean axis, perpendicular to the baseline.
  Eigen::Vector3d a = (left.a + right.a).normalized();
  a = (a - a.dot(hp) * hp).normalized();
  const Eigen::Vector3d vp = a.cross(hp).normalized() * (a.cross(hp).dot(left.v) >= 0 ? 1.0 : -1.0);
  const double hs = 0.5 * (left.hs() + right.hs()), vs = 0.5 * (left.vs() + right.vs());
  const double hc = 0.5 * (size.width - 1), vc = 0.5 * (size.height - 1);
  RectifiedStereoPair out;
  out.size = size;
  for (CahvModel* m : {&out.left, &out.right}) {
    m->kind = CahvKind::kCahv;
    m->a = a, m->o = a;
    m->h = hs * hp + hc * a;
    m->v = vs * vp + vc * a;
  }
  out.left.c = left.c;
  out.right.c = right.c;
  return out;
}

void RectificationMaps(const CahvModel& raw, const CahvModel& rectified, cv::Size size, double range_m, cv::Mat* map_x,
                       cv::Mat* map_y) {
  map_x->create(size, CV_32FC1);
  map_y->create(size, CV_32FC1);
  for (int y = 0; y < size.height; ++y) {
    float* mx = map_x->ptr<float>(y);
    float* my = map_y->ptr<float>(y);
    for (int x = 0; x < size.width; ++x) {
      mx[x] = my[x] = -1.f;
      const std::optional<CameraRay> ray = rectified.BackProject(Eigen::Vector2d(x, y));
      if (!ray) continue;
      const std::optional<Eigen::Vector2d> px = raw.Project(ray->At(range_m));
      if (!px) continue;
      mx[x] = static_cast<float>(px->x());
      my[x] = static_cast<float>(px->y());
    }
  }
}

}  // namespace vloc
