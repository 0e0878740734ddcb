#include "vloc/features/wallis.h"

#include <opencv2/imgproc.hpp>

#include "vloc/common/options.h"

namespace vloc {

void WallisOptions::Visit(OptionsReader& r) {
  r.Optional("window", &window, "px, side of the local statistics window", Odd() && AtLeast(3));
  r.Optional("target_mean", &target_mean, "grey level, mean after filtering (m_f)");
  r.Optional("target_std", &target_std, "grey level, std after filtering (s_f)", Positive());
  r.Optional("contrast", &contrast, "c, contrast expansion constant", InLeftOpen(0, 1));
  r.Optional("brightness", &brightness, "b, brightness forcing constant", InRange(0, 1));
  r.Optional("min_std", &min_std, "grey level, floor of the local std", Positive());
}

bool WallisOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

ImageStats ComputeImageStats(const cv::Mat& image, const cv::Mat& mask) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(image, mean, stddev, mask);
  return {mean[0], stddev[0]};
}

cv::Mat WallisFilter(const cv::Mat& gray, const WallisOptions& o) {
  CV_Assert(gray.type() == CV_8UC1);
  cv::Mat g;
  gray.convertTo(g, CV_32F);
  cv::Mat m, m2;
  const cv::Size win(o.window, o.window);
  cv::boxFilter(g, m, CV_32F, win, cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  cv::boxFilter(g.mul(g), m2, CV_32F, win, cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  cv::Mat out(gray.size(), CV_8UC1);
  const float c = static_cast<float>(o.contrast), b = static_cast<float>(o.brightness);
  const float mf = static_cast<float>(o.target_mean), sf = static_cast<float>(o.target_std);
  const float min_std = static_cast<float>(o.min_std);
  for (int y = 0; y < g.rows; ++y) {
    const float* gp = g.ptr<float>(y);
    const float* mp = m.ptr<float>(y);
    const float* m2p = m2.ptr<float>(y);
    uint8_t* op = out.ptr<uint8_t>(y);
    for (int x = 0; x < g.cols; ++x) {
      const float mg = mp[x];
      const float sg = std::max(std::sqrt(std::max(m2p[x] - mg * mg, 0.f)), min_std);
      const float r1 = c * sf / (c * sg + (1.f - c) * sf);
      const float r0 = b * mf + (1.f - b - r1) * mg;
      op[x] = cv::saturate_cast<uint8_t>(gp[x] * r1 + r0);
    }
  }
  return out;
}

}  // namespace vloc
