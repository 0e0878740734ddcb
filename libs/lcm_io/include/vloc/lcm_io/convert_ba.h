#pragma once
// Cross-site bundle adjustment result (libs/ba) -> SITE_POSE_VISUAL.

#include <cstdint>

#include "vloc/ba/crosssite_ba.h"
#include "vloc/localization_t.hpp"

namespace vloc {

// The summary of one site pair as localization_t: world_from_current as
// `pose` (world -> body), previous_from_current as `relative_pose`
// (site_<previous> -> site_<current>), the counts and residuals; a condition
// number that is not finite is sent as 1e300 (the schema refuses infinity).
localization_t LocalizationToMessage(const CrossSiteBaSummary& summary, int64_t utime);

}  // namespace vloc
