#pragma once
// The LCM tunnel's report (libs/tunnel) -> TUNNEL_STATUS.

#include <cstdint>
#include <string>

#include "vloc/tunnel/tunnel_core.h"
#include "vloc/tunnel_status_t.hpp"

namespace vloc {

// The report as tunnel_status_t: the tunnel's name and endpoint, link state,
// rates (bandwidth_cap_mbps as bytes/s), counts and one entry per channel.
tunnel_status_t TunnelStatusToMessage(const tunnel::TunnelReport& report, const tunnel::TunnelOptions& options,
                                      const std::string& endpoint, int64_t utime);

}  // namespace vloc
