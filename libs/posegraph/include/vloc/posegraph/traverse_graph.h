#pragma once
// The traverse pose graph: one MRPT node per rover site (MRPT holds the
// poses and, for saving and loading, the graph container and its text
// format), optimised after every change by vloc's sparse solver
// (sparse_solver.h, the only optimiser), warm-started from the last
// optimum, its marginals from the solver's last factorisation. Revisit
// (loop) and absolute-fix edges are robust: each update tests them against
// their predicted covariance (RobustEdgeScales): an implausible one (a match
// to the wrong place) is switched off, the others go through the DCS kernel.
//
//   TraverseGraph graph(options);
//   graph.AddDeadReckoning(site, utime, world_from_body_dr);      // node + DR edge
//   graph.AddRelative(reference, site, reference_from_current);   // BA edge
//   graph.AddAbsoluteFix(site, world_from_body_fix);              // optional
//   PoseGraphSummary s = graph.Optimize();
//   for (const SiteEstimate& e : graph.Sites()) ...               // poses + marginals
//   graph.Save(path); TraverseGraph::Load(path, options, &graph, &error);
//
// Edges:
//  - dead reckoning between consecutive sites that have a DR pose (by id):
//    Z = DR_prev^-1 DR_site; covariance either from the growth of the DR
//    covariance between the two sites ("difference": the relative covariance
//    that, composed on the earlier site's, gives the later one's) or from a
//    per-metre model ("per_metre"); "difference" falls back to "per_metre"
//    when the growth is not positive definite or the DR covariance unknown;
//  - visual (BA) between reference and current site, kind kVisual when the
//    reference is site - 1 and kLoop otherwise (a revisit);
//  - absolute fix: an edge from the root site (fixed, defines the world frame)
//    to the site, world_from_body with its covariance.
// Site poses are initialised from dead reckoning relative to the previous
// site's current estimate; the first site added is the root (normally site 0).
//
// Persistence: MRPT's text graph format (VERTEX3 / FIX / EDGE3 lines,
// written with 17 significant digits), or g2o (VERTEX_SE3:QUAT /
// EDGE_SE3:QUAT / FIX) when the path ends in ".g2o", plus vloc's metadata as
// comment lines both readers skip ("# VLOC_SITE ...", "# VLOC_EDGE ...").
// Either file opens in vloc_posegraph and g2o's tools.

#include <map>
#include <mrpt/graphs/CNetworkOfPoses.h>
#include <optional>
#include <string>
#include <vector>

#include "vloc/common/options.h"
#include "vloc/common/pose.h"
#include "vloc/common/rover_data.h"
#include "vloc/posegraph/graph_io.h"
#include "vloc/posegraph/mrpt_graph.h"

namespace vloc::posegraph {

enum class EdgeKind : int { kDeadReckoning = 0, kVisual = 1, kLoop = 2, kAbsoluteFix = 3 };
const char* EdgeKindName(EdgeKind kind);

struct PoseGraphOptions {
  SolverOptions solver = WarmStartSolverOptions();  // vloc's solver, warm-started (mrpt_graph.h)
  std::string dr_covariance = "difference";       // "difference" (from the DR covariance growth) or "per_metre"
  double dr_position_sigma_per_metre = 0.05;      // m/m, horizontal 1-sigma of a DR edge per metre driven
  double dr_vertical_sigma_per_metre = 0.02;      // m/m, vertical 1-sigma per metre driven
  double dr_heading_sigma_per_metre = 0.002;      // rad/m, heading 1-sigma per metre driven
  double dr_tilt_sigma = 0.005;                   // rad, roll and pitch 1-sigma of a DR edge
  double visual_covariance_scale = 1.0;           // multiplies the BA's relative-pose covariance
  double visual_default_position_sigma = 0.05;    // m, when a BA result carries no covariance
  double visual_default_rotation_sigma = 0.002;   // rad, when a BA result carries no covariance
  double fix_default_position_sigma = 1.0;        // m, when an absolute fix carries no covariance
  double fix_default_rotation_sigma = 3.0;        // rad, ditto (large: a position-only fix)
  double min_position_sigma = 1e-3;               // m, added in quadrature to every edge (keeps W finite)
  double min_rotation_sigma = 1e-5;               // rad, ditto
  bool compute_marginals = true;                  // marginal covariance of every site after each update
  bool root_uncertainty = true;                   // the root's own DR covariance (roll / pitch from gravity,
                                                  // heading) carried into every other site's marginal: the
                                                  // chain holds the root's tilt, which turns every step's height
  double loop_gate_chi2 = 22.46;                  // a loop/fix edge whose chi2 against its predicted covariance
                                                  // exceeds this (6 dof, 99.9 %) is switched off for the update
  int max_site_id_jump = kMaxSiteIdJump;          // a site id this far beyond the newest is corrupt: rejected
  int max_pending = 1000;                         // measurements waiting for their sites; beyond, the oldest goes
                                                  // (a repeated one replaces its earlier copy)

  void Visit(OptionsReader& r);
  bool Check(std::string* error) const;
};

// What one update did.
struct PoseGraphSummary {
  bool usable = false;           // the estimate may be used
  std::string message;           // why not, or a one-line report
  int num_sites = 0;
  int num_edges = 0;
  int num_dr_edges = 0;
  int num_visual_edges = 0;      // BA edges (adjacent and revisits)
  int num_loop_edges = 0;        // revisits (non-adjacent BA edges) and absolute fixes
  int num_fix_edges = 0;
  int num_pending = 0;           // measurements waiting for their sites
  int num_dr_fallbacks = 0;      // DR edges that used the per-metre model in "difference" mode
  int num_downweighted = 0;      // loop/fix edges the robust kernel down-weighted (weight < 0.5): likely false
  double initial_chi2 = 0.0;
  double final_chi2 = 0.0;
  int iterations = 0;
  bool marginals_valid = false;
  double optimize_seconds = 0.0; // the solver (without the marginals)
  double marginal_seconds = 0.0; // marginal covariances
  double total_seconds = 0.0;

  std::string BriefReport() const;
};

// A site's optimised pose and marginal covariance (vloc convention, world
// frame; all zero for the root site, which is fixed). With
// root_uncertainty the marginal adds the root's DR covariance carried to the
// site (first order: the root's tilt moves the site's height by the distance
// times the tilt).
struct SiteEstimate {
  int site_id = 0;
  int64_t utime = 0;
  PoseWithCovariance world_from_body;
  bool is_root = false;
};

// Result of adding a measurement.
struct AddResult {
  bool accepted = false;    // stored (maybe pending)
  bool changed = false;     // the graph changed: optimise
  bool pending = false;     // waiting for a site that is not in the graph yet
  std::string message;      // why rejected, or what happened
};

class TraverseGraph {
 public:
  explicit TraverseGraph(PoseGraphOptions options = {});

  AddResult AddDeadReckoning(int site_id, const PoseWithCovariance& world_from_body);
  // `reference_from_current` is reference_from_body(site) with covariance in
  // vloc's convention (frame: the reference body). A new result for the same
  // (reference, site) pair replaces the earlier one.
  AddResult AddRelative(int reference_site_id, int site_id, const PoseWithCovariance& reference_from_current);
  AddResult AddAbsoluteFix(int site_id, const PoseWithCovariance& world_from_body);

  PoseGraphSummary Optimize();
  const PoseGraphSummary& last_summary() const { return summary_; }

  std::vector<SiteEstimate> Sites() const;
  std::optional<SiteEstimate> Site(int site_id) const;
  int num_sites() const { return static_cast<int>(graph_.nodes.size()); }
  int64_t newest_utime() const;
  // The graph in MRPT's container (nodes and edges), as it is saved.
  mrpt::graphs::CNetworkOfPoses3DInf graph() const;
  const PoseGraphOptions& options() const { return options_; }

  // Writes atomically (temporary file + rename), in g2o when `path` ends in
  // ".g2o", else in MRPT's text format. False with *error on failure.
  bool Save(const std::string& path, std::string* error) const;
  // Reads a graph saved by Save in either format (or any MRPT 3D text or
  // 3D g2o graph; its edges are then classified by adjacency). False with
  // *error (the graph unchanged).
  bool Load(const std::string& path, std::string* error);
  // Loaded edges whose information matrix was not positive definite and was
  // repaired (eigenvalues raised to 1e-9 of the largest; one warning line).
  int num_repaired_informations() const { return num_repaired_informations_; }

 private:
  struct EdgeKey {
    int from;
    int to;
    EdgeKind kind;
    bool operator<(const EdgeKey& o) const {
      return std::tie(from, to, kind) < std::tie(o.from, o.to, o.kind);
    }
  };
  struct SiteRecord {
    int64_t utime = 0;
    bool has_dr = false;
    PoseWithCovariance dr;  // world_from_body from dead reckoning
  };
  struct Pending {
    int from;
    int to;
    EdgeKind kind;
    PoseWithCovariance measurement;
  };

  AddResult AddEdge(int from, int to, EdgeKind kind, const PoseWithCovariance& measurement);
  // Stores a measurement until its sites are in the graph: replaces a
  // pending one of the same (from, to, kind), keeps at most max_pending.
  void AddPending(int from, int to, EdgeKind kind, const PoseWithCovariance& measurement);
  bool MakeEdge(const Pose3& from_T_to, const Matrix6d& covariance_vloc, mrpt::poses::CPose3DPDFGaussianInf* edge,
                std::string* error) const;
  // "" when `site_id` may belong to this traverse, else why not.
  std::string SiteIdProblem(int site_id) const;
  Matrix6d DrEdgeCovariance(int from, int to, const Pose3& relative, bool* fallback) const;
  void AddNode(int site_id, const Pose3& world_from_body);
  // The solver's problem: graph_'s nodes (ids[k] is pose k's site), edges_
  // in order (robust[k] > 0: edge k robust, its kernel width scaled by it);
  // `keep` (optional) chooses the edges.
  PoseGraph3 Problem(std::vector<mrpt::graphs::TNodeID>* ids, const std::vector<double>* robust = nullptr,
                     bool (*keep)(EdgeKind) = nullptr) const;
  // The solver's robust-kernel width scale of every edge (edges_ order, 0 =
  // not robust).
  std::vector<double> RobustEdgeScales() const;
  // The marginals of the graph without its loop and fix edges, at the
  // current estimate (empty when singular).
  std::map<mrpt::graphs::TNodeID, Matrix6d> MarginalsWithoutLoops() const;
  // A site's marginal from `prior`, or its nearest site's grown by the DR
  // model over the distance between them (zero for the root).
  Matrix6d MarginalOrNearest(mrpt::graphs::TNodeID id, const std::map<mrpt::graphs::TNodeID, Matrix6d>& prior) const;
  // A loop or fix edge's kernel scale (RobustEdgeScales).
  double LoopKernelScale(const EdgeKey& key, const mrpt::poses::CPose3DPDFGaussianInf& edge,
                         const std::map<mrpt::graphs::TNodeID, Matrix6d>& prior) const;
  void RetryPending();
  // The root's DR covariance carried to a site at world_from_site (zero
  // without one).
  Matrix6d RootUncertaintyAt(const Pose3& world_from_site) const;
  std::string Serialize(GraphFormat format) const;
  bool Deserialize(const std::string& text, std::string* error);
  // Deserialize's steps on a fresh graph: the g2o or MRPT text into graph_;
  // the # VLOC_ lines (sites, edge kinds and exact informations, pending
  // measurements beyond max_pending dropped oldest first); graph_'s edges
  // into edges_ with their kinds, informations repaired where needed.
  bool ReadGraphBody(const std::string& text, std::string* error);
  bool ReadAnnotations(const std::string& text, std::vector<EdgeKey>* kinds, std::vector<Matrix6d>* informations,
                       std::string* error);
  bool AdoptEdges(const std::vector<EdgeKey>& kinds, const std::vector<Matrix6d>& informations, std::string* error);

  PoseGraphOptions options_;
  mrpt::graphs::CNetworkOfPoses3DInf graph_;  // the nodes (site poses); its edges stay empty: edges_ holds them
  std::map<EdgeKey, mrpt::poses::CPose3DPDFGaussianInf> edges_;  // authoritative edge list
  std::map<int, SiteRecord> sites_;
  std::vector<Pending> pending_;
  std::map<mrpt::graphs::TNodeID, Matrix6d> marginals_;  // the solver's (MRPT's) local tangent
  bool have_root_ = false;
  int num_dr_fallbacks_ = 0;
  int num_repaired_informations_ = 0;      // loaded edges whose information was not positive definite
  double smallest_repaired_eigenvalue_ = 0;
  PoseGraphSummary summary_;
};

}  // namespace vloc::posegraph
