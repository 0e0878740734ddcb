#include "vloc/common/logging.h"

namespace vloc {

void InitLogging(const char* argv0) {
  FLAGS_logtostderr = true;
  FLAGS_colorlogtostderr = false;
  FLAGS_minloglevel = 0;
  google::InitGoogleLogging(argv0);
}

}  // namespace vloc
