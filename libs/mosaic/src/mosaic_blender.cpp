#include "vloc/mosaic/mosaic_blender.h"

#include <glog/logging.h>

#include <chrono>

namespace vloc::mosaic {

MosaicBlender::MosaicBlender(const CanvasOptions& options, bool async) : options_(options), async_(async) {
  if (async_) worker_ = std::thread([this] { WorkerLoop(); });
}

MosaicBlender::~MosaicBlender() {
  if (!worker_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(job_mutex_);
    stop_worker_ = true;
  }
  job_cv_.notify_all();
  worker_.join();
}

void MosaicBlender::Start() { canvas_ = std::make_unique<TiledCanvas>(options_); }

void MosaicBlender::WorkerLoop() {
  std::unique_lock<std::mutex> lock(job_mutex_);
  while (true) {
    job_cv_.wait(lock, [this] { return stop_worker_ || job_.has_value(); });
    if (stop_worker_ && !job_) return;
    BlendJob job = std::move(*job_);
    job_.reset();
    worker_busy_ = true;
    lock.unlock();
    std::string why;
    bool ok = false;
    {
      std::lock_guard<std::mutex> canvas_lock(canvas_mutex_);
      ok = canvas_->Blend(job.frame, job.mosaic_from_frame, &why);
    }
    if (!ok) {
      LOG_EVERY_N(WARNING, 50) << "mosaic: frame not blended: " << why;
    }
    lock.lock();
    worker_busy_ = false;
    if (ok) ++blends_;
    job_cv_.notify_all();
  }
}

void MosaicBlender::Flush() {
  if (!worker_.joinable()) return;
  std::unique_lock<std::mutex> lock(job_mutex_);
  job_cv_.wait(lock, [this] { return !job_.has_value() && !worker_busy_; });
}

BlendResult MosaicBlender::Blend(const cv::Mat& frame, const Similarity2& S) {
  BlendResult result;
  if (!canvas_) return result;
  if (async_) {
    {
      std::lock_guard<std::mutex> lock(job_mutex_);
      if (job_) ++dropped_;  // the worker fell behind: the newer frame replaces the queued one
      job_ = BlendJob{frame.clone(), S};
    }
    job_cv_.notify_all();
    result.done = true;
    return result;
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::string why;
  {
    std::lock_guard<std::mutex> lock(canvas_mutex_);
    result.done = canvas_->Blend(frame, S, &why);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!result.done) {
    LOG_EVERY_N(WARNING, 50) << "mosaic: frame not blended: " << why;
    return result;
  }
  std::lock_guard<std::mutex> lock(job_mutex_);
  ++blends_;
  return result;
}

double MosaicBlender::Render(const Similarity2& mosaic_from_view, cv::Size size, cv::Mat* bgr, cv::Mat* mask) const {
  if (!canvas_) return 0;
  std::lock_guard<std::mutex> lock(canvas_mutex_);
  return canvas_->Render(mosaic_from_view, size, bgr, mask);
}

cv::Mat MosaicBlender::Preview(int max_side, double* scale, cv::Point2d* origin) const {
  if (!canvas_) return {};
  std::lock_guard<std::mutex> lock(canvas_mutex_);
  return canvas_->Preview(max_side, scale, origin);
}

bool MosaicBlender::Export(cv::Mat* bgra, double* scale, cv::Point2d* origin, std::string* error) {
  if (!canvas_) {
    if (error) *error = "no mosaic yet (not calibrated or no frame tracked)";
    return false;
  }
  Flush();
  std::lock_guard<std::mutex> lock(canvas_mutex_);
  return canvas_->Export(bgra, scale, origin, error);
}

CanvasStats MosaicBlender::stats() const {
  if (!canvas_) return {};
  std::lock_guard<std::mutex> lock(canvas_mutex_);
  return canvas_->stats();
}

int MosaicBlender::blends() const {
  std::lock_guard<std::mutex> lock(job_mutex_);
  return static_cast<int>(blends_);
}

}  // namespace vloc::mosaic
