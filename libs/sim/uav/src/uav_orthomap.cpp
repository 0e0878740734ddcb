#include "vloc/sim/uav_orthomap.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "vloc/common/options.h"

namespace vloc {

namespace {

bool PowerOfTwo(const int& n) { return n > 0 && (n & (n - 1)) == 0; }

}  // namespace

void OrthomapOptions::Visit(OptionsReader& r) {
  r.Optional("seed", &seed, "procedural map seed");
  r.Optional("size", &size, "m, side of the square procedural map");
  r.Optional("metres_per_pixel", &metres_per_pixel, "m/px of the procedural map or of `image`", InOpen(0.001, 10));
  r.Optional("centre", &centre, "m, world x/y of the map centre");
  r.Optional("image", &image, "path of a user orthomap (north up); empty = procedural");
  r.Optional("field_size", &field_size, "m, typical field side", Above(2));
  r.Optional("num_roads", &num_roads, "roads crossing the map", NonNegative());
  r.Optional("num_buildings", &num_buildings, "rectangular roofs", NonNegative());
  r.Optional("tree_density", &tree_density, "trees per m^2 outside forests", NonNegative());
  r.Optional("detail_amplitude", &detail_amplitude, "grey levels, 1-sigma of the fine detail texture; 0 = off",
             InRange(0, 80));
  r.Optional("detail_metres_per_pixel", &detail_metres_per_pixel, "m/px of the detail texture", Positive());
  r.Optional("detail_tile", &detail_tile, "px, side of the periodic detail tile (power of two)",
             InRange(64, 8192) && Rule<int>(PowerOfTwo, "a power of two"));
  r.Relation("size", !image.empty() || size > 10, "must be > 10 m (a procedural map)");
  r.Relation("size", !image.empty() || size / metres_per_pixel <= 20000,
             "must be <= 20000 px of metres_per_pixel (raise metres_per_pixel)");
}

bool OrthomapOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

namespace {

cv::Scalar Jitter(const cv::Scalar& c, double amount, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-amount, amount);
  const double k = 1.0 + u(rng);
  return cv::Scalar(std::clamp(c[0] * k + u(rng) * 20, 0.0, 255.0), std::clamp(c[1] * k + u(rng) * 20, 0.0, 255.0),
                    std::clamp(c[2] * k + u(rng) * 20, 0.0, 255.0));
}

// Sum of value-noise octaves (wavelength in px, amplitude) at size n x n, CV_32F.
cv::Mat ValueNoise(int n, const std::vector<std::pair<double, double>>& octaves, std::mt19937& rng) {
  cv::Mat sum(n, n, CV_32F, cv::Scalar(0));
  cv::RNG cvrng(rng());
  for (const auto& [wavelength, amplitude] : octaves) {
    const int k = std::max(2, static_cast<int>(std::ceil(n / wavelength)) + 1);
    cv::Mat grid(k, k, CV_32F);
    cvrng.fill(grid, cv::RNG::NORMAL, 0.0, amplitude);
    cv::Mat up;
    cv::resize(grid, up, cv::Size(n, n), 0, 0, cv::INTER_CUBIC);
    sum += up;
  }
  return sum;
}

}  // namespace

Orthomap::Orthomap(const OrthomapOptions& options) : options_(options) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  mpp_ = options_.metres_per_pixel;
  cv::Mat base;
  if (!options_.image.empty()) {
    base = cv::imread(options_.image, cv::IMREAD_COLOR);
    if (base.empty())
      throw std::runtime_error("orthomap image " + options_.image +
                               " cannot be read (missing or not an image); fix orthomap.image");
    const Eigen::Vector2d half(0.5 * base.cols * mpp_, 0.5 * base.rows * mpp_);
    min_ = options_.centre - half;
    max_ = options_.centre + half;
    levels_.push_back(base);
  } else {
    BuildProcedural();
  }
  while (levels_.back().cols > 256 && levels_.back().rows > 256 && levels_.size() < 8) {
    cv::Mat down;
    cv::pyrDown(levels_.back(), down);
    levels_.push_back(down);
  }
  BuildDetail();
}

cv::Matx33d Orthomap::PixelFromWorld(int level) const {
  // Level L pixel c covers level-0 pixels [c*2^L, (c+1)*2^L); centres at +0.5.
  const double s = 1.0 / (mpp_ * std::ldexp(1.0, level));
  return cv::Matx33d(s, 0, -min_.x() * s - 0.5, 0, -s, max_.y() * s - 0.5, 0, 0, 1);
}

cv::Matx33d Orthomap::DetailPixelFromWorld(int level) const {
  const double s = 1.0 / (options_.detail_metres_per_pixel * std::ldexp(1.0, level));
  // Rotated by an odd angle so the tile's period does not line up with roads or fields.
  const double a = 0.37, c = std::cos(a), sn = std::sin(a);
  return cv::Matx33d(s * c, s * sn, -0.5, s * sn, -s * c, -0.5, 0, 0, 1);
}

namespace {

// The procedural map being drawn: its pixels (n x n, BGR) and the world
// <-> pixel mapping (m/px, north up).
struct MapCanvas {
  cv::Mat map;
  Eigen::Vector2d min, max;
  double mpp = 0.1, side = 0, m = 10;  // m/px, m, px per metre
  int n = 0;
  cv::Point2d Px(const Eigen::Vector2d& w) const {
    return cv::Point2d((w.x() - min.x()) / mpp - 0.5, (max.y() - w.y()) / mpp - 0.5);
  }
  cv::Point IPx(const Eigen::Vector2d& w) const {
    const cv::Point2d p = Px(w);
    return cv::Point(static_cast<int>(std::lround(p.x)), static_cast<int>(std::lround(p.y)));
  }
};

// Crop rows / ploughing furrows inside a field's polygon.
void DrawFurrows(MapCanvas& c, const std::vector<cv::Point>& poly, const cv::Scalar& colour, std::mt19937& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  cv::Rect box = cv::boundingRect(poly) & cv::Rect(0, 0, c.n, c.n);
  if (box.area() <= 0) return;
  cv::Mat mask(box.size(), CV_8U, cv::Scalar(0));
  std::vector<cv::Point> local;
  for (const auto& p : poly) local.push_back(p - box.tl());
  cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{local}, cv::Scalar(255));
  cv::Mat stripes(box.size(), CV_8UC3, colour);
  const double angle = u01(rng) * M_PI;
  const double spacing = (0.6 + u01(rng) * 1.4) * c.m;
  const cv::Point2d dir(std::cos(angle), std::sin(angle)), normal(-dir.y, dir.x);
  const double reach = box.width + box.height;
  const cv::Scalar dark = colour * (0.7 + 0.15 * u01(rng));
  const int thickness = std::max(1, static_cast<int>(spacing * 0.35));
  for (double o = -reach; o <= reach; o += spacing) {
    const cv::Point2d centre = cv::Point2d(box.width / 2.0, box.height / 2.0) + normal * o;
    cv::line(stripes, centre - dir * reach, centre + dir * reach, dark, thickness);
  }
  stripes.copyTo(c.map(box), mask);
}

// 1. Fields on a jittered grid; returns the forests' polygons.
std::vector<std::vector<cv::Point>> DrawFields(MapCanvas& c, const OrthomapOptions& o, std::mt19937& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const cv::Scalar palette[] = {
      {60, 140, 90},   // green crop
      {80, 170, 200},  // ripe wheat
      {60, 95, 135},   // bare soil
      {70, 130, 95},   // meadow
      {40, 80, 45},    // forest floor
      {95, 150, 120},  // pale grass
  };
  const int g = static_cast<int>(std::ceil(c.side / o.field_size)) + 1;
  std::vector<Eigen::Vector2d> grid(static_cast<size_t>((g + 1) * (g + 1)));
  for (int j = 0; j <= g; ++j)
    for (int i = 0; i <= g; ++i) {
      Eigen::Vector2d p = c.min + Eigen::Vector2d(i, j) * o.field_size;
      p += Eigen::Vector2d(u01(rng) - 0.5, u01(rng) - 0.5) * 0.5 * o.field_size;
      grid[static_cast<size_t>(j * (g + 1) + i)] = p;
    }
  std::vector<std::vector<cv::Point>> forests;
  for (int j = 0; j < g; ++j)
    for (int i = 0; i < g; ++i) {
      std::vector<cv::Point> poly = {c.IPx(grid[static_cast<size_t>(j * (g + 1) + i)]),
                                     c.IPx(grid[static_cast<size_t>(j * (g + 1) + i + 1)]),
                                     c.IPx(grid[static_cast<size_t>((j + 1) * (g + 1) + i + 1)]),
                                     c.IPx(grid[static_cast<size_t>((j + 1) * (g + 1) + i)])};
      const int type = static_cast<int>(u01(rng) * 6) % 6;
      const cv::Scalar colour = Jitter(palette[type], 0.15, rng);
      cv::fillPoly(c.map, std::vector<std::vector<cv::Point>>{poly}, colour);
      if (type == 4) forests.push_back(poly);
      if (type <= 2) DrawFurrows(c, poly, colour, rng);
    }
  return forests;
}

// A gently curving polyline through p, both ways to 20 m past the map.
GroundPath CurvingRoad(const MapCanvas& c, const Eigen::Vector2d& p, double heading, std::mt19937& rng) {
  GroundPath forward, backward;
  for (int dir = 0; dir < 2; ++dir) {
    Eigen::Vector2d q = p;
    double h = heading + dir * M_PI;
    GroundPath& path = dir == 0 ? forward : backward;
    std::normal_distribution<double> turn(0.0, 0.06);
    while (q.x() > c.min.x() - 20 && q.x() < c.max.x() + 20 && q.y() > c.min.y() - 20 && q.y() < c.max.y() + 20) {
      path.push_back(q);
      h += turn(rng);
      q += 10.0 * Eigen::Vector2d(std::cos(h), std::sin(h));
    }
    path.push_back(q);
  }
  GroundPath road(backward.rbegin(), backward.rend());
  road.insert(road.end(), forward.begin() + 1, forward.end());
  return road;
}

// 2. Roads, paved (a dashed centre line) or dirt; road 0 passes through the
// map centre. Returns their centre lines.
std::vector<GroundPath> DrawRoads(MapCanvas& c, const OrthomapOptions& o, std::mt19937& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<GroundPath> roads;
  const double m = c.m;
  for (int r = 0; r < o.num_roads; ++r) {
    Eigen::Vector2d p = o.centre + Eigen::Vector2d(u01(rng) - 0.5, u01(rng) - 0.5) * (r == 0 ? 20.0 : c.side * 0.8);
    const double heading = u01(rng) * 2 * M_PI;
    const GroundPath road = CurvingRoad(c, p, heading, rng);
    roads.push_back(road);
    std::vector<cv::Point> line;
    for (const auto& w : road) line.push_back(c.IPx(w));
    const bool paved = r % 3 != 2;
    const double width = paved ? 7.0 : 3.5;
    cv::polylines(c.map, std::vector<std::vector<cv::Point>>{line}, false,
                  paved ? cv::Scalar(150, 150, 150) : cv::Scalar(120, 160, 185), static_cast<int>((width + 1.0) * m));
    cv::polylines(c.map, std::vector<std::vector<cv::Point>>{line}, false,
                  paved ? cv::Scalar(85, 85, 88) : cv::Scalar(95, 130, 155), static_cast<int>(width * m));
    if (!paved) continue;
    // Dashed centre line: 3 m dashes every 9 m.
    for (size_t k = 0; k + 1 < road.size(); ++k) {
      const Eigen::Vector2d a = road[k], b = road[k + 1];
      const Eigen::Vector2d d = (b - a).normalized();
      for (double s = 0; s < (b - a).norm(); s += 9.0)
        cv::line(c.map, c.Px(a + d * s), c.Px(a + d * std::min(s + 3.0, (b - a).norm())), cv::Scalar(235, 235, 235),
                 std::max(1, static_cast<int>(0.15 * m)));
    }
  }
  return roads;
}

// The distance from c to the nearest road centre line.
double RoadClearance(const Eigen::Vector2d& c, const std::vector<GroundPath>& roads) {
  double clearance = 1e300;
  for (const GroundPath& road : roads)
    for (size_t k = 0; k + 1 < road.size(); ++k) {
      const Eigen::Vector2d d = road[k + 1] - road[k];
      const double f = std::clamp((c - road[k]).dot(d) / std::max(d.squaredNorm(), 1e-9), 0.0, 1.0);
      clearance = std::min(clearance, (c - road[k] - f * d).norm());
    }
  return clearance;
}

// 3. Buildings off the roads: roofs with a ridge and a shadow towards the
// north-east.
void DrawBuildings(MapCanvas& c, const OrthomapOptions& o, const std::vector<GroundPath>& roads, std::mt19937& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double m = c.m;
  for (int b = 0; b < o.num_buildings; ++b) {
    const Eigen::Vector2d centre = c.min + Eigen::Vector2d(u01(rng), u01(rng)) * c.side;
    const double w = 6 + u01(rng) * 14, l = 8 + u01(rng) * 22, a = u01(rng) * M_PI;
    if (RoadClearance(centre, roads) < 0.5 * std::hypot(w, l) + 8.0) continue;
    const cv::RotatedRect roof(c.Px(centre), cv::Size2f(static_cast<float>(l * m), static_cast<float>(w * m)),
                               static_cast<float>(a * 180 / M_PI));
    cv::Point2f corners[4];
    cv::RotatedRect shadow = roof;
    shadow.center += cv::Point2f(static_cast<float>(2.5 * m), static_cast<float>(-2.5 * m));
    shadow.points(corners);
    std::vector<cv::Point> poly(corners, corners + 4);
    cv::fillConvexPoly(c.map, poly, cv::Scalar(35, 40, 40));
    roof.points(corners);
    poly.assign(corners, corners + 4);
    const cv::Scalar roof_colour =
        u01(rng) < 0.5 ? Jitter(cv::Scalar(60, 80, 170), 0.2, rng) : Jitter(cv::Scalar(150, 150, 155), 0.2, rng);
    cv::fillConvexPoly(c.map, poly, roof_colour);
    // Ridge along the long side; one half of the roof darker.
    const cv::Point2f m01 = (corners[0] + corners[1]) * 0.5f, m23 = (corners[2] + corners[3]) * 0.5f;
    const cv::Point2f m12 = (corners[1] + corners[2]) * 0.5f, m30 = (corners[3] + corners[0]) * 0.5f;
    const bool long01 = cv::norm(corners[0] - corners[1]) > cv::norm(corners[1] - corners[2]);
    std::vector<cv::Point> half = long01 ? std::vector<cv::Point>{corners[0], corners[1], m12, m30}
                                         : std::vector<cv::Point>{corners[1], corners[2], m23, m01};
    cv::fillConvexPoly(c.map, half, roof_colour * 0.75);
    cv::line(c.map, long01 ? m12 : m23, long01 ? m30 : m01, roof_colour * 1.2, std::max(1, static_cast<int>(0.3 * m)));
  }
}

// Where the trees stand: scattered, plus dense stands in the forest fields.
std::vector<Eigen::Vector2d> TreePositions(const MapCanvas& c, const OrthomapOptions& o,
                                           const std::vector<std::vector<cv::Point>>& forests, std::mt19937& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<Eigen::Vector2d> trees;
  const int scattered = static_cast<int>(o.tree_density * c.side * c.side);
  for (int k = 0; k < scattered; ++k) trees.push_back(c.min + Eigen::Vector2d(u01(rng), u01(rng)) * c.side);
  for (const auto& poly : forests) {
    const cv::Rect box = cv::boundingRect(poly);
    const double area = box.area() * c.mpp * c.mpp;
    const int count = static_cast<int>(area / 16.0);
    for (int k = 0; k < count; ++k) {
      const cv::Point2f p(static_cast<float>(box.x + u01(rng) * box.width), static_cast<float>(box.y + u01(rng) * box.height));
      if (cv::pointPolygonTest(poly, p, false) < 0) continue;
      trees.push_back(Eigen::Vector2d(c.min.x() + (p.x + 0.5) * c.mpp, c.max.y() - (p.y + 0.5) * c.mpp));
    }
  }
  return trees;
}

// 4. A tree: a lumpy crown of a few overlapping blobs, its shadow cast to
// the north-east.
void DrawTree(MapCanvas& c, const Eigen::Vector2d& t, std::mt19937& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double m = c.m;
  const double radius = 1.2 + u01(rng) * 2.5;
  const cv::Point2d centre = c.Px(t);
  const int lobes = 4 + static_cast<int>(u01(rng) * 4);
  std::vector<std::pair<cv::Point2d, double>> blobs;
  for (int k = 0; k < lobes; ++k) {
    const double a = u01(rng) * 2 * M_PI, d = (k == 0 ? 0.0 : 0.35 + 0.2 * u01(rng)) * radius;
    blobs.push_back({centre + cv::Point2d(std::cos(a) * d * m, std::sin(a) * d * m), (0.45 + 0.25 * u01(rng)) * radius * m});
  }
  const cv::Point2d shadow(0.5 * radius * m, -0.5 * radius * m);
  for (const auto& [p, r] : blobs)
    cv::circle(c.map, p + shadow, static_cast<int>(r), cv::Scalar(30, 45, 35), cv::FILLED);
  const cv::Scalar crown = Jitter(cv::Scalar(40, 95, 55), 0.25, rng);
  for (const auto& [p, r] : blobs) {
    const cv::Scalar lobe = crown * (0.85 + 0.3 * u01(rng));
    cv::circle(c.map, p, static_cast<int>(r), lobe, cv::FILLED);
    cv::circle(c.map, p - cv::Point2d(0.3 * r, -0.3 * r), static_cast<int>(0.5 * r), lobe * 1.2, cv::FILLED);
  }
}

// 5. Multi-scale brightness variation (60 m down to 0.3 m) and per-pixel grain.
void VaryBrightness(MapCanvas& c, std::mt19937& rng) {
  const int n = c.n;
  const double m = c.m;
  cv::Mat coarse = ValueNoise(n / 8, {{60.0 * m / 8, 0.10}, {15.0 * m / 8, 0.08}, {4.0 * m / 8, 0.07}}, rng);
  cv::Mat noise;
  cv::resize(coarse, noise, cv::Size(n, n), 0, 0, cv::INTER_LINEAR);
  coarse.release();
  cv::Mat fine = ValueNoise(n, {{1.0 * m, 0.08}}, rng);
  noise += fine;
  fine.release();
  cv::RNG grain_rng(rng());
#pragma omp parallel for schedule(static)
  for (int row = 0; row < n; ++row) {
    cv::RNG row_rng(grain_rng.state + static_cast<uint64_t>(row) * 7919u);
    const float* f = noise.ptr<float>(row);
    cv::Vec3b* p = c.map.ptr<cv::Vec3b>(row);
    for (int col = 0; col < n; ++col) {
      const float k = 1.0f + f[col] + static_cast<float>(row_rng.gaussian(0.06));
      for (int ch = 0; ch < 3; ++ch) p[col][ch] = cv::saturate_cast<uchar>(p[col][ch] * k);
    }
  }
}

}  // namespace

void Orthomap::BuildProcedural() {
  std::mt19937 rng(static_cast<uint32_t>(options_.seed));
  MapCanvas c;
  // Square map whose side is a multiple of 32 px so pyramid levels line up.
  c.n = static_cast<int>(std::ceil(options_.size / mpp_ / 32.0)) * 32;
  c.mpp = mpp_;
  c.side = c.n * mpp_;
  c.m = 1.0 / mpp_;
  min_ = c.min = options_.centre - Eigen::Vector2d(0.5 * c.side, 0.5 * c.side);
  max_ = c.max = options_.centre + Eigen::Vector2d(0.5 * c.side, 0.5 * c.side);
  c.map = cv::Mat(c.n, c.n, CV_8UC3, cv::Scalar(70, 120, 100));
  const std::vector<std::vector<cv::Point>> forests = DrawFields(c, options_, rng);
  roads_ = DrawRoads(c, options_, rng);
  DrawBuildings(c, options_, roads_, rng);
  for (const auto& t : TreePositions(c, options_, forests, rng)) DrawTree(c, t, rng);
  VaryBrightness(c, rng);
  levels_.push_back(c.map);
}

void Orthomap::BuildDetail() {
  if (options_.detail_amplitude <= 0) return;
  const int t = options_.detail_tile;
  cv::RNG rng(static_cast<uint64_t>(options_.seed) * 2654435761u + 17u);
  cv::Mat white(t, t, CV_32F);
  rng.fill(white, cv::RNG::NORMAL, 0.0, 1.0);
  cv::Mat spectrum;
  cv::dft(white, spectrum, cv::DFT_COMPLEX_OUTPUT);
  // Pink-ish band between 3 cm and 3 m wavelengths: amplitude ~ 1/f^0.8.
  const double dm = options_.detail_metres_per_pixel;
  for (int v = 0; v < t; ++v) {
    cv::Vec2f* row = spectrum.ptr<cv::Vec2f>(v);
    const double fy = (v <= t / 2 ? v : v - t) / (t * dm);
    for (int u = 0; u < t; ++u) {
      const double fx = (u <= t / 2 ? u : u - t) / (t * dm);
      const double f = std::sqrt(fx * fx + fy * fy);  // cycles per metre
      double a = 0;
      if (f > 1.0 / 3.0 && f < 1.0 / 0.03) a = std::pow(f, -0.8);
      row[u] *= static_cast<float>(a);
    }
  }
  cv::Mat tile;
  cv::idft(spectrum, tile, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  cv::Scalar mean, stddev;
  cv::meanStdDev(tile, mean, stddev);
  cv::Mat tile8;
  const double k = options_.detail_amplitude / std::max(stddev[0], 1e-12);
  tile.convertTo(tile8, CV_8U, k, 128.0 - mean[0] * k);
  detail_.push_back(tile8);
  while (detail_.back().cols > 64) {
    cv::Mat down;
    cv::pyrDown(detail_.back(), down);
    detail_.push_back(down);
  }
}

}  // namespace vloc
