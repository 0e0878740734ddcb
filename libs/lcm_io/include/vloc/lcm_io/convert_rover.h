#pragma once
// Rover messages <-> rover data model (vloc/common/rover_data.h). Every
// FromMessage throws std::invalid_argument with one line naming the problem.

#include "vloc/common/rover_data.h"
#include "vloc/imu_t.hpp"
#include "vloc/lcm_io/convert.h"
#include "vloc/site_event_t.hpp"
#include "vloc/stereo_image_t.hpp"
#include "vloc/tie_points_t.hpp"
#include "vloc/wheel_odometry_t.hpp"

namespace vloc {

stereo_image_t StereoPairToMessage(const StereoPair& pair, ImageEncoding encoding);
StereoPair StereoPairFromMessage(const stereo_image_t& msg);  // images as CV_8UC1
// Throws (one line) unless site_id >= 0, num_pairs in [1, kMaxPairsPerSite] and pair_index in [0, num_pairs):
// what StereoPairFromMessage checks first, for a reader that takes no images out (the console).
void CheckStereoPairIndex(const stereo_image_t& msg);

imu_t ImuToMessage(const ImuSample& sample);
ImuSample ImuFromMessage(const imu_t& msg);

wheel_odometry_t WheelOdometryToMessage(const WheelOdometrySample& sample);
WheelOdometrySample WheelOdometryFromMessage(const wheel_odometry_t& msg);

site_event_t SiteEventToMessage(const SiteEvent& event);
SiteEvent SiteEventFromMessage(const site_event_t& msg);

tie_points_t TiePointsToMessage(const TiePointSet& set);
TiePointSet TiePointsFromMessage(const tie_points_t& msg);

}  // namespace vloc
