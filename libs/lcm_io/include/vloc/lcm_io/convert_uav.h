#pragma once
// UAV messages <-> the mosaicker's structs (libs/mosaic): a frame's state
// as UAV_STATE, a GPS fix from UAV_GPS.

#include "vloc/mosaic/uav_mosaicker.h"
#include "vloc/uav_gps_t.hpp"
#include "vloc/uav_state_t.hpp"

namespace vloc {

uav_state_t StateToMessage(const mosaic::FrameState& state);
// A fix is valid unless the message says FIX_NONE or its latitude or
// longitude is not finite; every other field is copied as it is.
mosaic::GpsFix GpsFromMessage(const uav_gps_t& msg);

}  // namespace vloc
