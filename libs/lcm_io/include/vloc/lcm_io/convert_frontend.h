#pragma once
// Feature front end messages <-> vloc::CrossSiteFrontend's structs
// (libs/crosssite): its summary as FRONTEND_STATUS, an operator's clicks
// from MANUAL_TIE_POINTS.

#include <cstdint>
#include <vector>

#include "vloc/crosssite/frontend.h"
#include "vloc/frontend_status_t.hpp"
#include "vloc/manual_tie_points_t.hpp"

namespace vloc {

// The summary of one site pair (previous -> current) as frontend_status_t:
// status, message and the stages' names, counts and times in order.
frontend_status_t FrontendStatusToMessage(const FrontendSummary& summary, int64_t utime, int previous_site_id,
                                          int current_site_id);

// The clicks of a manual_tie_points_t; throws std::invalid_argument (one
// line naming the click) on a click that is not a pixel (negative or not finite).
std::vector<ManualTie> ManualTiesFromMessage(const manual_tie_points_t& msg);

}  // namespace vloc
