#pragma once
// vloc::sim_uav -- a simulated small UAV with a nadir camera over a flat
// textured ground. This is the API the UAV pipeline (uav_mosaicker tests,
// procs/sim_uav) builds on:
//
//   UavWorldOptions options = LoadOptionsFile<UavWorldOptions>("config/procs/sim_uav.yaml", "world");
//   UavWorld world(options);                 // builds the orthomap (1-3 s)
//   for (int i = 0; i < world.NumFrames(); ++i) {
//     double t = world.FrameTime(i);
//     cv::Mat bgr = world.RenderFrame(t);    // camera.width x camera.height, CV_8UC3
//     UavState truth = world.flight().StateAt(t);  // x east, y north, z height above ground, yaw
//   }
//   cv::Matx33d H = world.GroundHomography(t1, t2);  // ideal px of frame t1 -> ideal px of frame t2
//   const UavGpsSample& fix = world.gps().At(t);     // 5 Hz GPS with drop-outs
//
// Geometry: the ground is the plane z = 0 (world x east, y north, z up), so
// every frame pair is related by a homography; moving objects (cars,
// people) break it locally, as in real data. Pixels are "ideal" (pinhole,
// undistorted) in the homographies; when the camera has distortion the
// rendered frame is distorted with camera.k1.. (PinholeCamera::Distort).
// Rendering: the finest orthomap pyramid level that the ground sample
// distance does not minify by more than ~10 % (no aliasing) is warped with
// cv::warpPerspective by the ground-to-image homography, the periodic detail
// texture is added the same way, then the ArUco marker, moving objects,
// optional distortion and sensor noise. Deterministic: the same options give
// the same bytes for the same t. RenderFrame/Render are const and may run on
// several threads at once.

#include <opencv2/core.hpp>
#include <memory>
#include <string>
#include <vector>

#include "vloc/common/camera.h"
#include "vloc/sim/uav_flight.h"
#include "vloc/sim/uav_gps.h"
#include "vloc/sim/uav_orthomap.h"

namespace vloc {

class OptionsReader;

// An ArUco marker lying on the ground for the calibration step.
struct UavMarkerOptions {
  bool enabled = true;
  std::string dictionary = "DICT_4X4_50";  // cv::aruco predefined dictionary name
  int id = 0;                              // marker id in the dictionary
  double size = 1.0;                       // m, side of the marker's black square
  Eigen::Vector2d position = Eigen::Vector2d(0.0, 0.0);  // m, world x/y of the marker centre
  double yaw = 0.0;                        // rad, marker rotation about z (0: marker top to north)

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// Cars and people moving on the ground (ping-pong along paths).
struct UavObjectsOptions {
  int num_cars = 12;           // cars (on roads when the map has them)
  int num_people = 20;         // people walking near the take-off area
  double car_speed = 8.0;      // m/s, mean
  double person_speed = 1.4;   // m/s, mean
  double area_radius = 150.0;  // m, people and road-less cars stay this close to the take-off point
  int seed = 5;

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// Trees whose crowns stand above the ground (real parallax for the nadir
// camera: a crown at height h is seen from H - h, not H). 0 trees = none.
struct UavTreesOptions {
  int num_trees = 0;                 // crowns placed at random in the area (0 = no trees)
  Eigen::Vector2d centre = Eigen::Vector2d(0.0, 0.0);  // m, world x/y of the wooded area's centre
  double area_radius = 120.0;        // m, crowns within this distance of the centre
  double min_height = 15.0;          // m, crown top above the ground
  double max_height = 20.0;          // m
  double min_radius = 2.5;           // m, crown radius
  double max_radius = 5.0;           // m
  int seed = 11;                     // placement and crown texture

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct UavRenderOptions {
  double noise_sigma = 2.0;   // grey levels, 1-sigma sensor noise per pixel and channel (0 = none)
  bool moving_objects = true; // draw cars and people
  int seed = 9;               // sensor noise seed

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct UavWorldOptions {
  PinholeCamera camera = DefaultUavCamera();  // nadir camera intrinsics (config/uav_camera.yaml)
  double fps = 30.0;                          // frames/s
  OrthomapOptions orthomap;
  UavMarkerOptions marker;
  UavObjectsOptions objects;
  UavTreesOptions trees;
  UavFlightOptions flight;
  UavGpsOptions gps;
  UavRenderOptions render;

  // 1280 x 720, fx = fy = 1000 px (about 65 x 40 degrees), no distortion.
  static PinholeCamera DefaultUavCamera();
  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

// A moving object's ground footprint at a time (for tests: masks).
struct GroundObject {
  std::vector<Eigen::Vector2d> corners;  // m, world x/y, convex, counter-clockwise
  cv::Scalar colour;                     // BGR
};

class UavWorld {
 public:
  // Throws std::invalid_argument (bad options) or std::runtime_error
  // (unreadable orthomap image), one line each.
  explicit UavWorld(const UavWorldOptions& options);
  ~UavWorld();

  const UavWorldOptions& options() const { return options_; }
  const PinholeCamera& camera() const { return options_.camera; }
  const UavFlight& flight() const { return flight_; }
  const UavGps& gps() const { return *gps_; }
  const Orthomap& orthomap() const { return *map_; }

  int NumFrames() const;             // frames in the whole flight at options.fps
  double FrameTime(int index) const; // s
  int64_t FrameUtime(int index) const;  // microseconds since flight start

  // The camera image at time t along the flight (BGR, camera size).
  cv::Mat RenderFrame(double t) const;
  // The image seen from any world_from_camera pose, objects at time t.
  cv::Mat Render(const Pose3& world_from_camera, double t) const;
  // Same without moving objects, marker, noise or distortion (for tests).
  cv::Mat RenderGroundOnly(const Pose3& world_from_camera) const;

  // Homography from world ground (x, y, 1) in metres to ideal pixels of the
  // camera at world_from_camera.
  cv::Matx33d ImageFromGround(const Pose3& world_from_camera) const;
  // Maps ideal pixels of the frame at t1 to ideal pixels of the frame at t2
  // (exact for ground points; moving objects excepted).
  cv::Matx33d GroundHomography(double t1, double t2) const;

  // Moving objects at time t (world footprints).
  std::vector<GroundObject> ObjectsAt(double t) const;
  // The marker's four corners in world metres (top-left, top-right,
  // bottom-right, bottom-left in the marker's own image, as ArUco reports).
  std::vector<Eigen::Vector2d> MarkerCorners() const;

 private:
  struct Impl;
  UavWorldOptions options_;
  UavFlight flight_;
  std::unique_ptr<Orthomap> map_;
  std::unique_ptr<UavGps> gps_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vloc
