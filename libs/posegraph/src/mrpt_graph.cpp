#include "vloc/posegraph/mrpt_graph.h"

#include <Eigen/Geometry>
#include <map>
#include <stdexcept>

namespace vloc::posegraph {

namespace {

Eigen::Matrix<double, 6, 6> RotationBlocks(const Eigen::Matrix3d& R) {
  Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
  J.block<3, 3>(0, 0) = R;
  J.block<3, 3>(3, 3) = R;
  return J;
}

template <int D, class Graph>
PoseGraphProblem<D> ProblemFromGraphImpl(const Graph& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                                         const std::vector<double>* robust) {
  PoseGraphProblem<D> problem;
  std::map<mrpt::graphs::TNodeID, int> index;
  ids->clear();
  problem.poses.reserve(graph.nodes.size());
  for (const auto& [id, node] : graph.nodes) {
    index.emplace(id, static_cast<int>(ids->size()));
    ids->push_back(id);
    typename PoseGraphProblem<D>::Pose p;
    if constexpr (D == 3) {
      p.R = node.getRotationMatrix().asEigen();
      p.t = Eigen::Vector3d(node.x(), node.y(), node.z());
    } else {
      p.R = Eigen::Rotation2Dd(node.phi()).toRotationMatrix();
      p.t = Eigen::Vector2d(node.x(), node.y());
    }
    problem.poses.push_back(p);
    problem.fixed.push_back(id == graph.root ? 1 : 0);
  }
  problem.edges.reserve(graph.edges.size());
  size_t k = 0;
  for (const auto& [key, edge] : graph.edges) {
    const auto a = index.find(key.first), b = index.find(key.second);
    if (a == index.end() || b == index.end())
      throw std::runtime_error("pose graph edge " + std::to_string(key.first) + "->" + std::to_string(key.second) +
                               " refers to a missing node");
    typename PoseGraphProblem<D>::Edge e;
    e.i = a->second;
    e.j = b->second;
    const auto& z = edge.getPoseMean();
    if constexpr (D == 3) {
      e.measurement.R = z.getRotationMatrix().asEigen();
      e.measurement.t = Eigen::Vector3d(z.x(), z.y(), z.z());
    } else {
      e.measurement.R = Eigen::Rotation2Dd(z.phi()).toRotationMatrix();
      e.measurement.t = Eigen::Vector2d(z.x(), z.y());
    }
    e.information = edge.cov_inv.asEigen();
    e.robust = robust && k < robust->size() && (*robust)[k] > 0;
    if (e.robust) e.robust_scale = (*robust)[k];
    problem.edges.push_back(e);
    ++k;
  }
  return problem;
}

}  // namespace

PoseGraph3 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses3DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust) {
  return ProblemFromGraphImpl<3>(graph, ids, robust);
}
PoseGraph2 ProblemFromGraph(const mrpt::graphs::CNetworkOfPoses2DInf& graph, std::vector<mrpt::graphs::TNodeID>* ids,
                            const std::vector<double>* robust) {
  return ProblemFromGraphImpl<2>(graph, ids, robust);
}

void PosesToGraph(const PoseGraph3& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses3DInf* graph) {
  for (size_t k = 0; k < ids.size(); ++k) {
    const auto& p = problem.poses[k];
    graph->nodes.at(ids[k]) = ToMrpt(MakePose(p.R, p.t));
  }
}
void PosesToGraph(const PoseGraph2& problem, const std::vector<mrpt::graphs::TNodeID>& ids,
                  mrpt::graphs::CNetworkOfPoses2DInf* graph) {
  for (size_t k = 0; k < ids.size(); ++k) {
    const auto& p = problem.poses[k];
    graph->nodes.at(ids[k]) = mrpt::poses::CPose2D(p.t.x(), p.t.y(), std::atan2(p.R(1, 0), p.R(0, 0)));
  }
}

mrpt::poses::CPose3D ToMrpt(const Pose3& pose) {
  mrpt::math::CMatrixDouble44 m(pose.matrix());
  return mrpt::poses::CPose3D(m);
}

Pose3 FromMrpt(const mrpt::poses::CPose3D& pose) {
  Pose3 out = Pose3::Identity();
  out.linear() = pose.getRotationMatrix().asEigen();
  out.translation() = Eigen::Vector3d(pose.x(), pose.y(), pose.z());
  return out;
}

Matrix6d LocalFromVlocCovariance(const Pose3& a_from_b, const Matrix6d& covariance) {
  const Matrix6d J = RotationBlocks(a_from_b.linear().transpose());
  return J * covariance * J.transpose();
}

Matrix6d VlocFromLocalCovariance(const Pose3& a_from_b, const Matrix6d& covariance) {
  const Matrix6d J = RotationBlocks(a_from_b.linear());
  return J * covariance * J.transpose();
}

PoseGraph3::Pose ToSolver(const mrpt::poses::CPose3D& pose) {
  PoseGraph3::Pose p;
  p.R = pose.getRotationMatrix().asEigen();
  p.t = Eigen::Vector3d(pose.x(), pose.y(), pose.z());
  return p;
}

}  // namespace vloc::posegraph
