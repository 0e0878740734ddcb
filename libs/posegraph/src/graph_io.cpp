#include "vloc/posegraph/graph_io.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <map>
#include <mrpt/poses/CPose3DQuat.h>
#include <set>
#include <sstream>

#include "vloc/common/options.h"
#include "vloc/common/pose.h"
#include "vloc/posegraph/mrpt_optimize.h"

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

template <class Graph>
void FinishGraph(Graph* graph, bool had_root) {
  std::set<TNodeID> referenced;
  for (const auto& [ids, edge] : graph->edges) {
    referenced.insert(ids.first);
    referenced.insert(ids.second);
  }
  bool missing = false;
  for (const TNodeID id : referenced) missing |= graph->nodes.count(id) == 0;
  if (missing) {
    graph->nodes.clear();
    ChainOdometry(graph, referenced);
  }
  if (!had_root && !graph->nodes.empty()) graph->root = graph->nodes.begin()->first;
}

std::string RepairReport(int repaired, int rejected, int skipped, const std::string& first_skipped) {
  if (!repaired && !rejected && !skipped) return "";
  std::ostringstream os;
  os << "pose graph: ";
  if (skipped) os << skipped << " records of other types skipped (the first: " << first_skipped << ")";
  if (skipped && (rejected || repaired)) os << "; ";
  if (rejected) os << rejected << " edges rejected (information matrix or pose not finite)";
  if (rejected && repaired) os << "; ";
  if (repaired)
    os << repaired << " information matrices not positive definite, repaired by raising their eigenvalues "
       << "to 1e-9 of the largest (check the file's information convention)";
  return os.str();
}

// Numbers by strtod, which also takes "nan" and "inf" (streams refuse them):
// a non-finite value is then the edge's problem, not a parse error.
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

// Repairs an edge's information in place; false (the edge counted as rejected) when its pose is not finite or the
// information is beyond repair; a repair is counted.
template <int N>
bool AcceptInformation(GraphFile* file, bool finite_pose, Eigen::Matrix<double, N, N>* information) {
  bool repaired = false;
  if (!finite_pose || !RepairInformation<N>(information, &repaired)) {
    ++file->num_rejected;
    return false;
  }
  file->num_repaired += repaired ? 1 : 0;
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

// One line of a graph file with a record on it: the key, the values after
// it, and how to fail naming the line.
struct Record {
  std::string key;
  std::istringstream rest;
  int line_number = 0;
  std::string line;
  std::string* error = nullptr;
  bool Bad() const { return Fail(error, "line " + std::to_string(line_number) + ": cannot parse '" + line + "'"); }
  bool Unknown(const std::string& graph_kind) const {
    return Fail(error, "line " + std::to_string(line_number) + ": unknown record '" + key + "' in a " + graph_kind);
  }
};

// Calls on_record for every line that holds a record (blank lines and '#'
// comments skipped) and reads FIX records itself (*root, *had_root). False
// as soon as a record fails (on_record returns false with *error set).
template <class OnRecord>
bool ForEachRecord(const std::string& text, std::string* error, TNodeID* root, bool* had_root, OnRecord&& on_record) {
  std::istringstream lines(text);
  Record r;
  r.error = error;
  while (std::getline(lines, r.line)) {
    ++r.line_number;
    r.rest.clear();
    r.rest.str(r.line);
    if (!(r.rest >> r.key) || r.key[0] == '#') continue;
    if (r.key == "FIX") {
      TNodeID id;
      if (!(r.rest >> id)) return r.Bad();
      *root = id;
      *had_root = true;
    } else if (!on_record(r)) {
      return false;
    }
  }
  return true;
}

bool ParseG2o(const std::string& text, GraphFile* file, std::string* error) {
  bool had_root = false;
  const bool ok = ForEachRecord(text, error, file->dimension == 2 ? &file->graph2.root : &file->graph3.root, &had_root, [&](Record& rec) {
    std::istringstream& s = rec.rest;
    const std::string& key = rec.key;
    if (key == "VERTEX_SE3:QUAT") {
      TNodeID id;
      double x, y, z, qx, qy, qz, qw;
      if (file->dimension != 3 || !(s >> id) || !Numbers{s}.Read(&x, &y, &z, &qx, &qy, &qz, &qw)) return rec.Bad();
      file->graph3.nodes[id] = PoseFromQuat(x, y, z, qx, qy, qz, qw);
    } else if (key == "EDGE_SE3:QUAT") {
      TNodeID i, j;
      double x, y, z, qx, qy, qz, qw;
      Matrix6 info;
      if (file->dimension != 3 || !(s >> i >> j) || !Numbers{s}.Read(&x, &y, &z, &qx, &qy, &qz, &qw)) return rec.Bad();
      for (int r = 0; r < 6; ++r)
        for (int c = r; c < 6; ++c) {
          if (!Numbers{s}.One(&info(r, c))) return rec.Bad();
          info(c, r) = info(r, c);
        }
      Matrix6 information = QuatScale() * info * QuatScale();
      if (!AcceptInformation<6>(file, std::isfinite(x + y + z + qx + qy + qz + qw), &information)) return true;
      InsertEdge(file, i, j, PoseFromQuat(x, y, z, qx, qy, qz, qw), information);
    } else if (key == "VERTEX_SE2") {
      TNodeID id;
      double x, y, th;
      if (file->dimension != 2 || !(s >> id) || !Numbers{s}.Read(&x, &y, &th)) return rec.Bad();
      file->graph2.nodes[id] = mrpt::poses::CPose2D(x, y, th);
    } else if (key == "EDGE_SE2") {
      TNodeID i, j;
      double x, y, th;
      Eigen::Matrix3d info;
      if (file->dimension != 2 || !(s >> i >> j) || !Numbers{s}.Read(&x, &y, &th)) return rec.Bad();
      for (int r = 0; r < 3; ++r)
        for (int c = r; c < 3; ++c) {
          if (!Numbers{s}.One(&info(r, c))) return rec.Bad();
          info(c, r) = info(r, c);
        }
      if (!AcceptInformation<3>(file, std::isfinite(x + y + th), &info)) return true;
      InsertEdge(file, i, j, mrpt::poses::CPose2D(x, y, th), info);
    } else {
      if (file->num_skipped++ == 0) file->first_skipped = key;
    }
    return true;
  });
  if (!ok) return false;
  if (file->dimension == 2) FinishGraph(&file->graph2, had_root);
  else FinishGraph(&file->graph3, had_root);
  return true;
}

// MRPT's 3D text records, read in MRPT's layout (VERTEX3 id x y z roll
// pitch yaw; EDGE3 i j x y z roll pitch yaw + the 21 values MRPT's writer
// puts out, rows 0 1 2 5 4 3 of its matrix). MRPT 2.5's own reader mirrors
// three entries it never read over the rotation cross terms; this one keeps
// them. Information matrices repaired / rejected like the g2o path.
bool ParseMrpt3D(const std::string& text, GraphFile* file, std::string* error) {
  static const int kOrder[21][2] = {{0, 0}, {0, 1}, {0, 2}, {0, 5}, {0, 4}, {0, 3}, {1, 1}, {1, 2}, {1, 5}, {1, 4}, {1, 3},
                                    {2, 2}, {2, 5}, {2, 4}, {2, 3}, {5, 5}, {5, 4}, {5, 3}, {4, 4}, {4, 3}, {3, 3}};
  bool had_root = false;
  const bool ok = ForEachRecord(text, error, &file->graph3.root, &had_root, [&](Record& rec) {
    std::istringstream& s = rec.rest;
    const std::string& key = rec.key;
    if (key == "VERTEX3") {
      TNodeID id;
      mrpt::math::TPose3D p;
      if (!(s >> id) || !Numbers{s}.Read(&p.x, &p.y, &p.z, &p.roll, &p.pitch, &p.yaw)) return rec.Bad();
      file->graph3.nodes[id] = mrpt::poses::CPose3D(p);
    } else if (key == "EDGE3") {
      TNodeID i, j;
      mrpt::math::TPose3D p;
      if (!(s >> i >> j) || !Numbers{s}.Read(&p.x, &p.y, &p.z, &p.roll, &p.pitch, &p.yaw)) return rec.Bad();
      Matrix6 info = Matrix6::Identity();
      double v;
      for (const auto& rc : kOrder) {
        if (!Numbers{s}.One(&v)) return rec.Bad();
        info(rc[0], rc[1]) = info(rc[1], rc[0]) = v;
      }
      if (!AcceptInformation<6>(file, std::isfinite(p.x + p.y + p.z + p.roll + p.pitch + p.yaw), &info)) return true;
      InsertEdge(file, i, j, mrpt::poses::CPose3D(p), info);
    } else if (key != "EQUIV") {
      return rec.Unknown("3D MRPT graph");
    }
    return true;
  });
  if (!ok) return false;
  FinishGraph(&file->graph3, had_root);
  return true;
}

// TORO's 2D records: VERTEX2 (or VERTEX) id x y theta; EDGE2 (or EDGE) i j
// dx dy dtheta I_xx I_xy I_yy I_tt I_xt I_yt (TORO's information order; MRPT
// 2.5's reader takes them in g2o's order, which swaps the cross terms).
bool ParseToro2D(const std::string& text, GraphFile* file, std::string* error) {
  bool had_root = false;
  const bool ok = ForEachRecord(text, error, &file->graph2.root, &had_root, [&](Record& rec) {
    std::istringstream& s = rec.rest;
    const std::string& key = rec.key;
    if (key == "VERTEX2" || key == "VERTEX") {
      TNodeID id;
      double x, y, th;
      if (!(s >> id) || !Numbers{s}.Read(&x, &y, &th)) return rec.Bad();
      file->graph2.nodes[id] = mrpt::poses::CPose2D(x, y, th);
    } else if (key == "EDGE2" || key == "EDGE") {
      TNodeID i, j;
      double x, y, th, xx, xy, yy, tt, xt, yt;
      if (!(s >> i >> j) || !Numbers{s}.Read(&x, &y, &th, &xx, &xy, &yy, &tt, &xt, &yt)) return rec.Bad();
      Eigen::Matrix3d info;
      info << xx, xy, xt, xy, yy, yt, xt, yt, tt;
      if (!AcceptInformation<3>(file, std::isfinite(x + y + th), &info)) return true;
      InsertEdge(file, i, j, mrpt::poses::CPose2D(x, y, th), info);
    } else if (key != "EQUIV") {
      return rec.Unknown("2D TORO graph");
    }
    return true;
  });
  if (!ok) return false;
  FinishGraph(&file->graph2, had_root);
  return true;
}

}  // namespace

bool ParseGraphText(const std::string& text, GraphFile* file, std::string* error) {
  *file = GraphFile{};
  // The first vertex or edge keyword decides the dimension and format.
  std::istringstream lines(text);
  std::string line, key;
  bool found = false, had_vertices = false;
  while (std::getline(lines, line)) {
    std::istringstream s(line);
    std::string k;
    if (!(s >> k) || k[0] == '#') continue;
    if (k.rfind("VERTEX", 0) == 0) had_vertices = true;
    if (!found && (k.rfind("VERTEX", 0) == 0 || k.rfind("EDGE", 0) == 0)) {
      key = k;
      found = true;
    }
  }
  if (!found) return Fail(error, "no VERTEX or EDGE line");
  const bool three_d = key == "VERTEX_SE3:QUAT" || key == "EDGE_SE3:QUAT" || key == "VERTEX3" || key == "EDGE3";
  const bool two_d = key == "VERTEX_SE2" || key == "EDGE_SE2" || key == "VERTEX2" || key == "EDGE2" ||
                     key == "VERTEX" || key == "EDGE";
  if (!three_d && !two_d)
    return Fail(error, "unknown record '" + key + "' (expected VERTEX_SE3:QUAT/EDGE_SE3:QUAT, VERTEX_SE2/EDGE_SE2, "
                       "VERTEX2/EDGE2 or VERTEX3/EDGE3)");
  file->dimension = three_d ? 3 : 2;
  file->format = key.find("_SE") != std::string::npos ? GraphFormat::kG2o : GraphFormat::kMrptText;
  file->had_vertices = had_vertices;
  bool ok;
  if (file->format == GraphFormat::kG2o) ok = ParseG2o(text, file, error);
  else if (three_d) ok = ParseMrpt3D(text, file, error);
  else ok = ParseToro2D(text, file, error);
  if (!ok) return false;
  if (file->num_edges() == 0) return Fail(error, "no usable edge");
  file->repair_report = RepairReport(file->num_repaired, file->num_rejected, file->num_skipped, file->first_skipped);
  return true;
}

bool ReadGraphFile(const std::string& path, GraphFile* file, std::string* error) {
  std::ifstream f(path);
  if (!f) return Fail(error, "cannot read pose graph file " + path);
  std::stringstream buffer;
  buffer << f.rdbuf();
  std::string sub;
  if (!ParseGraphText(buffer.str(), file, &sub)) return Fail(error, "pose graph file " + path + ": " + sub);
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
