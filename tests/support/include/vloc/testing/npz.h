#pragma once
// Reads one float32 C-order 2-D array from a NumPy .npz archive (zip by
// libzip, then the .npy header): how scikit-image ships ground truth.

#include <opencv2/core.hpp>
#include <string>

namespace vloc::testing {

// The array `member` (e.g. "arr_0.npy") of `npz_path` as CV_32FC1; empty
// with `error` set when the file, the member or its format is not as expected.
cv::Mat ReadNpzFloat2d(const std::string& npz_path, const std::string& member, std::string* error);

}  // namespace vloc::testing
