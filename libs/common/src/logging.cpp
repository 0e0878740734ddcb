#include "vloc/common/logging.h"

#include <opencv2/core/utils/logger.hpp>

namespace vloc {

void InitLogging(const char* argv0) {
  FLAGS_logtostderr = true;
  FLAGS_colorlogtostderr = false;
  FLAGS_minloglevel = 0;
  google::InitGoogleLogging(argv0);
  // OpenCV's own warnings (e.g. two lines per image it cannot open) would
  // precede vloc's one line naming the problem; its errors still show.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
}

}  // namespace vloc
