// vloc_texture_stats: texture statistics of grey images, one row each, to
// compare simulated Navcam images with real ones (vloc::ComputeTextureStats).
//   vloc_texture_stats IMAGE...
// Columns: mean and standard deviation (DN); SIFT keypoints per 10,000 px in
// the top / middle / bottom third; gradient magnitude (DN/px) at the 50th,
// 90th and 99th percentile; median local contrast (DN, 15 x 15 px); slope of
// the lower half's power spectrum (log-log, 0.02-0.25 cycles/px).
#include <iostream>
#include <opencv2/imgcodecs.hpp>

#include "vloc/common/logging.h"
#include "vloc/features/texture_stats.h"

int main(int argc, char** argv) {
  vloc::InitLogging(argv[0]);
  if (argc < 2 || std::string(argv[1]) == "--help") {
    std::cerr << "usage: vloc_texture_stats IMAGE...\n";
    return 1;
  }
  std::cout << "  mean    std |  feat/10kpx top mid bottom | grad p50 p90 p99 | local | slope | image\n";
  int failures = 0;
  for (int i = 1; i < argc; ++i) {
    const cv::Mat gray = cv::imread(argv[i], cv::IMREAD_GRAYSCALE);
    if (gray.empty() || gray.rows < 64 || gray.cols < 64) {
      std::cerr << "vloc_texture_stats: " << argv[i] << ": not an image of at least 64 x 64 px; skipped\n";
      ++failures;
      continue;
    }
    std::cout << vloc::TextureStatsRow(vloc::ComputeTextureStats(gray)) << " | " << argv[i] << "\n";
  }
  return failures == 0 ? 0 : 2;
}
