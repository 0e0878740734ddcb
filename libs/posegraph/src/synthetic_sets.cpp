#include "vloc/posegraph/synthetic_sets.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "vloc/common/pose.h"

namespace vloc::posegraph {

const std::vector<SyntheticSet>& StandardSyntheticSets() {
  static const std::vector<SyntheticSet> sets = {
      {"torus", "torus", 100, 50, 0.82, 0.05, 0.02, "isotropic", 1},
      {"torus_indefinite", "torus", 100, 50, 0.82, 0.05, 0.02, "indefinite", 2},
      {"cube", "cube", 20, 0, 0.96, 0.05, 0.02, "correlated", 3},
      {"sphere_heavy", "sphere", 50, 50, 1.0, 0.1, 0.1, "indefinite", 4},
  };
  return sets;
}

namespace {

using Matrix6 = Eigen::Matrix<double, 6, 6>;

struct Geometry {
  std::vector<Pose3> poses;
  std::vector<std::pair<int, int>> loops;  // candidate loop edges (odometry i -> i+1 is implied)
};

// A frame whose z is `normal` and whose x is `forward` made orthogonal to it.
Pose3 Frame(const Eigen::Vector3d& position, const Eigen::Vector3d& forward, const Eigen::Vector3d& normal) {
  const Eigen::Vector3d z = normal.normalized();
  Eigen::Vector3d x = forward - forward.dot(z) * z;
  if (x.norm() < 1e-9) x = z.unitOrthogonal();
  x.normalize();
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = z.cross(x);
  R.col(2) = z;
  return MakePose(R, position);
}

Geometry Torus(int rings, int per_ring) {
  // Tube radius: per_ring steps of ~1 m around it; centre radius twice that.
  const double r = per_ring / (2 * M_PI), R = 2 * r;
  const int n = rings * per_ring;
  auto position = [&](double k) {
    const double u = 2 * M_PI * k / n, v = 2 * M_PI * k / per_ring;
    return Eigen::Vector3d((R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v));
  };
  Geometry g;
  for (int k = 0; k < n; ++k) {
    const double u = 2 * M_PI * k / n, v = 2 * M_PI * k / per_ring;
    const Eigen::Vector3d normal(std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v));
    g.poses.push_back(Frame(position(k), position(k + 0.5) - position(k - 0.5), normal));
    if (k >= per_ring) g.loops.emplace_back(k - per_ring, k);
  }
  return g;
}

Geometry Sphere(int rings, int per_ring) {
  const double r = per_ring / (2 * M_PI);
  const int n = rings * per_ring;
  Geometry g;
  for (int k = 0; k < n; ++k) {
    // Latitude from near the south pole to near the north pole, longitude round each ring.
    const double lat = -M_PI / 2 + M_PI * (k + 0.5) / n, lon = 2 * M_PI * k / per_ring;
    const Eigen::Vector3d normal(std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat));
    const Eigen::Vector3d east(-std::sin(lon), std::cos(lon), 0.0);
    g.poses.push_back(Frame(r * normal, east, normal));
    if (k >= per_ring) g.loops.emplace_back(k - per_ring, k);
  }
  return g;
}

Geometry Cube(int side) {
  // A snake: x back and forth along each row, rows back and forth in each
  // layer; 2 m between grid points.
  Geometry g;
  std::vector<int> index(static_cast<size_t>(side * side * side));
  auto at = [&](int x, int y, int z) -> int& { return index[static_cast<size_t>((z * side + y) * side + x)]; };
  std::vector<Eigen::Vector3i> cells;
  for (int z = 0; z < side; ++z)
    for (int yy = 0; yy < side; ++yy) {
      const int y = z % 2 == 0 ? yy : side - 1 - yy;
      for (int xx = 0; xx < side; ++xx) {
        const int x = (z * side + yy) % 2 == 0 ? xx : side - 1 - xx;
        at(x, y, z) = static_cast<int>(cells.size());
        cells.emplace_back(x, y, z);
      }
    }
  for (size_t k = 0; k < cells.size(); ++k) {
    const Eigen::Vector3d p = 2.0 * cells[k].cast<double>();
    const Eigen::Vector3d next = k + 1 < cells.size() ? Eigen::Vector3d(2.0 * cells[k + 1].cast<double>())
                                                      : Eigen::Vector3d(p + (p - 2.0 * cells[k - 1].cast<double>()));
    g.poses.push_back(Frame(p, next - p, Eigen::Vector3d::UnitZ() + 0.1 * (next - p).normalized()));
  }
  for (size_t k = 0; k < cells.size(); ++k) {
    const Eigen::Vector3i c = cells[k];
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Vector3i d = c;
      d[axis] += 1;
      if (d[axis] >= side) continue;
      const int other = at(d.x(), d.y(), d.z());
      if (std::abs(other - static_cast<int>(k)) == 1) continue;  // the odometry edge
      g.loops.emplace_back(std::min(other, static_cast<int>(k)), std::max(other, static_cast<int>(k)));
    }
  }
  return g;
}

Eigen::Matrix3d RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

Eigen::Matrix3d SquareRoot(const Eigen::Matrix3d& m) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m);
  return eig.eigenvectors() * eig.eigenvalues().cwiseSqrt().asDiagonal() * eig.eigenvectors().transpose();
}

struct EdgeNoise {
  Eigen::Matrix3d cov_t, cov_r;  // the blocks the noise is drawn from (rotation vector units)
  Matrix6 information;           // over [t; rotation vector], as the layout says
};

EdgeNoise MakeNoise(const SyntheticSet& set, std::mt19937& rng) {
  std::uniform_real_distribution<double> factor(0.5, 2.0);
  const double st = set.sigma_t * factor(rng), sr = set.sigma_r * factor(rng);
  EdgeNoise n;
  if (set.information == "isotropic") {
    n.cov_t = st * st * Eigen::Matrix3d::Identity();
    n.cov_r = sr * sr * Eigen::Matrix3d::Identity();
  } else {
    const Eigen::Matrix3d Q = RandomRotation(rng), P = RandomRotation(rng);
    n.cov_t = st * st * Q * Eigen::Vector3d(1.5, 1.0, 0.5).asDiagonal() * Q.transpose();
    n.cov_r = sr * sr * P * Eigen::Vector3d(1.5, 1.0, 0.5).asDiagonal() * P.transpose();
  }
  const Eigen::Matrix3d A = n.cov_t.inverse(), B = n.cov_r.inverse();
  n.information.setZero();
  n.information.topLeftCorner<3, 3>() = A;
  n.information.bottomRightCorner<3, 3>() = B;
  // Cross terms c A^1/2 B^1/2: the Schur complement is (1 - c^2) B.
  const double c = set.information == "correlated" ? 0.5 : set.information == "indefinite" ? 1.5 : 0.0;
  const Eigen::Matrix3d X = c * SquareRoot(A) * SquareRoot(B);
  n.information.topRightCorner<3, 3>() = X;
  n.information.bottomLeftCorner<3, 3>() = X.transpose();
  return n;
}

Pose3 Perturbed(const Pose3& z, const EdgeNoise& noise, std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Vector3d dt = Eigen::LLT<Eigen::Matrix3d>(noise.cov_t).matrixL() * Eigen::Vector3d(n(rng), n(rng), n(rng));
  const Eigen::Vector3d dr = Eigen::LLT<Eigen::Matrix3d>(noise.cov_r).matrixL() * Eigen::Vector3d(n(rng), n(rng), n(rng));
  return MakePose(z.linear() * ExpSO3(dr), z.translation() + z.linear() * dt);
}

void WritePose(std::ostream& os, const Pose3& p) {
  const Eigen::Quaterniond q(p.linear());
  os << p.translation().x() << ' ' << p.translation().y() << ' ' << p.translation().z() << ' ' << q.x() << ' ' << q.y()
     << ' ' << q.z() << ' ' << q.w();
}

}  // namespace

std::string SyntheticG2o(const SyntheticSet& set) {
  Geometry g;
  if (set.shape == "torus") g = Torus(set.rings, set.per_ring);
  else if (set.shape == "sphere") g = Sphere(set.rings, set.per_ring);
  else if (set.shape == "cube") g = Cube(set.rings);
  else throw std::invalid_argument("synthetic set shape must be torus, cube or sphere, got '" + set.shape + "'");
  std::mt19937 rng(set.seed);
  std::uniform_real_distribution<double> keep(0.0, 1.0);
  struct Edge {
    int i, j;
    Pose3 z;
    Matrix6 information;
  };
  std::vector<Edge> edges;
  auto add = [&](int i, int j) {
    const EdgeNoise noise = MakeNoise(set, rng);
    edges.push_back({i, j, Perturbed(g.poses[i].inverse() * g.poses[j], noise, rng), noise.information});
  };
  const int n = static_cast<int>(g.poses.size());
  for (int i = 0; i + 1 < n; ++i) add(i, i + 1);
  for (const auto& [i, j] : g.loops)
    if (keep(rng) < set.loop_probability) add(i, j);
  std::ostringstream os;
  os.precision(17);
  Pose3 chained = g.poses[0];
  for (int i = 0; i < n; ++i) {
    if (i > 0) chained = chained * edges[static_cast<size_t>(i - 1)].z;
    os << "VERTEX_SE3:QUAT " << i << ' ';
    WritePose(os, chained);
    os << '\n';
  }
  // g2o's information is over the quaternion's vector part (half the rotation vector).
  Eigen::Matrix<double, 6, 1> s;
  s << 1, 1, 1, 2, 2, 2;
  for (const Edge& e : edges) {
    os << "EDGE_SE3:QUAT " << e.i << ' ' << e.j << ' ';
    WritePose(os, e.z);
    const Matrix6 info_q = s.asDiagonal() * e.information * s.asDiagonal();
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) os << ' ' << info_q(r, c);
    os << '\n';
  }
  os << "FIX 0\n";
  return os.str();
}

}  // namespace vloc::posegraph
