// Row LSM of many pixels at once (internal::RowLeastSquaresMatchBatch, AVX2
// lanes) against vloc::RowLeastSquaresMatch one pixel at a time: the same
// accept / reject and the same disparity, sigma, correlation and iteration
// count, bit for bit, on a noisy slanted plane with starts up to 1.5 px off
// (some rejected for moving too far, some for leaving the image).
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "row_lsm.h"
#include "test_images.h"
#include "vloc/features/dense_stereo.h"

namespace vloc {
namespace {

bool Same(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void ExpectBatchEqualsScalar(const DenseStereoOptions& o, int* accepted_count, int* tested) {
  const testing::PlanePair p = testing::RenderPlane(160, 90, 12.0, 0.04, 0.02, 3.0, 7);
  cv::Mat L;
  p.left.convertTo(L, CV_32F);
  const cv::Mat R = PrepareRowLsmTarget(p.right, o);
  cv::RNG rng(3);
  std::vector<internal::RowLsmTask> tasks;
  for (int y = 0; y < L.rows; y += 3)
    for (int x = 0; x < L.cols; x += 2) {
      internal::RowLsmTask t;
      t.x = x, t.y = y;
      t.initial_disparity = 12.0 + 0.04 * x + 0.02 * y + rng.uniform(-1.5, 1.5);
      tasks.push_back(t);
    }
  std::vector<RowLsmResult> results(tasks.size());
  std::vector<unsigned char> accepted(tasks.size());
  internal::RowLeastSquaresMatchBatch(L, R, tasks.data(), static_cast<int>(tasks.size()), o, results.data(),
                                      accepted.data());
  for (size_t k = 0; k < tasks.size(); ++k) {
    RowLsmResult one;
    const bool ok = RowLeastSquaresMatch(L, R, tasks[k].x, tasks[k].y, tasks[k].initial_disparity, o, &one);
    ASSERT_EQ(ok, accepted[k] != 0) << "pixel " << tasks[k].x << ", " << tasks[k].y;
    EXPECT_TRUE(Same(one.disparity, results[k].disparity) && Same(one.sigma_px, results[k].sigma_px) &&
                Same(one.correlation, results[k].correlation) && one.iterations == results[k].iterations)
        << "pixel " << tasks[k].x << ", " << tasks[k].y << ": " << one.disparity << " vs " << results[k].disparity;
    *accepted_count += ok;
  }
  *tested = static_cast<int>(tasks.size());
}

// Both builds of the lanes' kernel where the CPU has AVX-512VL.
class RowLsmBatch : public ::testing::TestWithParam<bool> {
 protected:
  void SetUp() override { internal::AllowRowLsmAvx512(GetParam()); }
  void TearDown() override { internal::AllowRowLsmAvx512(true); }
};

TEST_P(RowLsmBatch, SameResultsAsOnePixelAtATime) {
  if (!internal::RowLsmBatchVectorised(DenseStereoOptions())) std::cout << "no AVX2: the batch loops over one pixel\n";
  if (GetParam() && !internal::RowLsmBatchUsesAvx512(DenseStereoOptions())) std::cout << "no AVX-512VL: AVX2 build\n";
  EXPECT_FALSE(!GetParam() && internal::RowLsmBatchUsesAvx512(DenseStereoOptions()));
  struct Case {
    bool bspline;
    int half_width, half_height, max_iterations;
  };
  for (const Case c : {Case{true, 5, 5, 10}, Case{true, 7, 7, 10}, Case{true, 3, 3, 10}, Case{false, 5, 5, 10},
                       Case{true, 6, 0, 10}, Case{true, 5, 2, 3}}) {
    SCOPED_TRACE(::testing::Message() << "bspline " << c.bspline << ", window " << c.half_width << " x "
                                      << c.half_height << ", iterations " << c.max_iterations);
    DenseStereoOptions o;
    o.lsm_bspline = c.bspline;
    o.lsm_half_window = c.half_width;
    o.lsm_half_height = c.half_height;
    o.lsm_max_iterations = c.max_iterations;
    int accepted = 0, tested = 0;
    ExpectBatchEqualsScalar(o, &accepted, &tested);
    // Both outcomes exercised.
    EXPECT_GT(accepted, tested / 50);
    EXPECT_LT(accepted, tested);
  }
}

INSTANTIATE_TEST_SUITE_P(KernelBuilds, RowLsmBatch, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) { return info.param ? "Avx512" : "Avx2"; });

}  // namespace
}  // namespace vloc
