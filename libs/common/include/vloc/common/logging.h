#pragma once
// glog set-up shared by every vloc executable.

#include <glog/logging.h>

namespace vloc {

// Logs to stderr (the launcher captures it), with colour off and every
// severity shown. Call once at the top of main().
void InitLogging(const char* argv0);

}  // namespace vloc
