#include "vloc/lcm_io/convert_frontend.h"

#include <stdexcept>
#include <string>

namespace vloc {

frontend_status_t FrontendStatusToMessage(const FrontendSummary& s, int64_t utime, int previous_site_id,
                                          int current_site_id) {
  frontend_status_t m;
  m.utime = utime;
  m.previous_site_id = previous_site_id;
  m.current_site_id = current_site_id;
  switch (s.status) {
    case FrontendStatus::kOk: m.status = frontend_status_t::STATUS_OK; break;
    case FrontendStatus::kNoOverlap: m.status = frontend_status_t::STATUS_NO_OVERLAP; break;
    case FrontendStatus::kLowTexture: m.status = frontend_status_t::STATUS_LOW_TEXTURE; break;
    case FrontendStatus::kTooFewPoints: m.status = frontend_status_t::STATUS_TOO_FEW_POINTS; break;
    case FrontendStatus::kMissingInput: m.status = frontend_status_t::STATUS_MISSING_INPUT; break;
    case FrontendStatus::kError: m.status = frontend_status_t::STATUS_ERROR; break;
  }
  m.message = s.message;
  m.num_stages = static_cast<int32_t>(s.stages.size());
  for (const auto& st : s.stages) {
    m.stage_names.push_back(st.name);
    m.stage_counts.push_back(st.count);
    m.stage_seconds.push_back(st.seconds);
  }
  m.total_seconds = s.total_seconds;
  return m;
}

std::vector<ManualTie> ManualTiesFromMessage(const manual_tie_points_t& m) {
  std::vector<ManualTie> ties;
  for (int i = 0; i < m.num_points; ++i) {
    ManualTie t{m.previous_pair[i], {m.previous_u[i], m.previous_v[i]}, m.current_pair[i],
                {m.current_u[i], m.current_v[i]}};
    if (!(t.previous_px.allFinite() && t.current_px.allFinite() && t.previous_px.minCoeff() >= 0 &&
          t.current_px.minCoeff() >= 0))
      throw std::invalid_argument("manual tie point " + std::to_string(i) + " is not a pixel position");
    ties.push_back(t);
  }
  return ties;
}

}  // namespace vloc
