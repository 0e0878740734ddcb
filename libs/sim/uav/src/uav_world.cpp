#include "vloc/sim/uav_world.h"

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "vloc/common/options.h"

namespace vloc {

// ---------------------------------------------------------------- options

namespace {
const std::vector<std::pair<std::string, int>>& ArucoDictionaries() {
  static const std::vector<std::pair<std::string, int>> names = {
      {"DICT_4X4_50", cv::aruco::DICT_4X4_50},         {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
      {"DICT_5X5_50", cv::aruco::DICT_5X5_50},         {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
      {"DICT_6X6_50", cv::aruco::DICT_6X6_50},         {"DICT_6X6_250", cv::aruco::DICT_6X6_250},
      {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL}};
  return names;
}
int ArucoDictionaryId(const std::string& name) {
  for (const auto& [n, id] : ArucoDictionaries())
    if (n == name) return id;
  return -1;
}
bool KnownDictionary(const std::string& name) { return ArucoDictionaryId(name) >= 0; }
}  // namespace

void UavMarkerOptions::Visit(OptionsReader& r) {
  r.Optional("enabled", &enabled, "draw the calibration marker");
  r.Optional("dictionary", &dictionary, "cv::aruco predefined dictionary, e.g. DICT_4X4_50",
             Rule<std::string>(KnownDictionary, "a cv::aruco dictionary (DICT_4X4_50, DICT_5X5_100, DICT_6X6_250, ...)"));
  r.Optional("id", &id, "marker id", InRightOpen(0, 50));
  r.Optional("size", &size, "m, side of the marker's black square", InOpen(0.05, 50));
  r.Optional("position", &position, "m, world x/y of the marker centre");
  r.Optional("yaw", &yaw, "rad, marker rotation about z (0: marker top to north)");
}

bool UavMarkerOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void UavObjectsOptions::Visit(OptionsReader& r) {
  r.Optional("num_cars", &num_cars, "cars", NonNegative());
  r.Optional("num_people", &num_people, "people", NonNegative());
  r.Optional("car_speed", &car_speed, "m/s, mean car speed", NonNegative());
  r.Optional("person_speed", &person_speed, "m/s, mean walking speed", NonNegative());
  r.Optional("area_radius", &area_radius, "m, objects stay this close to the take-off point", Positive());
  r.Optional("seed", &seed, "placement seed");
}

bool UavObjectsOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void UavRenderOptions::Visit(OptionsReader& r) {
  r.Optional("noise_sigma", &noise_sigma, "grey levels, 1-sigma sensor noise", InRange(0, 40));
  r.Optional("moving_objects", &moving_objects, "draw cars and people");
  r.Optional("seed", &seed, "sensor noise seed");
}

bool UavRenderOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

PinholeCamera UavWorldOptions::DefaultUavCamera() {
  PinholeCamera c;
  c.width = 1280;
  c.height = 720;
  c.fx = c.fy = 1000.0;
  c.cx = 639.5;
  c.cy = 359.5;
  return c;
}

void UavTreesOptions::Visit(OptionsReader& r) {
  r.Optional("num_trees", &num_trees, "crowns in the wooded area (0 = none)", InRange(0, 100000));
  r.Optional("centre", &centre, "m, world x/y of the wooded area's centre");
  r.Optional("area_radius", &area_radius, "m, crowns within this distance of the centre", Positive());
  r.Optional("min_height", &min_height, "m, lowest crown top", Positive());
  r.Optional("max_height", &max_height, "m, highest crown top");
  r.Optional("min_radius", &min_radius, "m, smallest crown radius", Positive());
  r.Optional("max_radius", &max_radius, "m, largest crown radius");
  r.Optional("seed", &seed, "placement and texture seed");
  r.Relation("max_height", max_height >= min_height, "must be >= min_height");
  r.Relation("max_radius", max_radius >= min_radius, "must be >= min_radius");
}

bool UavTreesOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void UavWorldOptions::Visit(OptionsReader& r) {
  r.Child("camera", [&](OptionsReader& c) { camera.Visit(c); });
  r.Optional("fps", &fps, "frames/s", InLeftOpen(0, 240));
  r.Child("orthomap", [&](OptionsReader& c) { orthomap.Visit(c); });
  r.Child("marker", [&](OptionsReader& c) { marker.Visit(c); });
  r.Child("objects", [&](OptionsReader& c) { objects.Visit(c); });
  r.Child("trees", [&](OptionsReader& c) { trees.Visit(c); });
  r.Child("flight", [&](OptionsReader& c) { flight.Visit(c); });
  r.Child("gps", [&](OptionsReader& c) { gps.Visit(c); });
  r.Child("render", [&](OptionsReader& c) { render.Visit(c); });
}

bool UavWorldOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

// ---------------------------------------------------------------- world

namespace {

struct MovingObject {
  GroundPath path;      // ping-pong along this polyline
  std::vector<double> cumulative;  // arc length at each vertex
  double speed = 0;     // m/s
  double phase = 0;     // m, arc length at t = 0
  double length = 4.4, width = 1.8;  // m
  bool car = true;
  cv::Scalar colour;
};

cv::Matx33d ToCv(const Eigen::Matrix3d& m) {
  return cv::Matx33d(m(0, 0), m(0, 1), m(0, 2), m(1, 0), m(1, 1), m(1, 2), m(2, 0), m(2, 1), m(2, 2));
}

cv::Matx33d Translation(double dx, double dy) { return cv::Matx33d(1, 0, dx, 0, 1, dy, 0, 0, 1); }

// The pyramid level to sample for a ground sample distance `gsd` (m/px)
// from a texture of `texel` m/px: the finest level that is not minified by
// more than ~10 % (minifying bilinear sampling aliases; magnifying only blurs).
int PyramidLevel(double gsd, double texel) {
  return std::max(0, static_cast<int>(std::ceil(std::log2(gsd / texel) - 0.15)));
}

// image += offset - 128 (saturated); `offset` has the type and size of
// `image`. Integer arithmetic, SIMD, rows in parallel.
void AddOffset(const cv::Mat& offset, cv::Mat* image) {
  const int n = image->cols * image->channels();
  cv::parallel_for_(cv::Range(0, image->rows), [&](const cv::Range& rows) {
    for (int r = rows.start; r < rows.end; ++r) {
      uchar* p = image->ptr<uchar>(r);
      const uchar* o = offset.ptr<uchar>(r);
#pragma omp simd
      for (int i = 0; i < n; ++i) {
        const int v = p[i] + o[i] - 128;
        p[i] = static_cast<uchar>(v < 0 ? 0 : (v > 255 ? 255 : v));
      }
    }
  });
}

// A tree crown seen from above.
struct CrownTree {
  double x = 0, y = 0, height = 0, radius = 0;  // m
  cv::Mat texture, mask;                        // BGR crown and its disc (kCrownPx square)
};

// The marker's texture and where its pixels lie on the ground.
struct MarkerTexture {
  cv::Mat texture;            // CV_8UC3, 8 x 8 cells (1 white cell around the 6-cell marker)
  cv::Matx33d world_from_px;  // texture pixel -> world metres
};

// Distortion: the ideal canvas (with margins) every raw pixel falls in,
// and the raw -> canvas maps (empty without distortion).
struct DistortionCanvas {
  cv::Size size;
  double margin_x = 0, margin_y = 0;
  cv::Mat map_x, map_y;
};

}  // namespace

struct UavWorld::Impl {
  MarkerTexture marker;                 // empty texture without a marker
  std::vector<MovingObject> objects;
  cv::Mat noise_bank;                   // CV_8UC3, 128 + N(0, sigma), larger than a frame
  DistortionCanvas distortion;
  // Per detail level: the periodic tile repeated to cover a whole frame footprint.
  std::vector<cv::Mat> detail_tiled;
  // Tree crowns, lowest first (drawn in that order: higher crowns hide lower ones).
  std::vector<CrownTree> trees;
};

namespace {

constexpr int kCrownPx = 256;  // crown texture side

// Tree crowns: textured discs (leaf clumps at several scales, darker rim),
// lowest first.
std::vector<CrownTree> MakeTrees(const UavTreesOptions& to) {
  std::vector<CrownTree> trees;
  cv::RNG rng(static_cast<uint64_t>(to.seed) * 7919 + 17);
  for (int i = 0; i < to.num_trees; ++i) {
    CrownTree tree;
    const double a = rng.uniform(0.0, 2 * M_PI), d = to.area_radius * std::sqrt(rng.uniform(0.0, 1.0));
    tree.x = to.centre.x() + d * std::cos(a);
    tree.y = to.centre.y() + d * std::sin(a);
    tree.height = rng.uniform(to.min_height, to.max_height);
    tree.radius = rng.uniform(to.min_radius, to.max_radius);
    cv::Mat tex(kCrownPx, kCrownPx, CV_32F, cv::Scalar(0));
    for (const int cell : {2, 4, 8, 16, 32}) {
      cv::Mat n(kCrownPx / cell + 1, kCrownPx / cell + 1, CV_32F);
      rng.fill(n, cv::RNG::NORMAL, 0.0, 1.0);
      cv::Mat up;
      cv::resize(n, up, cv::Size(kCrownPx, kCrownPx), 0, 0, cv::INTER_CUBIC);
      tex += up * (cell / 32.0);
    }
    cv::Mat shade(kCrownPx, kCrownPx, CV_32F);
    for (int r = 0; r < kCrownPx; ++r)
      for (int c = 0; c < kCrownPx; ++c) {
        const double u = (c - kCrownPx / 2.0) / (kCrownPx / 2.0), v = (r - kCrownPx / 2.0) / (kCrownPx / 2.0);
        shade.at<float>(r, c) = static_cast<float>(1.0 - 0.45 * (u * u + v * v));
      }
    const double base = rng.uniform(70.0, 110.0);
    cv::Mat green = (tex * 22.0 + base).mul(shade);
    std::vector<cv::Mat> ch = {green * 0.45, green, green * 0.55};
    cv::Mat bgr;
    cv::merge(ch, bgr);
    bgr.convertTo(tree.texture, CV_8UC3);
    tree.mask = cv::Mat(kCrownPx, kCrownPx, CV_8U, cv::Scalar(0));
    cv::circle(tree.mask, cv::Point(kCrownPx / 2, kCrownPx / 2), kCrownPx / 2 - 1, cv::Scalar(255), cv::FILLED);
    trees.push_back(std::move(tree));
  }
  std::sort(trees.begin(), trees.end(),
            [](const CrownTree& a, const CrownTree& b) { return a.height < b.height; });
  return trees;
}

// Marker texture: 6-cell marker (incl. its black border) in an 8-cell
// white square, and its pixels' place on the ground.
MarkerTexture MakeMarker(const UavMarkerOptions& mo) {
  MarkerTexture out;
  const int cell = 16;
  cv::Ptr<cv::aruco::Dictionary> dict = cv::aruco::getPredefinedDictionary(ArucoDictionaryId(mo.dictionary));
  const int bits = dict->markerSize + 2;
  cv::Mat marker;
  cv::aruco::drawMarker(dict, mo.id, bits * cell, marker, 1);
  cv::Mat texture((bits + 2) * cell, (bits + 2) * cell, CV_8UC1, cv::Scalar(245));
  marker.copyTo(texture(cv::Rect(cell, cell, bits * cell, bits * cell)));
  cv::cvtColor(texture, out.texture, cv::COLOR_GRAY2BGR);
  const double s = mo.size / (bits * cell);  // m per texture px
  const double half = 0.5 * texture.cols;
  const double c = std::cos(mo.yaw), sn = std::sin(mo.yaw);
  const cv::Matx33d local(s, 0, -(half - 0.5) * s, 0, -s, (half - 0.5) * s, 0, 0, 1);
  const cv::Matx33d rot(c, -sn, mo.position.x(), sn, c, mo.position.y(), 0, 0, 1);
  out.world_from_px = rot * local;
  return out;
}

// The map's road stretches within `reach` of `home`.
std::vector<GroundPath> RoadStretchesNear(const std::vector<GroundPath>& roads, const Eigen::Vector2d& home,
                                          double reach) {
  std::vector<GroundPath> stretches;
  for (const auto& road : roads) {
    GroundPath near;
    for (const auto& p : road) {
      if ((p - home).norm() < reach) near.push_back(p);
      else if (near.size() >= 2) break;
    }
    if (near.size() >= 2) stretches.push_back(near);
  }
  return stretches;
}

// Moving objects: cars on the road stretches near the take-off area (on a
// random line without one), people walking about, a few of them around
// the take-off point (visible in the calibration hover).
std::vector<MovingObject> MakeObjects(const UavWorldOptions& options, const std::vector<GroundPath>& roads) {
  std::mt19937 rng(static_cast<uint32_t>(options.objects.seed));
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const Eigen::Vector2d home = options.flight.takeoff;
  const double radius = options.objects.area_radius;
  const cv::Scalar car_colours[] = {{240, 240, 240}, {30, 30, 30},  {40, 40, 200}, {180, 120, 40},
                                    {160, 160, 160}, {30, 160, 220}, {90, 40, 30}};
  const cv::Scalar shirt_colours[] = {{30, 30, 220}, {220, 140, 30}, {30, 220, 230}, {230, 230, 230}, {150, 40, 150}};
  auto random_line = [&](double length, double spread) {
    const Eigen::Vector2d c = home + Eigen::Vector2d(u01(rng) - 0.5, u01(rng) - 0.5) * 2 * spread;
    const double a = u01(rng) * 2 * M_PI;
    const Eigen::Vector2d d(std::cos(a), std::sin(a));
    return GroundPath{c - 0.5 * length * d, c + 0.5 * length * d};
  };
  const std::vector<GroundPath> stretches = RoadStretchesNear(roads, home, radius + 60);
  std::vector<MovingObject> objects;
  for (int k = 0; k < options.objects.num_cars + options.objects.num_people; ++k) {
    MovingObject o;
    o.car = k < options.objects.num_cars;
    if (o.car) {
      if (!stretches.empty()) {
        const GroundPath& road = stretches[static_cast<size_t>(k) % stretches.size()];
        // Drive on the right of the centre line (offset by 1.8 m to one side).
        const double side = (k / static_cast<int>(stretches.size())) % 2 == 0 ? 1.0 : -1.0;
        for (size_t i = 0; i < road.size(); ++i) {
          const Eigen::Vector2d d =
              (road[std::min(i + 1, road.size() - 1)] - road[i == 0 ? 0 : i - 1]).normalized();
          o.path.push_back(road[i] + side * 1.8 * Eigen::Vector2d(d.y(), -d.x()));
        }
      } else {
        o.path = random_line(150.0, radius);
      }
      o.speed = options.objects.car_speed * (0.6 + 0.8 * u01(rng));
      o.length = 4.0 + u01(rng);
      o.width = 1.7 + 0.2 * u01(rng);
      o.colour = car_colours[static_cast<size_t>(u01(rng) * 7) % 7];
    } else {
      const int near_count = std::max(1, options.objects.num_people / 5);
      const bool near = (k - options.objects.num_cars) < near_count;
      o.path = random_line(10.0 + 20.0 * u01(rng), near ? 8.0 : radius);
      o.speed = options.objects.person_speed * (0.7 + 0.6 * u01(rng));
      o.length = 0.45;
      o.width = 0.6;
      o.colour = shirt_colours[static_cast<size_t>(u01(rng) * 5) % 5];
    }
    o.cumulative.push_back(0);
    for (size_t i = 1; i < o.path.size(); ++i) o.cumulative.push_back(o.cumulative.back() + (o.path[i] - o.path[i - 1]).norm());
    o.phase = u01(rng) * 2 * o.cumulative.back();
    objects.push_back(o);
  }
  return objects;
}

// Distortion: an ideal canvas large enough for every raw pixel, and the
// raw -> canvas maps.
DistortionCanvas MakeDistortionMaps(const PinholeCamera& cam) {
  DistortionCanvas d;
  d.size = cv::Size(cam.width, cam.height);
  if (!cam.HasDistortion()) return d;
  d.map_x.create(cam.height, cam.width, CV_32F);
  d.map_y.create(cam.height, cam.width, CV_32F);
  double min_x = 0, min_y = 0, max_x = cam.width - 1, max_y = cam.height - 1;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Eigen::Vector2d ideal = cam.Undistort(Eigen::Vector2d(u, v));
      d.map_x.at<float>(v, u) = static_cast<float>(ideal.x());
      d.map_y.at<float>(v, u) = static_cast<float>(ideal.y());
      min_x = std::min(min_x, ideal.x());
      min_y = std::min(min_y, ideal.y());
      max_x = std::max(max_x, ideal.x());
      max_y = std::max(max_y, ideal.y());
    }
  d.margin_x = std::ceil(-min_x) + 2;
  d.margin_y = std::ceil(-min_y) + 2;
  d.size = cv::Size(static_cast<int>(std::ceil(max_x + d.margin_x)) + 3,
                    static_cast<int>(std::ceil(max_y + d.margin_y)) + 3);
  d.map_x += static_cast<float>(d.margin_x);
  d.map_y += static_cast<float>(d.margin_y);
  return d;
}

// Detail tiles repeated to cover a frame: the chosen level's texel is at
// least 0.9 ground sample distance, so a footprint spans at most ~1.2
// canvas diagonals of texels.
std::vector<cv::Mat> TileDetail(const Orthomap& map, cv::Size canvas) {
  std::vector<cv::Mat> tiled_levels;
  const double diagonal = std::hypot(canvas.width, canvas.height) * 1.2;
  for (int l = 0; l < map.NumDetailLevels(); ++l) {
    const cv::Mat& tile = map.DetailLevel(l);
    const int n = static_cast<int>(std::ceil((diagonal + tile.cols) / tile.cols));
    cv::Mat tiled;
    cv::repeat(tile, n, n, tiled);
    tiled_levels.push_back(tiled);
  }
  return tiled_levels;
}

}  // namespace

UavWorld::UavWorld(const UavWorldOptions& options)
    : options_(options), flight_(options.flight), impl_(std::make_unique<Impl>()) {
  std::string error;
  if (!options_.Check(&error)) throw std::invalid_argument(error);
  map_ = std::make_unique<Orthomap>(options_.orthomap);
  gps_ = std::make_unique<UavGps>(options_.gps, flight_);
  Impl& im = *impl_;
  const PinholeCamera& cam = options_.camera;
  if (options_.trees.num_trees > 0) im.trees = MakeTrees(options_.trees);
  if (options_.marker.enabled) im.marker = MakeMarker(options_.marker);
  im.objects = MakeObjects(options_, map_->roads());
  im.distortion = MakeDistortionMaps(cam);
  im.detail_tiled = TileDetail(*map_, im.distortion.size);
  // Sensor noise bank (a frame uses a pseudo-random window of it).
  if (options_.render.noise_sigma > 0) {
    cv::RNG noise_rng(static_cast<uint64_t>(options_.render.seed) * 40503u + 1u);
    im.noise_bank.create(cam.height + 256, cam.width + 256, CV_8UC3);
    noise_rng.fill(im.noise_bank, cv::RNG::NORMAL, 128.0, options_.render.noise_sigma);
  }
}

UavWorld::~UavWorld() = default;

int UavWorld::NumFrames() const { return static_cast<int>(std::floor(flight_.Duration() * options_.fps + 1e-9)) + 1; }
double UavWorld::FrameTime(int index) const { return index / options_.fps; }
int64_t UavWorld::FrameUtime(int index) const { return static_cast<int64_t>(std::llround(FrameTime(index) * 1e6)); }

cv::Matx33d UavWorld::ImageFromGround(const Pose3& world_from_camera) const {
  const Eigen::Matrix3d Rt = world_from_camera.linear().transpose();
  const Eigen::Vector3d t = world_from_camera.translation();
  Eigen::Matrix3d M;
  M.col(0) = Rt.col(0);
  M.col(1) = Rt.col(1);
  M.col(2) = -Rt * t;
  const PinholeCamera& c = options_.camera;
  Eigen::Matrix3d K;
  K << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1;
  return ToCv(K * M);
}

cv::Matx33d UavWorld::GroundHomography(double t1, double t2) const {
  const cv::Matx33d h1 = ImageFromGround(flight_.WorldFromCamera(t1));
  const cv::Matx33d h2 = ImageFromGround(flight_.WorldFromCamera(t2));
  cv::Matx33d h = h2 * h1.inv();
  return h * (1.0 / h(2, 2));
}

std::vector<GroundObject> UavWorld::ObjectsAt(double t) const {
  std::vector<GroundObject> out;
  for (const MovingObject& o : impl_->objects) {
    const double total = o.cumulative.back();
    if (total <= 0) continue;
    double s = std::fmod(o.phase + o.speed * t, 2 * total);
    bool back = s > total;
    if (back) s = 2 * total - s;
    size_t i = static_cast<size_t>(std::upper_bound(o.cumulative.begin(), o.cumulative.end(), s) - o.cumulative.begin());
    i = std::clamp<size_t>(i, 1, o.path.size() - 1);
    const double seg = o.cumulative[i] - o.cumulative[i - 1];
    const double f = seg > 0 ? (s - o.cumulative[i - 1]) / seg : 0.0;
    const Eigen::Vector2d p = o.path[i - 1] + f * (o.path[i] - o.path[i - 1]);
    Eigen::Vector2d d = (o.path[i] - o.path[i - 1]).normalized();
    if (back) d = -d;
    const Eigen::Vector2d n(-d.y(), d.x());
    GroundObject g;
    const double hl = 0.5 * o.length, hw = 0.5 * o.width;
    g.corners = {p + hl * d - hw * n, p + hl * d + hw * n, p - hl * d + hw * n, p - hl * d - hw * n};
    g.colour = o.colour;
    out.push_back(g);
  }
  return out;
}

std::vector<Eigen::Vector2d> UavWorld::MarkerCorners() const {
  const double h = 0.5 * options_.marker.size, c = std::cos(options_.marker.yaw), s = std::sin(options_.marker.yaw);
  std::vector<Eigen::Vector2d> out;
  for (const Eigen::Vector2d& l : {Eigen::Vector2d(-h, h), Eigen::Vector2d(h, h), Eigen::Vector2d(h, -h), Eigen::Vector2d(-h, -h)})
    out.push_back(options_.marker.position + Eigen::Vector2d(c * l.x() - s * l.y(), s * l.x() + c * l.y()));
  return out;
}

cv::Mat UavWorld::RenderFrame(double t) const { return Render(flight_.WorldFromCamera(t), t); }

cv::Mat UavWorld::RenderGroundOnly(const Pose3& world_from_camera) const {
  const cv::Matx33d hg = ImageFromGround(world_from_camera);
  const double gsd = std::max(world_from_camera.translation().z(), 0.1) / options_.camera.fx;
  const int level =
      std::clamp(PyramidLevel(gsd, map_->metres_per_pixel()), 0, map_->NumLevels() - 1);
  cv::Mat frame;
  cv::warpPerspective(map_->Level(level), frame, hg * map_->PixelFromWorld(level).inv(),
                      cv::Size(options_.camera.width, options_.camera.height), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  return frame;
}

namespace {

// The ground texture at the pyramid level just finer than the ground
// sample distance, warped onto the canvas (hg: canvas from ground).
cv::Mat RenderGround(const Orthomap& map, const cv::Matx33d& hg, double gsd, cv::Size size) {
  const int level = std::clamp(PyramidLevel(gsd, map.metres_per_pixel()), 0, map.NumLevels() - 1);
  cv::Mat canvas;
  cv::warpPerspective(map.Level(level), canvas, hg * map.PixelFromWorld(level).inv(), size, cv::INTER_LINEAR,
                      cv::BORDER_REFLECT);
  return canvas;
}

// The fine detail texture added to the canvas. It samples the pre-tiled
// copy, shifted by whole tiles so the frame falls inside it (BORDER_WRAP is
// the slow per-pixel path of cv::remap); wraps only when the footprint is
// larger than the copy.
void AddDetail(const Orthomap& map, const std::vector<cv::Mat>& detail_tiled, const cv::Matx33d& hg, double gsd,
               cv::Mat* canvas) {
  const cv::Size size = canvas->size();
  const int dl = std::clamp(PyramidLevel(gsd, map.detail_metres_per_pixel()), 0, map.NumDetailLevels() - 1);
  const cv::Matx33d detail_from_canvas = map.DetailPixelFromWorld(dl) * hg.inv();
  double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
  for (const cv::Vec3d& c : {cv::Vec3d(0, 0, 1), cv::Vec3d(size.width, 0, 1), cv::Vec3d(0, size.height, 1),
                             cv::Vec3d(size.width, size.height, 1)}) {
    const cv::Vec3d p = detail_from_canvas * c;
    min_x = std::min(min_x, p[0] / p[2]);
    min_y = std::min(min_y, p[1] / p[2]);
    max_x = std::max(max_x, p[0] / p[2]);
    max_y = std::max(max_y, p[1] / p[2]);
  }
  const cv::Mat& tiled = detail_tiled[static_cast<size_t>(dl)];
  const double tile = map.DetailLevel(dl).cols;
  const double sx = -std::floor(min_x / tile) * tile, sy = -std::floor(min_y / tile) * tile;
  cv::Mat detail;
  if (max_x + sx < tiled.cols - 2 && max_y + sy < tiled.rows - 2)
    cv::warpPerspective(tiled, detail, Translation(sx, sy) * detail_from_canvas, size,
                        cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  else
    cv::warpPerspective(map.DetailLevel(dl), detail, detail_from_canvas, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                        cv::BORDER_WRAP);
  cv::cvtColor(detail, detail, cv::COLOR_GRAY2BGR);
  AddOffset(detail, canvas);
}

// The calibration marker (only the part of the canvas it covers).
void DrawMarker(const MarkerTexture& marker, const cv::Matx33d& hg, cv::Mat* canvas) {
  const cv::Matx33d m = hg * marker.world_from_px;
  const float w = static_cast<float>(marker.texture.cols), h = static_cast<float>(marker.texture.rows);
  std::vector<cv::Point2f> src = {{-0.5f, -0.5f}, {w - 0.5f, -0.5f}, {w - 0.5f, h - 0.5f}, {-0.5f, h - 0.5f}}, dst;
  cv::perspectiveTransform(src, dst, cv::Mat(m));
  const cv::Rect roi = cv::boundingRect(dst) & cv::Rect(0, 0, canvas->cols, canvas->rows);
  if (roi.area() <= 0) return;
  cv::Mat view = (*canvas)(roi);
  cv::warpPerspective(marker.texture, view, Translation(-roi.x, -roi.y) * m, roi.size(), cv::INTER_LINEAR,
                      cv::BORDER_TRANSPARENT);
}

// A tree crown: a disc in the plane z = its height (m: canvas from crown
// texture, the camera seen from that plane being the camera lowered by it).
void DrawCrown(const CrownTree& tree, const cv::Matx33d& m, cv::Mat* canvas) {
  std::vector<cv::Point2f> src = {{0, 0}, {kCrownPx, 0}, {kCrownPx, kCrownPx}, {0, kCrownPx}}, dst;
  cv::perspectiveTransform(src, dst, cv::Mat(m));
  const cv::Rect roi = cv::boundingRect(dst) & cv::Rect(0, 0, canvas->cols, canvas->rows);
  if (roi.area() <= 0) return;
  cv::Mat crown, mask;
  const cv::Matx33d to_roi = Translation(-roi.x, -roi.y) * m;
  cv::warpPerspective(tree.texture, crown, to_roi, roi.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::warpPerspective(tree.mask, mask, to_roi, roi.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  crown.copyTo((*canvas)(roi), mask);
}

// Moving objects: cars (with a dark windscreen) and people (a head seen
// from `height` m by a camera of focal length fx px).
void DrawObjects(const std::vector<GroundObject>& objects, const cv::Matx33d& hg, double fx, double height,
                 cv::Mat* canvas) {
  constexpr int kShift = 4;
  auto project = [&](const Eigen::Vector2d& g) {
    const cv::Vec3d p = hg * cv::Vec3d(g.x(), g.y(), 1.0);
    return cv::Point(static_cast<int>(std::lround(p[0] / p[2] * (1 << kShift))),
                     static_cast<int>(std::lround(p[1] / p[2] * (1 << kShift))));
  };
  const cv::Rect2d bounds(-200, -200, canvas->cols + 400, canvas->rows + 400);
  for (const GroundObject& o : objects) {
    std::vector<cv::Point> poly;
    bool inside = false;
    for (const auto& c : o.corners) {
      poly.push_back(project(c));
      inside = inside || bounds.contains(cv::Point2d(poly.back().x, poly.back().y) / (1 << kShift));
    }
    if (!inside) continue;
    cv::fillConvexPoly(*canvas, poly, o.colour, cv::LINE_8, kShift);
    const bool car = (o.corners[0] - o.corners[1]).norm() > 1.0;
    if (car) {
      // Windscreen: the front quarter of the roof.
      const Eigen::Vector2d f0 = o.corners[0] + 0.18 * (o.corners[3] - o.corners[0]);
      const Eigen::Vector2d f1 = o.corners[1] + 0.18 * (o.corners[2] - o.corners[1]);
      const Eigen::Vector2d b0 = o.corners[0] + 0.38 * (o.corners[3] - o.corners[0]);
      const Eigen::Vector2d b1 = o.corners[1] + 0.38 * (o.corners[2] - o.corners[1]);
      const Eigen::Vector2d in = 0.12 * (o.corners[1] - o.corners[0]);
      std::vector<cv::Point> glass = {project(f0 + in), project(f1 - in), project(b1 - in), project(b0 + in)};
      cv::fillConvexPoly(*canvas, glass, cv::Scalar(50, 40, 35), cv::LINE_8, kShift);
    } else {
      const Eigen::Vector2d c = 0.25 * (o.corners[0] + o.corners[1] + o.corners[2] + o.corners[3]);
      const cv::Point p = project(c);
      const int r = static_cast<int>(std::lround(0.12 * fx / height * (1 << kShift)));
      cv::circle(*canvas, p, std::max(r, 1), cv::Scalar(30, 50, 70), cv::FILLED, cv::LINE_8, kShift);
    }
  }
}

// Sensor noise: a window of the bank chosen by hashing the time (same t,
// same noise).
void AddSensorNoise(const cv::Mat& noise_bank, double t, cv::Mat* frame) {
  uint64_t h = static_cast<uint64_t>(std::llround(t * 1e6)) * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull;
  h ^= h >> 29;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 32;
  const int dx = static_cast<int>(h % 256), dy = static_cast<int>((h >> 16) % 256);
  AddOffset(noise_bank(cv::Rect(dx, dy, frame->cols, frame->rows)), frame);
}

}  // namespace

cv::Mat UavWorld::Render(const Pose3& world_from_camera, double t) const {
  const Impl& im = *impl_;
  const DistortionCanvas& d = im.distortion;
  const cv::Matx33d hg = Translation(d.margin_x, d.margin_y) * ImageFromGround(world_from_camera);
  const double height = std::max(world_from_camera.translation().z(), 0.1);
  const double gsd = height / options_.camera.fx;  // m per px at the image centre
  cv::Mat canvas = RenderGround(*map_, hg, gsd, d.size);
  if (map_->NumDetailLevels() > 0) AddDetail(*map_, im.detail_tiled, hg, gsd, &canvas);
  if (!im.marker.texture.empty()) DrawMarker(im.marker, hg, &canvas);
  for (const CrownTree& tree : im.trees) {
    Pose3 lowered = world_from_camera;
    lowered.translation().z() -= tree.height;
    if (lowered.translation().z() < 1.0) continue;
    const double k = 2 * tree.radius / kCrownPx;  // m per texture px
    const cv::Matx33d world_from_tex(k, 0, tree.x - tree.radius, 0, -k, tree.y + tree.radius, 0, 0, 1);
    DrawCrown(tree, Translation(d.margin_x, d.margin_y) * ImageFromGround(lowered) * world_from_tex, &canvas);
  }
  if (options_.render.moving_objects) DrawObjects(ObjectsAt(t), hg, options_.camera.fx, height, &canvas);
  cv::Mat frame;
  if (!d.map_x.empty()) cv::remap(canvas, frame, d.map_x, d.map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  else frame = canvas;
  if (!im.noise_bank.empty()) AddSensorNoise(im.noise_bank, t, &frame);
  return frame;
}

}  // namespace vloc
