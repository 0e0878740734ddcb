#pragma once
// Pose-graph files in and out of MRPT's graph types.
//
//   GraphFile file;
//   if (!ReadGraphFile("sphere2500.g2o", &file, &error)) ...   // 2D or 3D, g2o or MRPT/TORO
//   if (!file.repair_report.empty()) LOG(WARNING) << file.repair_report;
//   ... optimise file.graph3 (or file.graph2) ...
//   WriteGraphFile("out.g2o", file, &error);                  // in the format it was read in
//
// Formats (the first vertex/edge keyword decides):
//  - g2o: VERTEX_SE3:QUAT id x y z qx qy qz qw, EDGE_SE3:QUAT i j x y z qx qy
//    qz qw + 21 upper-triangular information values over [t, q_xyz]; and
//    VERTEX_SE2 id x y theta, EDGE_SE2 i j dx dy dtheta + 6 values over
//    [x y theta]. FIX id marks the fixed vertex.
//  - MRPT/TORO text: VERTEX2 / EDGE2 (2D, TORO's information order xx xy
//    yy tt xt yt) and VERTEX3 / EDGE3 (3D, roll pitch yaw, the information
//    in the layout MRPT's writer uses, read keeping the rotation cross terms
//    MRPT 2.5's own reader loses).
// Information matrices are held in the optimiser's tangent [t; rotation
// vector] (MRPT's): a g2o quaternion-vector information I_q becomes
// I_theta = S I S with S = diag(1,1,1,1/2,1/2,1/2), and back on writing.
// A file with edges but no vertices starts from chained odometry: the poses
// are composed along the edges i -> i+1 from the lowest id (at the origin),
// then along any edge to a pose not placed yet (the edges must connect them).
// A file that lies is refused at its first bad line (one line naming it):
// a vertex id that is not an integer in 0..2^31-1 (g2o's ids are ints), a
// vertex defined twice, an edge to a vertex the file does not define (when
// it defines any), a self-loop, a quaternion whose norm is more than 1e-3
// from 1, a pose or information matrix that is not finite, an information
// matrix not fit for the objective it is read for (InformationUse), a FIX
// naming no vertex.
// Information matrices are read for one objective:
//  - kChi2 (the file's own chi2): the whole matrix must be positive definite;
//    one with an eigenvalue below -1e-9 of the largest (or none positive) is
//    refused, and the line says when its translation and rotation blocks are
//    positive definite (real files hold such matrices: SE-Sync's cubicle has
//    5,021); a semi-definite one (a zero eigenvalue) is repaired (eigenvalues
//    raised to 1e-9 of the largest) and repair_report says how many;
//  - kSeSyncBlocks (SE-Sync's objective, whose weights come from the blocks
//    alone): the translation and rotation blocks must be positive definite;
//    the whole matrix is kept as the file gives it, never repaired, and
//    repair_report counts those that are not positive definite as a whole.

#include <Eigen/Core>
#include <mrpt/graphs/CNetworkOfPoses.h>
#include <string>

#include "vloc/posegraph/sesync_objective.h"
#include "vloc/posegraph/sparse_solver.h"

namespace vloc::posegraph {

enum class GraphFormat { kG2o, kMrptText };
enum class InformationUse { kChi2, kSeSyncBlocks };
const char* GraphFormatName(GraphFormat format);

struct GraphFile {
  int dimension = 3;                       // 2 or 3: which graph below holds the data
  GraphFormat format = GraphFormat::kG2o;  // format read (and to write back)
  mrpt::graphs::CNetworkOfPoses2DInf graph2;
  mrpt::graphs::CNetworkOfPoses3DInf graph3;
  bool had_vertices = true;                // false: poses from chained odometry
  InformationUse information_use = InformationUse::kChi2;  // what the information was read for (checked)
  int num_repaired = 0;                    // kChi2: semi-definite information matrices made positive definite
  int num_indefinite = 0;                  // kSeSyncBlocks: matrices not positive definite as a whole (blocks are)
  int num_skipped = 0;                     // g2o records of other types (landmarks, priors, ...) skipped
  std::string first_skipped;               // the first such record's type
  std::string repair_report;               // one line when any count is non-zero, else ""

  size_t num_nodes() const { return dimension == 2 ? graph2.nodes.size() : graph3.nodes.size(); }
  size_t num_edges() const { return dimension == 2 ? graph2.edges.size() : graph3.edges.size(); }
};

// False with *error naming the file and line when the file cannot be read or
// parsed, lies (above), or holds no edge.
bool ReadGraphFile(const std::string& path, GraphFile* file, std::string* error,
                   InformationUse use = InformationUse::kChi2);
bool ParseGraphText(const std::string& text, GraphFile* file, std::string* error,
                    InformationUse use = InformationUse::kChi2);
// A 3D graph in either format (g2o or MRPT's), checked the same way, which
// may have no edge (a traverse of one site); false with *error naming the line.
// *repair_report: GraphFile::repair_report (what was repaired or skipped).
bool ParseGraph3Text(const std::string& text, mrpt::graphs::CNetworkOfPoses3DInf* graph, std::string* error,
                     std::string* repair_report);

// Writes (atomically) in file.format; vertices hold the current poses.
bool WriteGraphFile(const std::string& path, const GraphFile& file, std::string* error);
std::string GraphText(const GraphFile& file);

// An information matrix made symmetric positive definite: eigenvalues below
// 1e-9 of the largest raised to it. Returns false when it is not finite or
// has no positive eigenvalue; *repaired says whether it changed.
template <int N>
bool RepairInformation(Eigen::Matrix<double, N, N>* information, bool* repaired);

// What OptimizeGraphFile did.
struct GraphFileReport {
  SolverSummary solver;          // the solve (its costs use the weights solved with)
  bool chi2_defined = true;      // false: some information matrices are not positive definite (SE-Sync reading)
  double initial_chi2 = 0.0;     // sum e^T W e with the file's information, at the file's poses
  double final_chi2 = 0.0;       // and at the optimum
  double initial_sesync = 0.0;   // SE-Sync's objective (sesync_objective.h) at the file's poses
  double final_sesync = 0.0;     // and at the optimum
  OptimalityCertificate certificate;  // for SE-Sync's objective (sesync_objective.h); with sesync_weights only

  std::string BriefReport() const;
};

// Optimises the poses of `file` in place (its root fixed), for the objective
// the file was read for: kChi2, the file's information matrices; kSeSyncBlocks,
// SE-Sync's objective exactly (its isotropic weights from the blocks,
// UseSeSyncWeights, on the chordal rotation residual), then its certificate.
// The file keeps its own information. The solver's failure is in
// report.solver (poses unchanged).
GraphFileReport OptimizeGraphFile(GraphFile* file, const SolverOptions& options);

}  // namespace vloc::posegraph
