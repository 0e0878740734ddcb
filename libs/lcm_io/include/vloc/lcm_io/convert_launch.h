#pragma once
// The launcher's state (libs/launch) <-> PROCMAN_STATUS / PROCMAN_PEERS.

#include <cstdint>
#include <string>
#include <vector>

#include "vloc/launch/peer_tracker.h"
#include "vloc/launch/supervisor.h"
#include "vloc/procman_peers_t.hpp"
#include "vloc/procman_status_t.hpp"

namespace vloc {

// One launcher's processes as procman_status_t (host or role name, the
// launcher's pid, the report's time in us).
procman_status_t ProcmanStatusToMessage(const std::string& host, int32_t launcher_pid, int64_t utime,
                                        const std::vector<ProcessStatus>& procs);
// Another launcher's status as the peer tracker takes it (a process has
// exited when its last exit code is not 0 or it is EXITED).
PeerReport PeerReportFromMessage(const procman_status_t& msg);
// The launchers this one hears, as procman_peers_t.
procman_peers_t ProcmanPeersToMessage(const std::string& host, int32_t launcher_pid, int64_t utime,
                                      double lost_after_s, const std::vector<PeerView>& peers);

}  // namespace vloc
