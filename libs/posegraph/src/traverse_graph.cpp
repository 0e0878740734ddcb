#include "vloc/posegraph/traverse_graph.h"

#include <glog/logging.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <mrpt/poses/CPose3DPDFGaussianInf.h>
#include <sstream>

#include "vloc/common/stopwatch.h"
#include "vloc/posegraph/graph_io.h"

namespace vloc::posegraph {

namespace {

// An information matrix must be symmetric positive definite, or the
// optimiser reports a negative chi2 and wanders. Some public data sets hold
// semi-definite or indefinite ones: eigenvalues below 1e-9 of the largest
// are raised to it. False when the matrix is not finite or has no positive
// eigenvalue; *smallest receives the smallest eigenvalue found.
bool RepairInformation(mrpt::poses::CPose3DPDFGaussianInf* edge, double* smallest) {
  Matrix6d info;
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) info(r, c) = edge->cov_inv(r, c);
  if (!info.allFinite()) return false;
  info = 0.5 * (info + info.transpose()).eval();
  Eigen::SelfAdjointEigenSolver<Matrix6d> eig(info);
  if (eig.info() != Eigen::Success) return false;
  Vector6d values = eig.eigenvalues();
  *smallest = values.minCoeff();
  const double largest = values.maxCoeff();
  if (!(largest > 0)) return false;
  if (*smallest > 1e-9 * largest) return true;
  values = values.cwiseMax(1e-9 * largest);
  info = eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
  edge->cov_inv = mrpt::math::CMatrixDouble66(0.5 * (info + info.transpose()));
  if (*smallest > 0) *smallest = 0;  // repaired though positive: report as repaired
  return true;
}

bool IsZero(const Matrix6d& m) { return (m.array() == 0.0).all(); }


Matrix6d Diagonal(double sx, double sy, double sz, double srx, double sry, double srz) {
  Vector6d d;
  d << sx * sx, sy * sy, sz * sz, srx * srx, sry * sry, srz * srz;
  return d.asDiagonal();
}

Matrix6d RotateBlocks(const Eigen::Matrix3d& R, const Matrix6d& covariance) {
  Matrix6d J = Matrix6d::Zero();
  J.block<3, 3>(0, 0) = R;
  J.block<3, 3>(3, 3) = R;
  return J * covariance * J.transpose();
}

}  // namespace

const char* EdgeKindName(EdgeKind kind) {
  switch (kind) {
    case EdgeKind::kDeadReckoning: return "dead_reckoning";
    case EdgeKind::kVisual: return "visual";
    case EdgeKind::kLoop: return "loop";
    case EdgeKind::kAbsoluteFix: return "absolute_fix";
  }
  return "unknown";
}

void PoseGraphOptions::Visit(OptionsReader& r) {
  const NumberBound sigma = Positive() && Finite();
  r.Child("solver", [this](OptionsReader& c) { solver.Visit(c); });
  r.Optional("dr_covariance", &dr_covariance, "how DR edge covariances are made", OneOf({"difference", "per_metre"}));
  r.Optional("dr_position_sigma_per_metre", &dr_position_sigma_per_metre, "m/m, horizontal DR 1-sigma", sigma);
  r.Optional("dr_vertical_sigma_per_metre", &dr_vertical_sigma_per_metre, "m/m, vertical DR 1-sigma", sigma);
  r.Optional("dr_heading_sigma_per_metre", &dr_heading_sigma_per_metre, "rad/m, DR heading 1-sigma", sigma);
  r.Optional("dr_tilt_sigma", &dr_tilt_sigma, "rad, DR roll/pitch 1-sigma per edge", sigma);
  r.Optional("visual_covariance_scale", &visual_covariance_scale, "multiplies BA covariances", sigma);
  r.Optional("visual_default_position_sigma", &visual_default_position_sigma, "m, BA result without covariance", sigma);
  r.Optional("visual_default_rotation_sigma", &visual_default_rotation_sigma, "rad, BA result without covariance", sigma);
  r.Optional("fix_default_position_sigma", &fix_default_position_sigma, "m, absolute fix without covariance", sigma);
  r.Optional("fix_default_rotation_sigma", &fix_default_rotation_sigma, "rad, absolute fix without covariance", sigma);
  r.Optional("min_position_sigma", &min_position_sigma, "m, floor added to every edge", sigma);
  r.Optional("min_rotation_sigma", &min_rotation_sigma, "rad, floor added to every edge", sigma);
  r.Optional("compute_marginals", &compute_marginals, "marginal covariances after each update");
  r.Optional("root_uncertainty", &root_uncertainty, "site marginals include the root's DR covariance, carried to the site");
  r.Optional("loop_gate_chi2", &loop_gate_chi2, "loop/fix edges beyond this chi2 against the predicted covariance are switched off",
             Positive());
  r.Optional("max_site_id_jump", &max_site_id_jump, "site ids further beyond the newest are rejected as corrupt",
             AtLeast(1));
  r.Optional("max_pending", &max_pending, "measurements waiting for their sites; beyond, the oldest goes", AtLeast(1));
}

bool PoseGraphOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::string PoseGraphSummary::BriefReport() const {
  std::ostringstream os;
  os << (usable ? "usable" : "NOT usable") << ": " << num_sites << " sites, " << num_edges << " edges ("
     << num_dr_edges << " DR, " << num_visual_edges << " visual, " << num_loop_edges << " loop/fix), chi2 "
     << initial_chi2 << " -> " << final_chi2 << " in " << iterations << " iterations, " << total_seconds << " s";
  if (num_pending) os << ", " << num_pending << " pending";
  if (num_downweighted) os << ", " << num_downweighted << " loop/fix edges down-weighted as outliers";
  if (!message.empty()) os << "; " << message;
  return os.str();
}

TraverseGraph::TraverseGraph(PoseGraphOptions options) : options_(std::move(options)) {}

void TraverseGraph::AddNode(int site_id, const Pose3& world_from_body) {
  graph_.nodes[static_cast<mrpt::graphs::TNodeID>(site_id)] = ToMrpt(world_from_body);
  if (!have_root_) {
    graph_.root = static_cast<mrpt::graphs::TNodeID>(site_id);
    have_root_ = true;
  }
}

bool TraverseGraph::MakeEdge(const Pose3& from_T_to, const Matrix6d& covariance_vloc,
                             mrpt::poses::CPose3DPDFGaussianInf* edge, std::string* error) const {
  Matrix6d local = LocalFromVlocCovariance(from_T_to, covariance_vloc);
  local = 0.5 * (local + local.transpose());
  const double p2 = options_.min_position_sigma * options_.min_position_sigma;
  const double r2 = options_.min_rotation_sigma * options_.min_rotation_sigma;
  for (int i = 0; i < 3; ++i) local(i, i) += p2;
  for (int i = 3; i < 6; ++i) local(i, i) += r2;
  if (!local.allFinite()) return Fail(error, "covariance is not finite");
  Eigen::LLT<Matrix6d> llt(local);
  if (llt.info() != Eigen::Success) return Fail(error, "covariance is not positive definite");
  const Matrix6d information = llt.solve(Matrix6d::Identity());
  edge->mean = ToMrpt(from_T_to);
  edge->cov_inv = mrpt::math::CMatrixDouble66(0.5 * (information + information.transpose()));
  return true;
}

Matrix6d TraverseGraph::DrEdgeCovariance(int from, int to, const Pose3& relative, bool* fallback) const {
  const SiteRecord& a = sites_.at(from);
  const SiteRecord& b = sites_.at(to);
  *fallback = false;
  if (options_.dr_covariance == "difference") {
    if (!IsZero(a.dr.covariance) || !IsZero(b.dr.covariance)) {
      // cov_b = J1 cov_a J1^T + J2 cov_rel J2^T (ComposeCovariance), J2 = blockdiag(R_a, R_a).
      const Matrix6d predicted = ComposeCovariance(a.dr.pose, a.dr.covariance, relative, Matrix6d::Zero());
      Matrix6d growth = RotateBlocks(a.dr.pose.linear().transpose(), b.dr.covariance - predicted);
      growth = 0.5 * (growth + growth.transpose());
      Eigen::SelfAdjointEigenSolver<Matrix6d> eig(growth);
      if (eig.info() == Eigen::Success && eig.eigenvalues().minCoeff() > 0.0) return growth;
    }
    *fallback = true;
  }
  const double d = relative.translation().norm();
  return Diagonal(options_.dr_position_sigma_per_metre * d, options_.dr_position_sigma_per_metre * d,
                  options_.dr_vertical_sigma_per_metre * d, options_.dr_tilt_sigma, options_.dr_tilt_sigma,
                  options_.dr_heading_sigma_per_metre * d);
}

std::string TraverseGraph::SiteIdProblem(int site_id) const {
  if (site_id < 0) return "site id " + std::to_string(site_id) + " is negative";
  if (sites_.empty()) return "";
  const int newest = sites_.rbegin()->first;
  if (static_cast<int64_t>(site_id) - newest > options_.max_site_id_jump)
    return "site id " + std::to_string(site_id) + " is more than max_site_id_jump " +
           std::to_string(options_.max_site_id_jump) + " beyond the newest site " + std::to_string(newest) +
           " (a corrupt id?)";
  return "";
}

AddResult TraverseGraph::AddDeadReckoning(int site_id, const PoseWithCovariance& world_from_body) {
  AddResult result;
  if (const std::string problem = SiteIdProblem(site_id); !problem.empty()) {
    result.message = problem + "; dead-reckoning pose ignored";
    return result;
  }
  std::string why;
  if (!IsPlausiblePose(world_from_body, &why)) {
    result.message = "site " + std::to_string(site_id) + ": dead-reckoning pose rejected: " + why + "; ignored";
    return result;
  }
  SiteRecord& record = sites_[site_id];
  record.has_dr = true;
  record.dr = world_from_body;
  record.utime = world_from_body.utime;

  // Neighbouring sites with dead reckoning.
  std::optional<int> prev, next;
  for (const auto& [id, rec] : sites_) {
    if (!rec.has_dr || id == site_id) continue;
    if (id < site_id) prev = id;
    if (id > site_id && !next) next = id;
  }
  const auto key = static_cast<mrpt::graphs::TNodeID>(site_id);
  if (!graph_.nodes.count(key)) {
    std::optional<int> anchor = prev ? prev : next;
    if (anchor && graph_.nodes.count(static_cast<mrpt::graphs::TNodeID>(*anchor))) {
      const Pose3 world_from_anchor = FromMrpt(graph_.nodes.at(static_cast<mrpt::graphs::TNodeID>(*anchor)));
      const Pose3 anchor_from_site = sites_.at(*anchor).dr.pose.inverse() * world_from_body.pose;
      AddNode(site_id, world_from_anchor * anchor_from_site);
    } else {
      AddNode(site_id, world_from_body.pose);
    }
  }
  // Dead-reckoning edges to the neighbours (replacing a prev -> next edge).
  if (prev && next) edges_.erase(EdgeKey{*prev, *next, EdgeKind::kDeadReckoning});
  std::string error;
  for (const auto& [from, to] : {std::make_pair(prev, std::optional<int>(site_id)),
                                 std::make_pair(std::optional<int>(site_id), next)}) {
    if (!from || !to) continue;
    const Pose3 relative = sites_.at(*from).dr.pose.inverse() * sites_.at(*to).dr.pose;
    bool fallback = false;
    const Matrix6d covariance = DrEdgeCovariance(*from, *to, relative, &fallback);
    mrpt::poses::CPose3DPDFGaussianInf edge;
    if (!MakeEdge(relative, covariance, &edge, &error)) {
      result.message = "dead-reckoning edge " + std::to_string(*from) + "->" + std::to_string(*to) + ": " + error +
                       "; edge skipped";
      continue;
    }
    if (fallback) ++num_dr_fallbacks_;
    edges_[EdgeKey{*from, *to, EdgeKind::kDeadReckoning}] = edge;
  }
  RetryPending();
  result.accepted = true;
  result.changed = true;
  return result;
}

AddResult TraverseGraph::AddRelative(int reference_site_id, int site_id,
                                     const PoseWithCovariance& reference_from_current) {
  AddResult result;
  if (reference_site_id == site_id || reference_site_id < 0 || site_id < 0) {
    result.message = "visual edge " + std::to_string(reference_site_id) + "->" + std::to_string(site_id) +
                     ": needs two different non-negative site ids; ignored";
    return result;
  }
  for (const int id : {reference_site_id, site_id})
    if (const std::string problem = SiteIdProblem(id); !problem.empty()) {
      result.message = "visual edge " + std::to_string(reference_site_id) + "->" + std::to_string(site_id) + ": " +
                       problem + "; ignored";
      return result;
    }
  std::string why;
  if (!IsPlausiblePose(reference_from_current, &why)) {
    result.message = "visual edge " + std::to_string(reference_site_id) + "->" + std::to_string(site_id) + ": " +
                     why + "; ignored";
    return result;
  }
  PoseWithCovariance measurement = reference_from_current;
  if (IsZero(measurement.covariance)) {
    const double p = options_.visual_default_position_sigma;
    const double r = options_.visual_default_rotation_sigma;
    measurement.covariance = Diagonal(p, p, p, r, r, r);
  } else {
    measurement.covariance *= options_.visual_covariance_scale;
  }
  const EdgeKind kind = reference_site_id == site_id - 1 ? EdgeKind::kVisual : EdgeKind::kLoop;
  return AddEdge(reference_site_id, site_id, kind, measurement);
}

AddResult TraverseGraph::AddAbsoluteFix(int site_id, const PoseWithCovariance& world_from_body) {
  AddResult result;
  std::string why = SiteIdProblem(site_id);
  if (!why.empty() || !IsPlausiblePose(world_from_body, &why)) {
    result.message = "absolute fix for site " + std::to_string(site_id) + ": " + why + "; ignored";
    return result;
  }
  PoseWithCovariance measurement = world_from_body;
  if (IsZero(measurement.covariance)) {
    const double p = options_.fix_default_position_sigma;
    const double r = options_.fix_default_rotation_sigma;
    measurement.covariance = Diagonal(p, p, p, r, r, r);
  }
  return AddEdge(-1, site_id, EdgeKind::kAbsoluteFix, measurement);
}

AddResult TraverseGraph::AddEdge(int from, int to, EdgeKind kind, const PoseWithCovariance& measurement) {
  AddResult result;
  const std::string name = std::string(EdgeKindName(kind)) + " edge " +
                           (kind == EdgeKind::kAbsoluteFix ? std::string("root") : std::to_string(from)) + "->" +
                           std::to_string(to);
  const auto has = [this](int id) { return id >= 0 && graph_.nodes.count(static_cast<mrpt::graphs::TNodeID>(id)); };
  Pose3 relative = measurement.pose;
  Matrix6d covariance = measurement.covariance;
  if (kind == EdgeKind::kAbsoluteFix) {
    if (!have_root_ || !has(to)) {
      AddPending(from, to, kind, measurement);
      result.accepted = result.pending = true;
      result.message = name + ": site not in the graph yet; pending";
      return result;
    }
    from = static_cast<int>(graph_.root);
    if (to == from) {
      result.message = name + ": site " + std::to_string(to) + " is the fixed root (it defines the world frame); ignored";
      return result;
    }
    // The root's pose is exact: the fix relative to it has the fix's
    // covariance rotated into the root frame.
    const Pose3 world_from_root = FromMrpt(graph_.nodes.at(graph_.root));
    relative = world_from_root.inverse() * measurement.pose;
    covariance = RotateBlocks(world_from_root.linear().transpose(), measurement.covariance);
  } else if (!has(from)) {
    AddPending(from, to, kind, measurement);
    result.accepted = result.pending = true;
    result.message = name + ": reference site " + std::to_string(from) + " not in the graph yet; pending";
    return result;
  } else if (!has(to)) {
    // A site seen by the BA before its dead reckoning: place it from the reference.
    AddNode(to, FromMrpt(graph_.nodes.at(static_cast<mrpt::graphs::TNodeID>(from))) * measurement.pose);
    sites_[to].utime = measurement.utime;
  }
  mrpt::poses::CPose3DPDFGaussianInf edge;
  std::string error;
  if (!MakeEdge(relative, covariance, &edge, &error)) {
    result.message = name + ": " + error + "; ignored";
    return result;
  }
  edges_[EdgeKey{from, to, kind}] = edge;
  if (!sites_.count(to)) sites_[to].utime = measurement.utime;
  result.accepted = result.changed = true;
  return result;
}

void TraverseGraph::AddPending(int from, int to, EdgeKind kind, const PoseWithCovariance& measurement) {
  for (auto it = pending_.begin(); it != pending_.end(); ++it)
    if (it->from == from && it->to == to && it->kind == kind) {
      pending_.erase(it);
      break;
    }
  pending_.push_back({from, to, kind, measurement});
  if (static_cast<int>(pending_.size()) > options_.max_pending) {
    LOG(WARNING) << "pose graph: more than max_pending " << options_.max_pending << " measurements wait for their "
                 << "sites; the oldest (" << EdgeKindName(pending_.front().kind) << " edge to site "
                 << pending_.front().to << ") dropped";
    pending_.erase(pending_.begin());
  }
}

void TraverseGraph::RetryPending() {
  std::vector<Pending> waiting;
  waiting.swap(pending_);
  for (const Pending& p : waiting) AddEdge(p.from, p.to, p.kind, p.measurement);
}

mrpt::graphs::CNetworkOfPoses3DInf TraverseGraph::graph() const {
  mrpt::graphs::CNetworkOfPoses3DInf g = graph_;
  for (const auto& [key, edge] : edges_)
    g.insertEdge(static_cast<mrpt::graphs::TNodeID>(key.from), static_cast<mrpt::graphs::TNodeID>(key.to), edge);
  return g;
}

PoseGraph3 TraverseGraph::Problem(std::vector<mrpt::graphs::TNodeID>* ids, const std::vector<double>* robust,
                                  bool (*keep)(EdgeKind)) const {
  PoseGraph3 problem;
  std::map<mrpt::graphs::TNodeID, int> index;
  ids->clear();
  for (const auto& [id, node] : graph_.nodes) {
    index.emplace(id, static_cast<int>(ids->size()));
    ids->push_back(id);
    PoseGraph3::Pose p;
    p.R = node.getRotationMatrix().asEigen();
    p.t = Eigen::Vector3d(node.x(), node.y(), node.z());
    problem.poses.push_back(p);
    problem.fixed.push_back(id == graph_.root ? 1 : 0);
  }
  size_t k = 0;
  for (const auto& [key, edge] : edges_) {
    const size_t at = k++;
    if (keep && !keep(key.kind)) continue;
    const auto a = index.find(static_cast<mrpt::graphs::TNodeID>(key.from));
    const auto b = index.find(static_cast<mrpt::graphs::TNodeID>(key.to));
    if (a == index.end() || b == index.end())
      throw std::runtime_error("pose graph edge " + std::to_string(key.from) + "->" + std::to_string(key.to) +
                               " refers to a missing site");
    PoseGraph3::Edge e;
    e.i = a->second;
    e.j = b->second;
    e.measurement.R = edge.mean.getRotationMatrix().asEigen();
    e.measurement.t = Eigen::Vector3d(edge.mean.x(), edge.mean.y(), edge.mean.z());
    e.information = edge.cov_inv.asEigen();
    e.robust = robust && (*robust)[at] > 0;
    if (e.robust) e.robust_scale = (*robust)[at];
    problem.edges.push_back(e);
  }
  return problem;
}

std::map<mrpt::graphs::TNodeID, Matrix6d> TraverseGraph::MarginalsWithoutLoops() const {
  std::map<mrpt::graphs::TNodeID, Matrix6d> computed;
  std::vector<mrpt::graphs::TNodeID> ids;
  const PoseGraph3 plain = Problem(&ids, nullptr, [](EdgeKind kind) {
    return kind != EdgeKind::kLoop && kind != EdgeKind::kAbsoluteFix;
  });
  std::vector<PoseGraph3::Information> blocks;
  std::string ignored;
  if (MarginalCovariances(plain, options_.solver, &blocks, &ignored))
    for (size_t p = 0; p < ids.size(); ++p)
      if (!plain.fixed[p]) computed[ids[p]] = blocks[p];
  return computed;
}

Matrix6d TraverseGraph::MarginalOrNearest(mrpt::graphs::TNodeID id,
                                          const std::map<mrpt::graphs::TNodeID, Matrix6d>& prior) const {
  if (id == graph_.root || prior.empty()) return Matrix6d::Zero();
  if (const auto it = prior.find(id); it != prior.end()) return it->second;
  auto nearest = prior.lower_bound(id);
  if (nearest == prior.end()) --nearest;
  const auto& a = graph_.nodes.at(id);
  const auto& b = graph_.nodes.at(nearest->first);
  const double d = std::sqrt((a.x() - b.x()) * (a.x() - b.x()) + (a.y() - b.y()) * (a.y() - b.y()) +
                             (a.z() - b.z()) * (a.z() - b.z()));
  return nearest->second + Diagonal(options_.dr_position_sigma_per_metre * d, options_.dr_position_sigma_per_metre * d,
                                    options_.dr_vertical_sigma_per_metre * d, options_.dr_tilt_sigma,
                                    options_.dr_tilt_sigma, options_.dr_heading_sigma_per_metre * d);
}

double TraverseGraph::LoopKernelScale(const EdgeKey& key, const mrpt::poses::CPose3DPDFGaussianInf& edge,
                                      const std::map<mrpt::graphs::TNodeID, Matrix6d>& prior) const {
  const auto i = static_cast<mrpt::graphs::TNodeID>(key.from), j = static_cast<mrpt::graphs::TNodeID>(key.to);
  if (prior.empty() || !graph_.nodes.count(i) || !graph_.nodes.count(j)) return 1.0;
  Matrix6d J_i, J_j;
  const Vector6d e = EdgeResidual<3>(ToSolver(edge.mean), ToSolver(graph_.nodes.at(i)), ToSolver(graph_.nodes.at(j)),
                                     &J_i, &J_j);
  const Matrix6d W = edge.cov_inv.asEigen();
  const Matrix6d S = J_i * MarginalOrNearest(i, prior) * J_i.transpose() +
                     J_j * MarginalOrNearest(j, prior) * J_j.transpose() + W.inverse();
  const double own = e.dot(W * e);
  const double predicted = e.dot(S.ldlt().solve(e));
  if (!(predicted <= options_.loop_gate_chi2)) return 1e-9;
  if (predicted > 0 && std::isfinite(own / predicted)) return std::max(1.0, own / predicted);
  return 1.0;
}

std::vector<double> TraverseGraph::RobustEdgeScales() const {
  // Per edge (edges_ order): 0
  // for DR and adjacent visual edges. A loop or fix is tested against the
  // predicted covariance of its residual, S = J_i C_i J_i^T + J_j C_j J_j^T
  // + W^-1 (C = the last update's marginals; the two sites taken as
  // uncorrelated, which widens S a little: the test errs on accepting):
  //  - s' = e^T S^-1 e <= loop_gate_chi2: a plausible match. Its kernel
  //    width is scaled by max(1, s / s') (s = e^T W e, its own chi2), so a
  //    revisit that closes a long drift keeps its full weight from the first
  //    iteration while the drift is within the traverse's uncertainty;
  //  - beyond: switched off for this update (width 1e-9: weight ~0), like a
  //    switchable constraint whose switch went to zero. It is tested again
  //    at the next update, so a match that becomes plausible comes back.
  // With no marginals from the last update (the first after a reload, or
  // compute_marginals off) they are computed here, at the current estimate,
  // from the graph without its loop and fix edges; when even that is
  // singular the kernel runs at its plain width. A site without a marginal
  // (added since the last update) takes its nearest site's, grown by the
  // per-metre DR model over the distance between them.
  const bool any_robust = std::any_of(edges_.begin(), edges_.end(), [](const auto& entry) {
    return entry.first.kind == EdgeKind::kLoop || entry.first.kind == EdgeKind::kAbsoluteFix;
  });
  const std::map<mrpt::graphs::TNodeID, Matrix6d> computed =
      any_robust && marginals_.empty() ? MarginalsWithoutLoops() : std::map<mrpt::graphs::TNodeID, Matrix6d>();
  const std::map<mrpt::graphs::TNodeID, Matrix6d>& prior = marginals_.empty() ? computed : marginals_;
  std::vector<double> scales;
  scales.reserve(edges_.size());
  for (const auto& [key, edge] : edges_) {
    const bool robust = key.kind == EdgeKind::kLoop || key.kind == EdgeKind::kAbsoluteFix;
    scales.push_back(robust ? LoopKernelScale(key, edge, prior) : 0.0);
  }
  return scales;
}

PoseGraphSummary TraverseGraph::Optimize() {
  const Stopwatch total;
  PoseGraphSummary s;
  s.num_sites = num_sites();
  s.num_edges = static_cast<int>(edges_.size());
  for (const auto& [key, edge] : edges_) {
    if (key.kind == EdgeKind::kDeadReckoning) ++s.num_dr_edges;
    if (key.kind == EdgeKind::kVisual || key.kind == EdgeKind::kLoop) ++s.num_visual_edges;
    if (key.kind == EdgeKind::kLoop || key.kind == EdgeKind::kAbsoluteFix) ++s.num_loop_edges;
    if (key.kind == EdgeKind::kAbsoluteFix) ++s.num_fix_edges;
  }
  s.num_pending = static_cast<int>(pending_.size());
  s.num_dr_fallbacks = num_dr_fallbacks_;
  if (graph_.nodes.empty()) {
    s.message = "no sites yet";
    summary_ = s;
    return s;
  }
  // Revisits and absolute fixes go through the robust kernel: a false
  // match must not bend the traverse.
  const std::vector<double> robust = RobustEdgeScales();
  marginals_.clear();
  try {
    const Stopwatch watch;
    std::vector<mrpt::graphs::TNodeID> ids;
    PoseGraph3 problem = Problem(&ids, &robust);
    std::vector<PoseGraph3::Information> blocks;
    const SolverSummary r = SolvePoseGraph(&problem, options_.solver, options_.compute_marginals ? &blocks : nullptr);
    if (!r.usable) throw std::runtime_error("pose graph solver: " + r.message);
    for (size_t p = 0; p < ids.size(); ++p) {
      if (problem.fixed[p]) continue;
      graph_.nodes.at(ids[p]) = ToMrpt(MakePose(problem.poses[p].R, problem.poses[p].t));
      if (r.marginals_valid) marginals_[ids[p]] = blocks[p];
    }
    s.initial_chi2 = r.initial_cost;
    s.final_chi2 = r.final_cost;
    s.iterations = r.iterations;
    s.optimize_seconds = watch.Seconds() - r.marginal_seconds;
    s.num_downweighted = r.num_downweighted;
    if (options_.compute_marginals) {
      s.marginals_valid = r.marginals_valid;
      s.marginal_seconds = r.marginal_seconds;
      if (!s.marginals_valid)
        s.message = "the pose graph's Hessian is singular (a site not linked to the root by edges?); marginal "
                    "covariances not computed";
    }
  } catch (const std::exception& e) {
    s.message = e.what();
    s.total_seconds = total.Seconds();
    summary_ = s;
    return s;
  }
  s.usable = std::isfinite(s.final_chi2);
  if (!s.usable) s.message = "chi2 is not finite";
  s.total_seconds = total.Seconds();
  summary_ = s;
  return s;
}

std::optional<SiteEstimate> TraverseGraph::Site(int site_id) const {
  const auto it = graph_.nodes.find(static_cast<mrpt::graphs::TNodeID>(site_id));
  if (site_id < 0 || it == graph_.nodes.end()) return std::nullopt;
  SiteEstimate e;
  e.site_id = site_id;
  const auto rec = sites_.find(site_id);
  e.utime = rec != sites_.end() ? rec->second.utime : 0;
  e.world_from_body.utime = e.utime;
  e.world_from_body.pose = FromMrpt(it->second);
  e.is_root = it->first == graph_.root;
  const auto m = marginals_.find(it->first);
  if (!e.is_root && m != marginals_.end()) {
    e.world_from_body.covariance = VlocFromLocalCovariance(e.world_from_body.pose, m->second);
    if (options_.root_uncertainty) e.world_from_body.covariance += RootUncertaintyAt(e.world_from_body.pose);
  }
  return e;
}

Matrix6d TraverseGraph::RootUncertaintyAt(const Pose3& world_from_site) const {
  const auto root = sites_.find(static_cast<int>(graph_.root));
  if (root == sites_.end() || !root->second.has_dr || IsZero(root->second.dr.covariance)) return Matrix6d::Zero();
  const Pose3 world_from_root = FromMrpt(graph_.nodes.at(graph_.root));
  return ComposeCovariance(world_from_root, root->second.dr.covariance, world_from_root.inverse() * world_from_site,
                           Matrix6d::Zero());
}

std::vector<SiteEstimate> TraverseGraph::Sites() const {
  std::vector<SiteEstimate> out;
  out.reserve(graph_.nodes.size());
  for (const auto& n : graph_.nodes) out.push_back(*Site(static_cast<int>(n.first)));
  return out;
}

int64_t TraverseGraph::newest_utime() const {
  int64_t newest = 0;
  for (const auto& [id, rec] : sites_) newest = std::max(newest, rec.utime);
  return newest;
}

std::string TraverseGraph::Serialize(GraphFormat format) const {
  std::ostringstream os;
  os.precision(17);
  os << "# vloc traverse graph: " << GraphFormatName(format) << " format; '# VLOC_' lines are vloc metadata\n";
  os << "# VLOC_VERSION 1\n";
  for (const auto& [id, rec] : sites_) {
    os << "# VLOC_SITE " << id << ' ' << rec.utime << ' ' << (rec.has_dr ? 1 : 0) << ' ';
    WritePoseText(os, rec.dr);
    os << '\n';
  }
  // The exact information matrix (upper triangle, optimiser order x y z rx ry
  // rz): MRPT 2.5's EDGE3 reader drops the rotation cross terms.
  for (const auto& [key, edge] : edges_) {
    os << "# VLOC_EDGE " << key.from << ' ' << key.to << ' ' << static_cast<int>(key.kind);
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) os << ' ' << edge.cov_inv(r, c);
    os << '\n';
  }
  for (const Pending& p : pending_) {
    os << "# VLOC_PENDING " << p.from << ' ' << p.to << ' ' << static_cast<int>(p.kind) << ' ';
    WritePoseText(os, p.measurement);
    os << '\n';
  }
  if (format == GraphFormat::kG2o) {
    GraphFile file;
    file.dimension = 3;
    file.format = GraphFormat::kG2o;
    file.graph3 = graph();
    os << GraphText(file);
  } else {
    graph().writeAsText(os);
  }
  return os.str();
}

bool TraverseGraph::Save(const std::string& path, std::string* error) const {
  std::string sub;
  const bool g2o = path.size() >= 4 && path.compare(path.size() - 4, 4, ".g2o") == 0;
  if (!WriteFileAtomically(path, Serialize(g2o ? GraphFormat::kG2o : GraphFormat::kMrptText), &sub))
    return Fail(error, "pose graph file: " + sub);
  return true;
}

bool TraverseGraph::Load(const std::string& path, std::string* error) {
  std::ifstream f(path);
  if (!f) return Fail(error, "cannot read pose graph file " + path);
  std::stringstream buffer;
  buffer << f.rdbuf();
  std::string sub;
  if (!Deserialize(buffer.str(), &sub)) return Fail(error, "pose graph file " + path + ": " + sub);
  return true;
}

bool TraverseGraph::ReadGraphBody(const std::string& text, std::string* error) {
  // graph_io's reader refuses what MRPT's would skip: a file that is no
  // graph, or a graph with a damaged line, would load as less than it holds
  // (and the next save would overwrite it).
  std::string repaired;
  if (!ParseGraph3Text(text, &graph_, error, &repaired)) return false;
  if (!repaired.empty()) LOG(WARNING) << "pose graph file: " << repaired;
  return true;
}

bool TraverseGraph::ReadAnnotations(const std::string& text, std::vector<EdgeKey>* kinds,
                                    std::vector<Matrix6d>* informations, std::string* error) {
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind("# VLOC_", 0) != 0) continue;
    std::istringstream ls(line.substr(2));
    std::string tag;
    ls >> tag;
    if (tag == "VLOC_SITE") {
      int id, has_dr;
      SiteRecord rec;
      if (!(ls >> id >> rec.utime >> has_dr) || !ReadPoseText(ls, &rec.dr)) return Fail(error, "bad line: " + line);
      rec.has_dr = has_dr != 0;
      sites_[id] = rec;
    } else if (tag == "VLOC_EDGE") {
      int from, to, kind;
      if (!(ls >> from >> to >> kind) || kind < 0 || kind > 3) return Fail(error, "bad line: " + line);
      kinds->push_back({from, to, static_cast<EdgeKind>(kind)});
      Matrix6d info;
      for (int r = 0; r < 6; ++r)
        for (int c = r; c < 6; ++c) {
          if (!(ls >> info(r, c))) return Fail(error, "bad line: " + line);
          info(c, r) = info(r, c);
        }
      informations->push_back(info);
    } else if (tag == "VLOC_PENDING") {
      Pending p;
      int kind;
      if (!(ls >> p.from >> p.to >> kind) || kind < 0 || kind > 3 || !ReadPoseText(ls, &p.measurement))
        return Fail(error, "bad line: " + line);
      p.kind = static_cast<EdgeKind>(kind);
      pending_.push_back(p);
    }
  }
  if (pending_.size() > static_cast<size_t>(options_.max_pending)) {
    const size_t dropped = pending_.size() - static_cast<size_t>(options_.max_pending);
    LOG(WARNING) << "pose graph: " << pending_.size() << " pending measurements in the file, more than "
                 << "max_pending " << options_.max_pending << "; the oldest " << dropped << " dropped";
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(dropped));
  }
  return true;
}

bool TraverseGraph::AdoptEdges(const std::vector<EdgeKey>& kinds, const std::vector<Matrix6d>& informations,
                               std::string* error) {
  const auto& g = graph_;
  if (!kinds.empty() && kinds.size() != g.edges.size())
    return Fail(error, std::to_string(kinds.size()) + " VLOC_EDGE lines for " + std::to_string(g.edges.size()) +
                           " edges; the file is inconsistent");
  size_t i = 0;
  std::map<std::pair<int, int>, int> seen;
  for (const auto& [ids, edge] : g.edges) {
    const int from = static_cast<int>(ids.first);
    const int to = static_cast<int>(ids.second);
    EdgeKey key{from, to, EdgeKind::kLoop};
    mrpt::poses::CPose3DPDFGaussianInf exact = edge;
    if (!kinds.empty()) {
      key = kinds[i];
      exact.cov_inv = mrpt::math::CMatrixDouble66(informations[i]);
      ++i;
      if (key.from != from || key.to != to) return Fail(error, "VLOC_EDGE lines do not match the EDGE3 lines");
    } else if (std::abs(to - from) == 1) {
      // A plain MRPT graph: first edge of an adjacent pair = DR, then visual.
      key.kind = seen[{from, to}]++ == 0 ? EdgeKind::kDeadReckoning : EdgeKind::kVisual;
    }
    double smallest = 0;
    if (!RepairInformation(&exact, &smallest))
      return Fail(error, "edge " + std::to_string(from) + "->" + std::to_string(to) +
                             ": information matrix is not finite or has no positive eigenvalue");
    if (smallest <= 0) {
      if (num_repaired_informations_++ == 0) smallest_repaired_eigenvalue_ = smallest;
      smallest_repaired_eigenvalue_ = std::min(smallest_repaired_eigenvalue_, smallest);
    }
    edges_[key] = exact;
  }
  if (num_repaired_informations_ > 0)
    LOG(WARNING) << "pose graph: " << num_repaired_informations_
                 << " edges had an information matrix that is not positive definite (smallest eigenvalue "
                 << smallest_repaired_eigenvalue_ << "); repaired by raising its eigenvalues to 1e-9 of the largest";
  return true;
}

bool TraverseGraph::Deserialize(const std::string& text, std::string* error) {
  TraverseGraph loaded(options_);
  std::vector<EdgeKey> kinds;
  std::vector<Matrix6d> informations;
  if (!loaded.ReadGraphBody(text, error) || !loaded.ReadAnnotations(text, &kinds, &informations, error) ||
      !loaded.AdoptEdges(kinds, informations, error))
    return false;
  for (const auto& n : loaded.graph_.nodes) {
    const int id = static_cast<int>(n.first);
    if (!loaded.sites_.count(id)) loaded.sites_[id] = SiteRecord{};
  }
  loaded.have_root_ = !loaded.graph_.nodes.empty();
  loaded.graph_.edges.clear();  // edges_ holds them now
  *this = std::move(loaded);
  return true;
}

}  // namespace vloc::posegraph
