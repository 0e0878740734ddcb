#include "vloc/posegraph/graph_io.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <mrpt/poses/CPose3DQuat.h>
#include <set>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/common/printable.h"
#include "vloc/common/pose.h"
#include "vloc/posegraph/mrpt_graph.h"

namespace vloc::posegraph {

const char* GraphFormatName(GraphFormat format) {
  return format == GraphFormat::kG2o ? "g2o" : "MRPT/TORO text";
}

template <int N>
bool RepairInformation(Eigen::Matrix<double, N, N>* information, bool* repaired) {
  *repaired = false;
  if (!information->allFinite()) return false;
  Eigen::Matrix<double, N, N> sym = 0.5 * (*information + information->transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(sym);
  if (eig.info() != Eigen::Success) return false;
  Eigen::Matrix<double, N, 1> values = eig.eigenvalues();
  const double largest = values.maxCoeff();
  if (!(largest > 0)) return false;
  if (values.minCoeff() > 1e-9 * largest) return true;
  values = values.cwiseMax(1e-9 * largest);
  sym = eig.eigenvectors() * values.asDiagonal() * eig.eigenvectors().transpose();
  *information = 0.5 * (sym + sym.transpose());
  *repaired = true;
  return true;
}
template bool RepairInformation<3>(Eigen::Matrix3d*, bool*);
template bool RepairInformation<6>(Eigen::Matrix<double, 6, 6>*, bool*);

namespace {

using mrpt::graphs::TNodeID;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// The g2o rotation information is over the quaternion's vector part (half
// the rotation vector): I_theta = S I_q S.
Matrix6 QuatScale() {
  Eigen::Matrix<double, 6, 1> s;
  s << 1, 1, 1, 0.5, 0.5, 0.5;
  return s.asDiagonal();
}

mrpt::poses::CPose3D PoseFromQuat(double x, double y, double z, double qx, double qy, double qz, double qw) {
  Eigen::Quaterniond q(qw, qx, qy, qz);
  q.normalize();
  return ToMrpt(MakePose(q.toRotationMatrix(), Eigen::Vector3d(x, y, z)));
}

template <class Graph>
void ChainOdometry(Graph* graph, const std::set<TNodeID>& referenced) {
  using PoseT = typename Graph::constraint_t::type_value;
  if (referenced.empty()) return;
  std::multimap<TNodeID, std::pair<TNodeID, PoseT>> adjacent;  // id -> (other, id_from_other)
  for (const auto& [ids, edge] : graph->edges) {
    adjacent.emplace(ids.first, std::make_pair(ids.second, PoseT(edge.getPoseMean())));
    adjacent.emplace(ids.second, std::make_pair(ids.first, PoseT() - PoseT(edge.getPoseMean())));
  }
  auto place = [&](TNodeID from, TNodeID to, const PoseT& from_to) {
    graph->nodes[to] = graph->nodes.at(from) + from_to;
  };
  // Odometry first: i -> i+1 in id order.
  graph->nodes[*referenced.begin()] = PoseT();
  for (auto it = std::next(referenced.begin()); it != referenced.end(); ++it) {
    if (graph->nodes.count(*it) || !graph->nodes.count(*it - 1)) continue;
    const auto range = graph->edges.equal_range({*it - 1, *it});
    if (range.first != range.second) place(*it - 1, *it, PoseT(range.first->second.getPoseMean()));
  }
  // Then breadth first over any edge.
  std::deque<TNodeID> queue;
  for (const auto& n : graph->nodes) queue.push_back(n.first);
  while (!queue.empty()) {
    const TNodeID id = queue.front();
    queue.pop_front();
    const auto range = adjacent.equal_range(id);
    for (auto it = range.first; it != range.second; ++it)
      if (!graph->nodes.count(it->second.first)) {
        place(id, it->second.first, it->second.second);
        queue.push_back(it->second.first);
      }
  }
}

// What a file's records are checked against.
constexpr TNodeID kMaxVertexId = 2147483647;       // g2o's vertex ids are C ints
constexpr double kQuaternionNormTolerance = 1e-3;  // | |q| - 1 | beyond it: not a rotation (writers print >= 6 digits)

std::string Str(double v) {
  std::ostringstream os;
  os.precision(6);
  os << v;
  return os.str();
}

std::string RepairReport(int repaired, int skipped, const std::string& first_skipped, int indefinite) {
  if (!repaired && !skipped && !indefinite) return "";
  std::ostringstream os;
  os << "pose graph: ";
  if (indefinite)
    os << indefinite << " information matrices not positive definite as a whole (their translation and rotation "
       << "blocks are): SE-Sync's weights read only the blocks, unchanged; the file's chi2 is not an objective here"
       << (repaired || skipped ? "; " : "");
  if (skipped) os << skipped << " records of other types skipped (the first: " << first_skipped << ")";
  if (skipped && repaired) os << "; ";
  if (repaired)
    os << repaired << " information matrices only positive semi-definite, repaired by raising their eigenvalues "
       << "to 1e-9 of the largest (check the file's information convention)";
  return os.str();
}

// Numbers by strtod, which also takes "nan" and "inf" (streams refuse them):
// a non-finite value is then refused by name, not as a parse error.
struct Numbers {
  std::istringstream& s;
  template <class... T>
  bool Read(T*... values) {
    return (One(values) && ...);
  }
  bool One(double* v) {
    std::string token;
    if (!(s >> token)) return false;
    char* end = nullptr;
    *v = std::strtod(token.c_str(), &end);
    return end && *end == '\0';
  }
};

// One line of a graph file with a record on it: the key, the values after
// it, and how to fail naming the line.
struct Record {
  std::string key;
  std::istringstream rest;
  int line_number = 0;
  std::string line;
  std::string* error = nullptr;

  bool Refuse(const std::string& what) const { return Fail(error, "line " + std::to_string(line_number) + ": " + what); }
  bool Bad() const { return Refuse("cannot parse '" + Printable(line, 80) + "'"); }
  bool Unknown(const std::string& graph_kind) const {
    return Refuse("unknown record '" + Printable(key, 80) + "' in a " + graph_kind);
  }
  // A vertex id: a decimal integer in 0..kMaxVertexId ("-1" would wrap to 2^64 - 1 through a stream).
  bool ReadId(TNodeID* id) {
    std::string token;
    if (!(rest >> token)) return Bad();
    const bool digits = !token.empty() && token.size() <= 10 &&
                        token.find_first_not_of("0123456789") == std::string::npos;
    const unsigned long long value = digits ? std::strtoull(token.c_str(), nullptr, 10) : 0;
    if (!digits || value > kMaxVertexId)
      return Refuse("vertex id '" + Printable(token, 80) + "' is not an integer in 0.." + std::to_string(kMaxVertexId));
    *id = value;
    return true;
  }
  // "EDGE_SE2 3 -> 7", the edge as messages name it.
  std::string Edge(TNodeID i, TNodeID j) const { return key + " " + std::to_string(i) + " -> " + std::to_string(j); }
};

// Calls on_record for every line of `in` (from its start) that holds a
// record: blank lines and '#' comments skipped. False as soon as on_record
// returns false (with *error set).
template <class OnRecord>
bool ForEachRecord(std::istream& in, std::string* error, OnRecord&& on_record) {
  in.clear();
  in.seekg(0);
  Record r;
  r.error = error;
  while (std::getline(in, r.line)) {
    ++r.line_number;
    r.rest.clear();
    r.rest.str(r.line);
    if (!(r.rest >> r.key) || r.key[0] == '#') continue;
    if (!on_record(r)) return false;
  }
  return true;
}

bool CheckQuaternion(const Record& rec, const std::string& what, double qx, double qy, double qz, double qw) {
  const double norm = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
  if (std::abs(norm - 1.0) <= kQuaternionNormTolerance) return true;
  return rec.Refuse(what + ": quaternion norm " + Str(norm) + " is not 1 (tolerance " + Str(kQuaternionNormTolerance) +
                    "): not a rotation");
}

// Eigenvalues of a symmetric matrix, quoted "a to b".
template <int N>
std::string EigenvalueRange(const Eigen::Matrix<double, N, N>& m, double* smallest = nullptr) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(0.5 * (m + m.transpose()), Eigen::EigenvaluesOnly);
  if (smallest) *smallest = eig.info() == Eigen::Success ? eig.eigenvalues().minCoeff() : -1.0;
  return Str(eig.eigenvalues().minCoeff()) + " to " + Str(eig.eigenvalues().maxCoeff());
}

// Positive definite by Cholesky of its symmetric part.
template <int N>
bool PositiveDefinite(const Eigen::Matrix<double, N, N>& m) {
  const Eigen::Matrix<double, N, N> sym = 0.5 * (m + m.transpose());
  return Eigen::LLT<Eigen::Matrix<double, N, N>>(sym).info() == Eigen::Success;
}

// An edge's information, checked for what it is read for (file->information_use):
//  - kSeSyncBlocks: its translation and rotation blocks must be positive
//    definite (SE-Sync's weights come from their inverses); the whole matrix
//    is neither checked nor changed (counted when it is not positive definite);
//  - kChi2: the whole matrix must be positive (semi-)definite (an eigenvalue
//    below -1e-9 of the largest, or none positive, is refused, saying when its
//    blocks are positive definite); a semi-definite one is repaired
//    (RepairInformation) and counted.
// Not finite: refused either way.
template <int N>
bool CheckInformation(const Record& rec, const std::string& what, Eigen::Matrix<double, N, N>* information,
                      GraphFile* file) {
  constexpr int D = N == 6 ? 3 : 2, kRot = N - D;
  if (!information->allFinite()) return rec.Refuse(what + ": information matrix not finite (nan or inf in it)");
  const Eigen::Matrix<double, D, D> tt = information->template topLeftCorner<D, D>();
  const Eigen::Matrix<double, kRot, kRot> rr = information->template bottomRightCorner<kRot, kRot>();
  const bool blocks_pd = PositiveDefinite<D>(tt) && PositiveDefinite<kRot>(rr);
  if (file->information_use == InformationUse::kSeSyncBlocks) {
    if (!PositiveDefinite<D>(tt))
      return rec.Refuse(what + ": translation block of the information not positive definite (eigenvalues " +
                        EigenvalueRange<D>(tt) + "): SE-Sync's weight tau = " + std::to_string(D) +
                        " / tr(inv(I_tt)) needs it");
    if (!PositiveDefinite<kRot>(rr))
      return rec.Refuse(what + ": rotation block of the information not positive definite (eigenvalues " +
                        EigenvalueRange<kRot>(rr) + "): SE-Sync's weight kappa needs it");
    file->num_indefinite += PositiveDefinite<N>(*information) ? 0 : 1;
    return true;
  }
  double smallest = 0.0;
  const std::string range = EigenvalueRange<N>(*information, &smallest);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(0.5 * (*information + information->transpose()),
                                                                   Eigen::EigenvaluesOnly);
  const double largest = eig.eigenvalues().maxCoeff();
  bool repaired = false;
  if (eig.info() != Eigen::Success || !(largest > 0) || smallest < -1e-9 * largest ||
      !RepairInformation<N>(information, &repaired)) {
    if (blocks_pd && largest > 0)
      return rec.Refuse(what + ": information matrix not positive definite (eigenvalues " + range + ") though its "
                        "translation and rotation blocks are: the file's chi2 has no minimum; SE-Sync's weights read "
                        "only the blocks (vloc_posegraph --weights sesync)");
    return rec.Refuse(what + ": information matrix not positive definite (eigenvalues " + range + ")");
  }
  file->num_repaired += repaired ? 1 : 0;
  return true;
}

// The checks on an edge's ends: no self-loop, and both vertices defined
// when the file defines any.
template <class Graph>
bool CheckEnds(const Record& rec, const Graph& graph, TNodeID i, TNodeID j) {
  if (i == j) return rec.Refuse(rec.Edge(i, j) + ": an edge from a vertex to itself (a self-loop)");
  if (graph.nodes.empty()) return true;  // a file of edges only: poses from chained odometry
  for (const TNodeID id : {i, j})
    if (!graph.nodes.count(id))
      return rec.Refuse(rec.Edge(i, j) + ": vertex " + std::to_string(id) + " has no VERTEX line (the file defines " +
                        std::to_string(graph.nodes.size()) + "; an edge may only join those)");
  return true;
}

template <class Graph, class Pose>
bool AddVertex(const Record& rec, Graph* graph, TNodeID id, const Pose& pose) {
  if (!graph->nodes.emplace(id, pose).second)
    return rec.Refuse("vertex " + std::to_string(id) + " defined a second time");
  return true;
}

void InsertEdge(GraphFile* file, TNodeID i, TNodeID j, const mrpt::poses::CPose2D& mean, const Eigen::Matrix3d& info) {
  mrpt::poses::CPosePDFGaussianInf edge;
  edge.mean = mean;
  edge.cov_inv = mrpt::math::CMatrixDouble33(info);
  file->graph2.insertEdge(i, j, edge);
}

void InsertEdge(GraphFile* file, TNodeID i, TNodeID j, const mrpt::poses::CPose3D& mean, const Matrix6& info) {
  mrpt::poses::CPose3DPDFGaussianInf edge;
  edge.mean = mean;
  edge.cov_inv = mrpt::math::CMatrixDouble66(info);
  file->graph3.insertEdge(i, j, edge);
}

// Reads `in` in two passes: FIX and the vertices (is_vertex, on_vertex)
// first, so that every edge is checked against them at its own line; then
// every other record (on_other). A file with no vertex starts from chained
// odometry, and must then be connected.
template <class Graph, class IsVertex, class OnVertex, class OnOther>
bool ParseRecords(std::istream& in, GraphFile* file, Graph* graph, std::string* error, IsVertex&& is_vertex,
                  OnVertex&& on_vertex, OnOther&& on_other) {
  bool had_root = false;
  int root_line = 0;
  const bool vertices_ok = ForEachRecord(in, error, [&](Record& r) {
    if (r.key != "FIX") return is_vertex(r.key) ? on_vertex(r) : true;
    if (!r.ReadId(&graph->root)) return false;
    had_root = true;
    root_line = r.line_number;
    return true;
  });
  if (!vertices_ok) return false;
  file->had_vertices = !graph->nodes.empty();
  if (!ForEachRecord(in, error, [&](Record& r) { return r.key == "FIX" || is_vertex(r.key) || on_other(r); }))
    return false;
  if (!file->had_vertices) {
    std::set<TNodeID> referenced;
    for (const auto& [ids, edge] : graph->edges) {
      referenced.insert(ids.first);
      referenced.insert(ids.second);
    }
    ChainOdometry(graph, referenced);
    for (const TNodeID id : referenced)
      if (!graph->nodes.count(id))
        return Fail(error, "no VERTEX lines, and no chain of edges joins vertex " + std::to_string(id) + " to vertex " +
                               std::to_string(*referenced.begin()) + " (the graph is not connected): give the vertices");
  }
  if (!had_root) {
    if (!graph->nodes.empty()) graph->root = graph->nodes.begin()->first;
  } else if (!graph->nodes.count(graph->root)) {
    return Fail(error, "line " + std::to_string(root_line) + ": FIX " + std::to_string(graph->root) +
                           " names no vertex of the graph");
  }
  return true;
}

// The upper triangle of an N x N information matrix, row by row, mirrored (g2o's order).
template <int N>
bool ReadUpperTriangle(std::istringstream& s, Eigen::Matrix<double, N, N>* info) {
  for (int r = 0; r < N; ++r)
    for (int c = r; c < N; ++c) {
      if (!Numbers{s}.One(&(*info)(r, c))) return false;
      (*info)(c, r) = (*info)(r, c);
    }
  return true;
}

// The values of a g2o EDGE_SE3:QUAT record after its ends: x y z qx qy qz qw
// and the upper triangle of the information, checked, into the graph.
bool ReadG2oEdge3(Record& rec, TNodeID i, TNodeID j, GraphFile* file) {
  std::istringstream& s = rec.rest;
  const std::string what = rec.Edge(i, j);
  double x, y, z, qx, qy, qz, qw;
  Matrix6 info;
  if (!Numbers{s}.Read(&x, &y, &z, &qx, &qy, &qz, &qw) || !ReadUpperTriangle<6>(s, &info)) return rec.Bad();
  if (!std::isfinite(x + y + z + qx + qy + qz + qw)) return rec.Refuse(what + ": pose not finite");
  if (!CheckQuaternion(rec, what, qx, qy, qz, qw)) return false;
  if (!CheckInformation<6>(rec, what, &info, file)) return false;  // in the file's numbers
  InsertEdge(file, i, j, PoseFromQuat(x, y, z, qx, qy, qz, qw), QuatScale() * info * QuatScale());
  return true;
}

// The same for EDGE_SE2: x y theta and the information's upper triangle.
bool ReadG2oEdge2(Record& rec, TNodeID i, TNodeID j, GraphFile* file) {
  std::istringstream& s = rec.rest;
  const std::string what = rec.Edge(i, j);
  double x, y, th;
  Eigen::Matrix3d info;
  if (!Numbers{s}.Read(&x, &y, &th) || !ReadUpperTriangle<3>(s, &info)) return rec.Bad();
  if (!std::isfinite(x + y + th)) return rec.Refuse(what + ": pose not finite");
  if (!CheckInformation<3>(rec, what, &info, file)) return false;
  InsertEdge(file, i, j, mrpt::poses::CPose2D(x, y, th), info);
  return true;
}

// A g2o vertex record after its keyword: id and pose (x y z and a quaternion, or x y theta).
bool ReadG2oVertex(Record& rec, GraphFile* file) {
  std::istringstream& s = rec.rest;
  TNodeID id;
  if (!rec.ReadId(&id)) return false;
  const std::string what = "vertex " + std::to_string(id);
  if (file->dimension == 3) {
    double x, y, z, qx, qy, qz, qw;
    if (!Numbers{s}.Read(&x, &y, &z, &qx, &qy, &qz, &qw)) return rec.Bad();
    if (!std::isfinite(x + y + z + qx + qy + qz + qw)) return rec.Refuse(what + ": pose not finite");
    if (!CheckQuaternion(rec, what, qx, qy, qz, qw)) return false;
    return AddVertex(rec, &file->graph3, id, PoseFromQuat(x, y, z, qx, qy, qz, qw));
  }
  double x, y, th;
  if (!Numbers{s}.Read(&x, &y, &th)) return rec.Bad();
  if (!std::isfinite(x + y + th)) return rec.Refuse(what + ": pose not finite");
  return AddVertex(rec, &file->graph2, id, mrpt::poses::CPose2D(x, y, th));
}

// g2o: VERTEX_SE3:QUAT / EDGE_SE3:QUAT or VERTEX_SE2 / EDGE_SE2; records of
// other types (landmarks, priors, ...) skipped and counted.
bool ParseG2o(std::istream& in, GraphFile* file, std::string* error) {
  const bool three_d = file->dimension == 3;
  const std::string vertex_key = three_d ? "VERTEX_SE3:QUAT" : "VERTEX_SE2";
  const std::string edge_key = three_d ? "EDGE_SE3:QUAT" : "EDGE_SE2";
  const std::string other_vertex = three_d ? "VERTEX_SE2" : "VERTEX_SE3:QUAT";
  const std::string other_edge = three_d ? "EDGE_SE2" : "EDGE_SE3:QUAT";
  auto is_vertex = [&](const std::string& key) { return key == vertex_key; };
  auto on_other = [&](Record& rec) {
    if (rec.key == other_vertex || rec.key == other_edge)
      return rec.Refuse(rec.key + " in a " + std::to_string(file->dimension) + "D graph (its first record decides)");
    if (rec.key != edge_key) {
      if (file->num_skipped++ == 0) file->first_skipped = rec.key;
      return true;
    }
    TNodeID i, j;
    if (!rec.ReadId(&i) || !rec.ReadId(&j)) return false;
    if (!(three_d ? CheckEnds(rec, file->graph3, i, j) : CheckEnds(rec, file->graph2, i, j))) return false;
    return three_d ? ReadG2oEdge3(rec, i, j, file) : ReadG2oEdge2(rec, i, j, file);
  };
  auto on_vertex = [&](Record& rec) { return ReadG2oVertex(rec, file); };
  if (three_d) return ParseRecords(in, file, &file->graph3, error, is_vertex, on_vertex, on_other);
  return ParseRecords(in, file, &file->graph2, error, is_vertex, on_vertex, on_other);
}

// MRPT's 3D text records, read in MRPT's layout (VERTEX3 id x y z roll
// pitch yaw; EDGE3 i j x y z roll pitch yaw + the 21 values MRPT's writer
// puts out, rows 0 1 2 5 4 3 of its matrix). MRPT 2.5's own reader mirrors
// three entries it never read over the rotation cross terms; this one keeps
// them. Checked like the g2o records.
bool ParseMrpt3D(std::istream& in, GraphFile* file, std::string* error) {
  static const int kOrder[21][2] = {{0, 0}, {0, 1}, {0, 2}, {0, 5}, {0, 4}, {0, 3}, {1, 1}, {1, 2}, {1, 5}, {1, 4}, {1, 3},
                                    {2, 2}, {2, 5}, {2, 4}, {2, 3}, {5, 5}, {5, 4}, {5, 3}, {4, 4}, {4, 3}, {3, 3}};
  auto is_vertex = [](const std::string& key) { return key == "VERTEX3"; };
  auto on_vertex = [&](Record& rec) {
    TNodeID id;
    mrpt::math::TPose3D p;
    if (!rec.ReadId(&id)) return false;
    if (!Numbers{rec.rest}.Read(&p.x, &p.y, &p.z, &p.roll, &p.pitch, &p.yaw)) return rec.Bad();
    if (!std::isfinite(p.x + p.y + p.z + p.roll + p.pitch + p.yaw))
      return rec.Refuse("vertex " + std::to_string(id) + ": pose not finite");
    return AddVertex(rec, &file->graph3, id, mrpt::poses::CPose3D(p));
  };
  auto on_other = [&](Record& rec) {
    if (rec.key == "EQUIV") return true;
    if (rec.key != "EDGE3") return rec.Unknown("3D MRPT graph");
    TNodeID i, j;
    mrpt::math::TPose3D p;
    if (!rec.ReadId(&i) || !rec.ReadId(&j) || !CheckEnds(rec, file->graph3, i, j)) return false;
    if (!Numbers{rec.rest}.Read(&p.x, &p.y, &p.z, &p.roll, &p.pitch, &p.yaw)) return rec.Bad();
    Matrix6 info = Matrix6::Identity();
    double v;
    for (const auto& rc : kOrder) {
      if (!Numbers{rec.rest}.One(&v)) return rec.Bad();
      info(rc[0], rc[1]) = info(rc[1], rc[0]) = v;
    }
    if (!std::isfinite(p.x + p.y + p.z + p.roll + p.pitch + p.yaw)) return rec.Refuse(rec.Edge(i, j) + ": pose not finite");
    if (!CheckInformation<6>(rec, rec.Edge(i, j), &info, file)) return false;
    InsertEdge(file, i, j, mrpt::poses::CPose3D(p), info);
    return true;
  };
  return ParseRecords(in, file, &file->graph3, error, is_vertex, on_vertex, on_other);
}

// TORO's 2D records: VERTEX2 (or VERTEX) id x y theta; EDGE2 (or EDGE) i j
// dx dy dtheta I_xx I_xy I_yy I_tt I_xt I_yt (TORO's information order; MRPT
// 2.5's reader takes them in g2o's order, which swaps the cross terms).
bool ParseToro2D(std::istream& in, GraphFile* file, std::string* error) {
  auto is_vertex = [](const std::string& key) { return key == "VERTEX2" || key == "VERTEX"; };
  auto on_vertex = [&](Record& rec) {
    TNodeID id;
    double x, y, th;
    if (!rec.ReadId(&id)) return false;
    if (!Numbers{rec.rest}.Read(&x, &y, &th)) return rec.Bad();
    if (!std::isfinite(x + y + th)) return rec.Refuse("vertex " + std::to_string(id) + ": pose not finite");
    return AddVertex(rec, &file->graph2, id, mrpt::poses::CPose2D(x, y, th));
  };
  auto on_other = [&](Record& rec) {
    if (rec.key == "EQUIV") return true;
    if (rec.key != "EDGE2" && rec.key != "EDGE") return rec.Unknown("2D TORO graph");
    TNodeID i, j;
    double x, y, th, xx, xy, yy, tt, xt, yt;
    if (!rec.ReadId(&i) || !rec.ReadId(&j) || !CheckEnds(rec, file->graph2, i, j)) return false;
    if (!Numbers{rec.rest}.Read(&x, &y, &th, &xx, &xy, &yy, &tt, &xt, &yt)) return rec.Bad();
    if (!std::isfinite(x + y + th)) return rec.Refuse(rec.Edge(i, j) + ": pose not finite");
    Eigen::Matrix3d info;
    info << xx, xy, xt, xy, yy, yt, xt, yt, tt;
    if (!CheckInformation<3>(rec, rec.Edge(i, j), &info, file)) return false;
    InsertEdge(file, i, j, mrpt::poses::CPose2D(x, y, th), info);
    return true;
  };
  return ParseRecords(in, file, &file->graph2, error, is_vertex, on_vertex, on_other);
}

bool ParseGraphStream(std::istream& in, GraphFile* file, std::string* error, InformationUse use,
                      bool edges_required = true) {
  *file = GraphFile{};
  file->information_use = use;
  // The first vertex or edge keyword decides the dimension and format.
  std::string line, key;
  while (key.empty() && std::getline(in, line)) {
    std::istringstream s(line);
    std::string k;
    if (!(s >> k) || k[0] == '#') continue;
    if (k.rfind("VERTEX", 0) == 0 || k.rfind("EDGE", 0) == 0) key = k;
  }
  if (key.empty()) return Fail(error, "no VERTEX or EDGE line");
  const bool three_d = key == "VERTEX_SE3:QUAT" || key == "EDGE_SE3:QUAT" || key == "VERTEX3" || key == "EDGE3";
  const bool two_d = key == "VERTEX_SE2" || key == "EDGE_SE2" || key == "VERTEX2" || key == "EDGE2" ||
                     key == "VERTEX" || key == "EDGE";
  if (!three_d && !two_d)
    return Fail(error, "unknown record '" + Printable(key, 80) +
                           "' (expected VERTEX_SE3:QUAT/EDGE_SE3:QUAT, VERTEX_SE2/EDGE_SE2, VERTEX2/EDGE2 or VERTEX3/EDGE3)");
  file->dimension = three_d ? 3 : 2;
  file->format = key.find("_SE") != std::string::npos ? GraphFormat::kG2o : GraphFormat::kMrptText;
  bool ok;
  if (file->format == GraphFormat::kG2o) ok = ParseG2o(in, file, error);
  else if (three_d) ok = ParseMrpt3D(in, file, error);
  else ok = ParseToro2D(in, file, error);
  if (!ok) return false;
  if (edges_required && file->num_edges() == 0) return Fail(error, "no edge");
  file->repair_report = RepairReport(file->num_repaired, file->num_skipped, file->first_skipped, file->num_indefinite);
  return true;
}

}  // namespace

bool ParseGraphText(const std::string& text, GraphFile* file, std::string* error, InformationUse use) {
  std::istringstream in(text);
  return ParseGraphStream(in, file, error, use);
}

bool ParseGraph3Text(const std::string& text, mrpt::graphs::CNetworkOfPoses3DInf* graph, std::string* error,
                     std::string* repair_report) {
  std::istringstream in(text);
  GraphFile file;
  if (!ParseGraphStream(in, &file, error, InformationUse::kChi2, false)) return false;
  if (file.dimension != 3) return Fail(error, "a 2D graph where a 3D one is needed");
  *graph = std::move(file.graph3);
  *repair_report = file.repair_report;
  return true;
}

bool ReadGraphFile(const std::string& path, GraphFile* file, std::string* error, InformationUse use) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    *file = GraphFile{};
    return Fail(error, "cannot read pose graph file " + path + ": " +
                           (std::filesystem::exists(path, ec) ? "not a regular file" : "no such file"));
  }
  std::ifstream f(path);
  if (!f) return Fail(error, "cannot read pose graph file " + path);
  std::string sub;
  if (!ParseGraphStream(f, file, &sub, use)) return Fail(error, "pose graph file " + path + ": " + sub);
  return true;
}

std::string GraphText(const GraphFile& file) {
  std::ostringstream os;
  os.precision(17);
  if (file.format == GraphFormat::kMrptText) {
    if (file.dimension == 3) {
      file.graph3.writeAsText(os);  // VERTEX3 / EDGE3 (and FIX)
      return os.str();
    }
    // TORO's 2D records (MRPT writes 2D graphs with g2o's keywords).
    for (const auto& [id, p] : file.graph2.nodes)
      os << "VERTEX2 " << id << ' ' << p.x() << ' ' << p.y() << ' ' << p.phi() << '\n';
    for (const auto& [ids, edge] : file.graph2.edges) {
      const auto& I = edge.cov_inv;
      os << "EDGE2 " << ids.first << ' ' << ids.second << ' ' << edge.mean.x() << ' ' << edge.mean.y() << ' '
         << edge.mean.phi() << ' ' << I(0, 0) << ' ' << I(0, 1) << ' ' << I(1, 1) << ' ' << I(2, 2) << ' ' << I(0, 2)
         << ' ' << I(1, 2) << '\n';
    }
    os << "FIX " << file.graph2.root << '\n';
    return os.str();
  }
  if (file.dimension == 2) {
    for (const auto& [id, p] : file.graph2.nodes)
      os << "VERTEX_SE2 " << id << ' ' << p.x() << ' ' << p.y() << ' ' << p.phi() << '\n';
    for (const auto& [ids, edge] : file.graph2.edges) {
      os << "EDGE_SE2 " << ids.first << ' ' << ids.second << ' ' << edge.mean.x() << ' ' << edge.mean.y() << ' '
         << edge.mean.phi();
      for (int r = 0; r < 3; ++r)
        for (int c = r; c < 3; ++c) os << ' ' << edge.cov_inv(r, c);
      os << '\n';
    }
    os << "FIX " << file.graph2.root << '\n';
    return os.str();
  }
  auto write_pose = [&os](const mrpt::poses::CPose3D& p) {
    const Pose3 pose = FromMrpt(p);
    const Eigen::Quaterniond q(pose.linear());
    os << pose.translation().x() << ' ' << pose.translation().y() << ' ' << pose.translation().z() << ' ' << q.x()
       << ' ' << q.y() << ' ' << q.z() << ' ' << q.w();
  };
  for (const auto& [id, p] : file.graph3.nodes) {
    os << "VERTEX_SE3:QUAT " << id << ' ';
    write_pose(p);
    os << '\n';
  }
  const Matrix6 unscale = QuatScale().inverse();
  for (const auto& [ids, edge] : file.graph3.edges) {
    os << "EDGE_SE3:QUAT " << ids.first << ' ' << ids.second << ' ';
    write_pose(edge.mean);
    const Matrix6 info = unscale * edge.cov_inv.asEigen() * unscale;
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) os << ' ' << info(r, c);
    os << '\n';
  }
  os << "FIX " << file.graph3.root << '\n';
  return os.str();
}

bool WriteGraphFile(const std::string& path, const GraphFile& file, std::string* error) {
  std::string sub;
  if (!WriteFileAtomically(path, GraphText(file), &sub)) return Fail(error, "pose graph file: " + sub);
  return true;
}

}  // namespace vloc::posegraph
