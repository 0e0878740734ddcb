#include "vloc/sim/rover_traverse.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vloc/common/options.h"
#include "vloc/sim/noise.h"

namespace vloc::sim {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Counter-based random numbers: a pure function of (seed, stream, index).
class Random {
 public:
  Random(uint64_t seed, uint64_t stream) : seed_(Hash3(seed, stream, 0x7A3F1ULL)) {}
  double Uniform() { return HashToUnit(Hash3(seed_, counter_++, 1)); }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  double Gaussian() { return HashToGaussian(Hash3(seed_, counter_++, 2)); }
  Eigen::Vector3d Gaussian3() {
    const double a = Gaussian(), b = Gaussian(), c = Gaussian();
    return {a, b, c};
  }

 private:
  uint64_t seed_;
  uint64_t counter_ = 0;
};

double DistanceToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

// Smooth 0 -> 1 -> 0 profile of duration T with cosine ramps of `ramp` s.
double Profile(double t, double T, double ramp) {
  if (t <= 0 || t >= T) return 0.0;
  const double r = std::min(ramp, 0.5 * T);
  if (t < r) return 0.5 * (1 - std::cos(M_PI * t / r));
  if (t > T - r) return 0.5 * (1 - std::cos(M_PI * (T - t) / r));
  return 1.0;
}

class Simulator {
 public:
  Simulator(const Terrain& terrain, const TraverseOptions& options)
      : terrain_(terrain),
        o_(options),
        dt_(1.0 / options.imu.rate_hz),
        wheel_every_(std::max(1, static_cast<int>(std::lround(options.imu.rate_hz / options.wheels.rate_hz)))),
        noise_(options.seed, 11),
        soil_seed_(Hash3(options.seed, 12, 0x5017ULL)) {}

  SimulatedTraverse Run() {
    const std::vector<Eigen::Vector2d> plan = PlanSites();
    const int num_planned = static_cast<int>(plan.size());
    StartAt(plan);
    Stationary(o_.motion.stop_pause_s);
    std::vector<double> site_heading;
    for (int i = 0; i < num_planned; ++i) {
      const bool revisit = o_.plan.revisit_site >= 0 && o_.plan.sites_xy.empty() && i == num_planned - 1;
      if (i > 0) DriveToSite(i, plan[i], revisit ? site_heading[o_.plan.revisit_site] : std::nan(""));
      ImageSite(i, plan[i], revisit, i + 1 < num_planned);
      site_heading.push_back(yaw_);
    }
    out_.duration_s = (utime_ - static_cast<int64_t>(o_.motion.start_utime)) * 1e-6;
    return std::move(out_);
  }

 private:
  // The initial state at the first site: heading as planned (towards the
  // second site of an explicit plan), attitude settled on the ground, the
  // sensor biases drawn, the first sample recorded.
  void StartAt(const std::vector<Eigen::Vector2d>& plan) {
    p_ = Eigen::Vector3d(plan[0].x(), plan[0].y(), 0.0);
    yaw_ = o_.plan.initial_heading_deg * kDegToRad;
    if (!o_.plan.sites_xy.empty() && plan.size() > 1) {
      const Eigen::Vector2d d = plan[1] - plan[0];
      yaw_ = std::atan2(d.y(), d.x());
    }
    const Eigen::Vector3d fit = FitPlane(p_.x(), p_.y(), yaw_);
    roll_ = fit.x();
    pitch_ = fit.y();
    p_.z() = fit.z();
    R_ = RotationFromRollPitchYaw(roll_, pitch_, yaw_);
    utime_ = static_cast<int64_t>(o_.motion.start_utime);
    if (!o_.ideal_sensors) {
      out_.gyro_bias = o_.imu.gyro_bias_sigma * noise_.Gaussian3();
      out_.accel_bias = o_.imu.accel_bias_sigma * noise_.Gaussian3();
    }
    gyro_bias_ = out_.gyro_bias;
    Record(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, o_.imu.gravity_mps2));
  }

  // Departs site i - 1 and drives to site i (`xy`): turn, pause, drive,
  // pause; a revisit then turns to `revisit_heading` (NaN: none), the
  // heading it had there.
  void DriveToSite(int i, const Eigen::Vector2d& xy, double revisit_heading) {
    Event(i - 1, SiteEventType::kDeparted);
    out_.sites.back().departed_utime = utime_;
    const Eigen::Vector2d to_next = xy - p_.head<2>();
    Turn(WrapAngle(std::atan2(to_next.y(), to_next.x()) - yaw_));
    Stationary(o_.motion.stop_pause_s);
    Drive(to_next.norm());
    Stationary(o_.motion.stop_pause_s);
    if (!std::isnan(revisit_heading)) {
      Turn(WrapAngle(revisit_heading - yaw_));
      Stationary(o_.motion.stop_pause_s);
    }
  }

  // At site i: the suspension settles, then the rover rests and reports its
  // arrival (one pose from arrival to departure, the site's truth; the dead
  // reckoning's site pose is taken at that same instant), images its
  // panorama pair by pair, reports the imaging done, and pauses unless it
  // is the last site.
  void ImageSite(int i, const Eigen::Vector2d& planned_xy, bool revisit, bool more_to_come) {
    Stationary(o_.panorama.settle_s);
    at_rest_ = true;
    SiteVisit site;
    site.site_id = i;
    site.revisit_of = revisit ? o_.plan.revisit_site : -1;
    site.planned_xy = planned_xy;
    site.arrived_utime = utime_;
    site.world_from_body = MakePose(R_, p_);
    site.distance_from_start_m = out_.path_length_m;
    out_.sites.push_back(site);
    const std::vector<MastPointing> pointings = o_.panorama.Pointings();
    Event(i, SiteEventType::kArrived, static_cast<int>(pointings.size()));
    Step(0.0, 0.0);  // the first exposure follows the arrival
    for (size_t k = 0; k < pointings.size(); ++k) {
      Exposure e;
      e.utime = utime_;
      e.site_id = i;
      e.pair_index = static_cast<int>(k);
      e.num_pairs = static_cast<int>(pointings.size());
      e.mast_pan = pointings[k].pan;
      e.mast_tilt = pointings[k].tilt;
      e.world_from_body = MakePose(R_, p_);
      out_.exposures.push_back(e);
      out_.sites.back().exposures.push_back(e);
      Stationary(k + 1 < pointings.size() ? o_.panorama.pair_interval_s : o_.motion.stop_pause_s);
    }
    Event(i, SiteEventType::kImagingDone, static_cast<int>(pointings.size()));
    out_.sites.back().imaging_done_utime = utime_;
    if (more_to_come) Stationary(o_.motion.stop_pause_s);
    at_rest_ = false;
  }

  // Sites: explicit, or a random walk that stays inside the terrain and
  // steers around large craters and rocks.
  std::vector<Eigen::Vector2d> PlanSites() {
    std::vector<Eigen::Vector2d> sites;
    const Region b = terrain_.Bounds();
    auto inside = [&](const Eigen::Vector2d& q, double margin) {
      return q.x() >= b.x_min + margin && q.x() <= b.x_max - margin && q.y() >= b.y_min + margin &&
             q.y() <= b.y_max - margin;
    };
    if (!o_.plan.sites_xy.empty()) {
      for (size_t k = 0; k + 1 < o_.plan.sites_xy.size(); k += 2)
        sites.emplace_back(o_.plan.sites_xy[k], o_.plan.sites_xy[k + 1]);
    } else {
      Random rng(o_.seed, 10);
      sites.emplace_back(0.0, 0.0);
      double heading = o_.plan.initial_heading_deg * kDegToRad;
      for (int i = 1; i < o_.plan.num_sites; ++i) {
        double best_penalty = 1e300;
        Eigen::Vector2d best;
        double best_heading = heading;
        for (int c = 0; c < 16; ++c) {
          const double h = heading + o_.plan.max_turn_deg * kDegToRad * rng.Uniform(-1.0, 1.0);
          const double spacing = rng.Uniform(o_.plan.spacing_min_m, o_.plan.spacing_max_m);
          const Eigen::Vector2d q = sites.back() + spacing * Eigen::Vector2d(std::cos(h), std::sin(h));
          double penalty = 0.01 * c;
          if (!inside(q, o_.plan.margin_m)) penalty += 1000.0;
          // Steer away early: a soft penalty within 25 m of the margin.
          const double edge = std::min({q.x() - b.x_min, b.x_max - q.x(), q.y() - b.y_min, b.y_max - q.y()});
          penalty += 2.0 * std::max(0.0, o_.plan.margin_m + 25.0 - edge);
          for (const Crater& cr : terrain_.craters()) {
            if (cr.diameter < 1.5) continue;
            const double gap = DistanceToSegment(cr.centre, sites.back(), q) - (0.5 * cr.diameter + 0.8);
            if (gap < 0) penalty += 10.0 * (-gap) * cr.diameter;
          }
          for (const Rock& rock : terrain_.rocks()) {
            if (rock.diameter < 0.25) continue;
            if (DistanceToSegment(rock.centre, sites.back(), q) < 1.0 + 0.5 * rock.diameter) penalty += 5.0;
          }
          if (penalty < best_penalty) {
            best_penalty = penalty;
            best = q;
            best_heading = h;
          }
        }
        sites.push_back(best);
        heading = best_heading;
      }
      if (o_.plan.revisit_site >= 0) sites.push_back(sites[o_.plan.revisit_site]);
    }
    for (size_t k = 0; k < sites.size(); ++k) {
      if (!inside(sites[k], 3.0))
        throw std::invalid_argument("traverse: site " + std::to_string(k) +
                                    " lies within 3 m of the terrain edge or outside it; move it or enlarge the terrain");
    }
    return sites;
  }

  // Terrain height averaged over a 16 cm footprint (a wheel contact patch).
  double ContactHeight(double x, double y) const {
    const double r = 0.08;
    return 0.2 * (terrain_.Height(x, y) + terrain_.Height(x + r, y) + terrain_.Height(x - r, y) +
                  terrain_.Height(x, y + r) + terrain_.Height(x, y - r));
  }

  // Plane through the six wheel contacts: (roll, pitch, height at centre).
  Eigen::Vector3d FitPlane(double x, double y, double yaw) const {
    const double c = std::cos(yaw), s = std::sin(yaw);
    const double half_l = 0.5 * o_.motion.wheel_base_m, half_w = 0.5 * o_.motion.track_width_m;
    double sum = 0, sum_fx = 0, sum_fy = 0, sxx = 0, syy = 0;
    for (double fx : {half_l, 0.0, -half_l}) {
      for (double fy : {half_w, -half_w}) {
        const double h = ContactHeight(x + fx * c - fy * s, y + fx * s + fy * c);
        sum += h;
        sum_fx += fx * h;
        sum_fy += fy * h;
        sxx += fx * fx;
        syy += fy * fy;
      }
    }
    const double slope_x = sum_fx / sxx, slope_y = sum_fy / syy;
    const double pitch = -std::atan(slope_x);
    const double roll = std::atan(slope_y / std::cos(pitch));
    return {roll, pitch, sum / 6.0};
  }

  double SoilFactor(double x, double y) const {
    const double n = FractalNoise(x, y, o_.wheels.soil_wavelength_m, 3, 0.5, soil_seed_) / 0.35;
    return 1.0 + o_.wheels.soil_variation * std::clamp(n, -1.0, 1.0);
  }

  // One IMU period with speed v (m/s) and yaw rate (rad/s) at its midpoint.
  void Step(double v, double yaw_rate) {
    utime_ += static_cast<int64_t>(std::lround(dt_ * 1e6));
    ++step_;
    yaw_ = WrapAngle(yaw_ + yaw_rate * dt_);
    const Eigen::Vector3d target = FitPlane(p_.x(), p_.y(), yaw_);
    const double w = 1.0 / o_.motion.attitude_time_constant_s;
    auto filter = [&](double goal, double* x, double* x_dot) {
      const double acc = w * w * (WrapAngle(goal - *x)) - 2.0 * w * *x_dot;
      *x_dot += acc * dt_;
      *x += *x_dot * dt_;
    };
    if (at_rest_) {
      roll_rate_ = pitch_rate_ = 0;  // at rest on its wheels: the attitude holds
    } else {
      filter(target.x(), &roll_, &roll_rate_);
      filter(target.y(), &pitch_, &pitch_rate_);
    }
    const Eigen::Matrix3d R_new = RotationFromRollPitchYaw(roll_, pitch_, yaw_);
    const double lateral = o_.ideal_sensors ? 0.0 : -o_.wheels.sideslip_per_rad_roll * roll_ * v;
    const Eigen::Vector3d dp = dt_ * (v * 0.5 * (R_.col(0) + R_new.col(0)) + lateral * R_new.col(1));
    p_ += dp;
    out_.path_length_m += dp.norm();

    double slip = 0.0;
    if (!o_.ideal_sensors) {
      const double uphill = std::asin(std::clamp(R_new(2, 0), -1.0, 1.0));
      slip = o_.wheels.slip_flat * SoilFactor(p_.x(), p_.y()) +
             (uphill > 0 ? o_.wheels.slip_per_rad_uphill * uphill : o_.wheels.skid_per_rad_downhill * uphill);
      slip = std::clamp(slip, -0.3, 0.6);
    }
    wheel_distance_ += dt_ * v / (1.0 - slip);
    if (!o_.ideal_sensors && v > 1e-6) wheel_distance_ += o_.wheels.distance_noise_m * noise_.Gaussian();

    Eigen::Vector3d gyro = LogSO3(R_.transpose() * R_new) / dt_;
    const Eigen::Vector3d velocity = dp / dt_;
    const Eigen::Vector3d accel_world = (velocity - velocity_) / dt_;
    Eigen::Vector3d specific_force = R_new.transpose() * (accel_world + Eigen::Vector3d(0, 0, o_.imu.gravity_mps2));
    if (!o_.ideal_sensors) {
      const double sqrt_rate = std::sqrt(o_.imu.rate_hz);
      gyro_bias_ += o_.imu.gyro_bias_walk * std::sqrt(dt_) * noise_.Gaussian3();
      gyro += gyro_bias_ + o_.imu.gyro_noise_density * sqrt_rate * noise_.Gaussian3();
      specific_force += out_.accel_bias + o_.imu.accel_noise_density * sqrt_rate * noise_.Gaussian3();
    }
    R_ = R_new;
    velocity_ = velocity;
    Record(velocity, gyro, specific_force);
  }

  void Record(const Eigen::Vector3d& velocity, const Eigen::Vector3d& gyro, const Eigen::Vector3d& specific_force) {
    GroundTruthSample gt;
    gt.utime = utime_;
    gt.world_from_body = MakePose(R_, p_);
    gt.velocity = velocity;
    out_.ground_truth.push_back(gt);
    ImuSample imu;
    imu.utime = utime_;
    imu.angular_velocity = gyro;
    imu.linear_acceleration = specific_force;
    out_.imu.push_back(imu);
    if (step_ % wheel_every_ == 0) {
      WheelOdometrySample wheel;
      wheel.utime = utime_;
      wheel.distance = wheel_distance_;
      wheel.speed = (wheel_distance_ - last_wheel_distance_) / (wheel_every_ * dt_);
      if (step_ == 0) wheel.speed = 0.0;
      last_wheel_distance_ = wheel_distance_;
      out_.wheel.push_back(wheel);
    }
  }

  void Stationary(double seconds) {
    const int n = static_cast<int>(std::lround(seconds / dt_));
    for (int k = 0; k < n; ++k) Step(0.0, 0.0);
  }

  // Runs a smooth profile whose integral is exactly `amount` (m or rad):
  // `peak` is the nominal rate, driving speed or turn rate.
  template <class StepFn>
  void RunProfile(double amount, double peak, StepFn step) {
    if (std::abs(amount) < 1e-9) return;
    const double ramp = o_.motion.ramp_s;
    double T = std::abs(amount) / peak + ramp;
    if (T < 2 * ramp) T = 2 * ramp;
    const int n = std::max(2, static_cast<int>(std::ceil(T / dt_)));
    T = n * dt_;
    double sum = 0;
    for (int k = 0; k < n; ++k) sum += Profile((k + 0.5) * dt_, T, ramp) * dt_;
    const double scale = amount / sum;
    for (int k = 0; k < n; ++k) step(scale * Profile((k + 0.5) * dt_, T, ramp));
  }

  void Turn(double angle) {
    RunProfile(angle, o_.motion.turn_rate_deg_s * kDegToRad, [&](double rate) { Step(0.0, rate); });
  }
  void Drive(double distance) {
    RunProfile(distance, o_.motion.speed_mps, [&](double speed) { Step(speed, 0.0); });
  }

  void Event(int site_id, SiteEventType type, int num_pairs = 0) {
    SiteEvent e;
    e.utime = utime_;
    e.site_id = site_id;
    e.event = type;
    e.num_pairs = num_pairs;
    if (type != SiteEventType::kArrived && num_pairs == 0) e.num_pairs = static_cast<int>(o_.panorama.Pointings().size());
    out_.events.push_back(e);
  }

  const Terrain& terrain_;
  const TraverseOptions& o_;
  const double dt_;
  const int wheel_every_;
  Random noise_;
  const uint64_t soil_seed_;
  SimulatedTraverse out_;
  int64_t utime_ = 0;
  int64_t step_ = 0;
  Eigen::Vector3d p_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d velocity_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();
  double yaw_ = 0, roll_ = 0, pitch_ = 0, roll_rate_ = 0, pitch_rate_ = 0;
  bool at_rest_ = false;  // imaging at a site: roll and pitch hold (the suspension has settled)
  double wheel_distance_ = 0, last_wheel_distance_ = 0;
};

}  // namespace

void PanoramaOptions::Visit(OptionsReader& r) {
  r.Optional("num_pairs", &num_pairs, "pairs across the forward direction", InRange(1, 36));
  r.Optional("pan_step_deg", &pan_step_deg, "deg between adjacent pairs", NonNegative());
  r.Optional("tilt_deg", &tilt_deg, "deg, mast tilt, positive down", InOpen(-60, 89));
  r.Optional("backward_pair", &backward_pair, "add one pair looking backward");
  r.Optional("backward_tilt_deg", &backward_tilt_deg, "deg, tilt of the backward pair", InOpen(-60, 89));
  r.Optional("settle_s", &settle_s, "s the suspension settles after the stop, before arrival and imaging",
             NonNegative());
  r.Optional("pair_interval_s", &pair_interval_s, "s between exposures", Positive());
  r.Relation("pan_step_deg", pan_step_deg * (num_pairs - 1) <= 360, "must span at most 360 deg over num_pairs");
}

bool PanoramaOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

std::vector<MastPointing> PanoramaOptions::Pointings() const {
  std::vector<MastPointing> out;
  for (int i = 0; i < num_pairs; ++i)
    out.push_back({(0.5 * (num_pairs - 1) - i) * pan_step_deg * kDegToRad, tilt_deg * kDegToRad});
  if (backward_pair) out.push_back({M_PI, backward_tilt_deg * kDegToRad});
  return out;
}

namespace {

bool EvenCount(const std::vector<double>& xy) { return xy.size() % 2 == 0; }

}  // namespace

void TraversePlanOptions::Visit(OptionsReader& r) {
  r.Optional("num_sites", &num_sites, "sites including the start");
  r.Optional("spacing_min_m", &spacing_min_m, "m, shortest leg", Positive());
  r.Optional("spacing_max_m", &spacing_max_m, "m, longest leg");
  r.Optional("initial_heading_deg", &initial_heading_deg, "deg, heading at site 0, ccw from east");
  r.Optional("max_turn_deg", &max_turn_deg, "deg, largest heading change between legs", InRange(0, 180));
  r.Optional("margin_m", &margin_m, "m, sites stay this far inside the terrain", AtLeast(3));
  r.Optional("revisit_site", &revisit_site, ">= 0: extra final site back at that site");
  r.Optional("sites_xy", &sites_xy, "m, explicit site positions x0,y0,x1,y1,...",
             Rule<std::vector<double>>(EvenCount, "x,y pairs (an even count)"));
  r.Relation("num_sites", !sites_xy.empty() || num_sites >= 1, "must be >= 1 (or sites_xy given)");
  r.Relation("spacing_max_m", spacing_max_m >= spacing_min_m, "must be >= spacing_min_m");
  r.Relation("revisit_site", revisit_site < num_sites, "must be < num_sites (or -1 for none)");
}

bool TraversePlanOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void MotionOptions::Visit(OptionsReader& r) {
  r.Optional("speed_mps", &speed_mps, "m/s, driving speed", InLeftOpen(0, 2));
  r.Optional("ramp_s", &ramp_s, "s, speed and turn-rate ramps", Positive());
  r.Optional("turn_rate_deg_s", &turn_rate_deg_s, "deg/s, point-turn rate", Positive());
  r.Optional("attitude_time_constant_s", &attitude_time_constant_s, "s, roll/pitch smoothing", AtLeast(0.05));
  r.Optional("wheel_base_m", &wheel_base_m, "m, front to rear contacts", Positive());
  r.Optional("track_width_m", &track_width_m, "m, left to right contacts", Positive());
  r.Optional("start_utime", &start_utime, "us, time of the first sample", NonNegative());
  r.Optional("stop_pause_s", &stop_pause_s, "s, pause between events", NonNegative());
}

bool MotionOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void ImuOptions::Visit(OptionsReader& r) {
  r.Optional("rate_hz", &rate_hz, "Hz", InRange(10, 2000));
  r.Optional("gravity_mps2", &gravity_mps2, "m/s^2 (1.62 lunar)", Positive());
  r.Optional("gyro_noise_density", &gyro_noise_density, "rad/s/sqrt(Hz)", NonNegative());
  r.Optional("gyro_bias_sigma", &gyro_bias_sigma, "rad/s, constant bias 1-sigma", NonNegative());
  r.Optional("gyro_bias_walk", &gyro_bias_walk, "rad/s^2/sqrt(Hz)", NonNegative());
  r.Optional("accel_noise_density", &accel_noise_density, "m/s^2/sqrt(Hz)", NonNegative());
  r.Optional("accel_bias_sigma", &accel_bias_sigma, "m/s^2, constant bias 1-sigma", NonNegative());
}

bool ImuOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void WheelOptions::Visit(OptionsReader& r) {
  r.Optional("rate_hz", &rate_hz, "Hz", Positive());
  r.Optional("slip_flat", &slip_flat, "slip ratio on level ground", InRightOpen(0, 0.5));
  r.Optional("soil_variation", &soil_variation, "relative spread of the soil factor", InRightOpen(0, 1));
  r.Optional("soil_wavelength_m", &soil_wavelength_m, "m, soil patch size", Positive());
  r.Optional("slip_per_rad_uphill", &slip_per_rad_uphill, "slip added per rad uphill", NonNegative());
  r.Optional("skid_per_rad_downhill", &skid_per_rad_downhill, "slip removed per rad downhill", NonNegative());
  r.Optional("sideslip_per_rad_roll", &sideslip_per_rad_roll, "side velocity / speed per rad of roll", NonNegative());
  r.Optional("distance_noise_m", &distance_noise_m, "m, 1-sigma per sample", NonNegative());
}

bool WheelOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

void TraverseOptions::Visit(OptionsReader& r) {
  r.Optional("seed", &seed, "plan randomness and sensor noise");
  r.Optional("ideal_sensors", &ideal_sensors, "true: no IMU noise/bias and no wheel slip");
  r.Child("plan", [&](OptionsReader& c) { plan.Visit(c); });
  r.Child("panorama", [&](OptionsReader& c) { panorama.Visit(c); });
  r.Child("motion", [&](OptionsReader& c) { motion.Visit(c); });
  r.Child("imu", [&](OptionsReader& c) { imu.Visit(c); });
  r.Child("wheels", [&](OptionsReader& c) { wheels.Visit(c); });
  r.Relation("wheels.rate_hz", wheels.rate_hz <= imu.rate_hz, "must not exceed imu.rate_hz");
}

bool TraverseOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

SimulatedTraverse SimulateTraverse(const Terrain& terrain, const TraverseOptions& options) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument(error);
  Simulator simulator(terrain, options);
  return simulator.Run();
}

}  // namespace vloc::sim
