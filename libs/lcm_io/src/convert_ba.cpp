#include "vloc/lcm_io/convert_ba.h"

#include <cmath>
#include <string>

#include "vloc/lcm_io/convert.h"

namespace vloc {

localization_t LocalizationToMessage(const CrossSiteBaSummary& s, int64_t utime) {
  localization_t msg;
  msg.utime = utime;
  msg.site_id = s.current_site_id;
  msg.reference_site_id = s.previous_site_id;
  msg.status = static_cast<int8_t>(s.status);
  msg.message = s.message;
  msg.pose = PoseToMessage(s.world_from_current, "world", "body");
  msg.relative_pose = PoseToMessage(s.previous_from_current, "site_" + std::to_string(s.previous_site_id),
                                    "site_" + std::to_string(s.current_site_id));
  msg.num_tie_points_used = s.num_tie_points_used;
  msg.num_tie_points_rejected = s.num_tie_points_rejected;
  msg.num_observations = s.num_observations;
  msg.initial_rms_px = s.initial_rms_px;
  msg.final_rms_px = s.final_rms_px;
  msg.iterations = s.iterations;
  msg.solve_seconds = s.solve_seconds;
  msg.condition_number = std::isfinite(s.condition_number) ? s.condition_number : 1e300;
  return msg;
}

}  // namespace vloc
