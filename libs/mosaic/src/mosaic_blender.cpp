#include "vloc/mosaic/mosaic_blender.h"

#include <glog/logging.h>

#include <chrono>

namespace vloc::mosaic {

MosaicBlender::MosaicBlender(const CanvasOptions& options, bool async, int queue)
    : options_(options), async_(async), queue_(queue) {
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
    job_cv_.wait(lock, [this] { return stop_worker_ || !jobs_.empty(); });
    if (stop_worker_ && jobs_.empty()) return;
    BlendJob job = std::move(jobs_.front());
    jobs_.pop_front();
    worker_busy_ = true;
    lock.unlock();
    job_cv_.notify_all();  // a place in the queue
    std::string why;
    bool ok = false;
    const auto t0 = std::chrono::steady_clock::now();
    {
      std::lock_guard<std::mutex> canvas_lock(canvas_mutex_);
      ok = canvas_->Blend(job.frame, job.mosaic_from_frame, &why);
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!ok) {
      LOG_EVERY_N(WARNING, 50) << "mosaic: frame not blended: " << why;
    }
    lock.lock();
    worker_busy_ = false;
    seconds_ += seconds;
    if (ok) ++blends_;
    job_cv_.notify_all();
  }
}

void MosaicBlender::Flush() const {
  if (!worker_.joinable()) return;
  std::unique_lock<std::mutex> lock(job_mutex_);
  job_cv_.wait(lock, [this] { return jobs_.empty() && !worker_busy_; });
}

BlendResult MosaicBlender::Blend(const cv::Mat& frame, const Similarity2& S) {
  BlendResult result;
  if (!canvas_) return result;
  if (async_) {
    {
      std::unique_lock<std::mutex> lock(job_mutex_);
      if (queue_ == 0) {
        if (!jobs_.empty()) ++dropped_;  // the worker fell behind: the newer frame replaces the queued one
        jobs_.clear();
      } else {
        job_cv_.wait(lock, [this] { return static_cast<int>(jobs_.size()) < queue_; });
      }
      jobs_.push_back(BlendJob{frame.clone(), S});
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
  seconds_ += result.seconds;
  return result;
}

double MosaicBlender::Render(const Similarity2& mosaic_from_view, cv::Size size, cv::Mat* bgr, cv::Mat* mask) const {
  if (!canvas_) return 0;
  if (queue_ > 0) Flush();
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

double MosaicBlender::seconds() const {
  std::lock_guard<std::mutex> lock(job_mutex_);
  return seconds_;
}

int MosaicBlender::blends() const {
  std::lock_guard<std::mutex> lock(job_mutex_);
  return static_cast<int>(blends_);
}

}  // namespace vloc::mosaic
