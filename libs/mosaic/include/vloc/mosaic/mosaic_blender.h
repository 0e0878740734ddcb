#pragma once
// The mosaic canvas behind a mutex, blended now or on a worker thread.
//
//   MosaicBlender blender(canvas_options, /*async=*/true);
//   blender.Start();                                  // creates the canvas (first frame)
//   BlendResult r = blender.Blend(frame, mosaic_from_frame);
//   blender.Render(mosaic_from_view, size, &view, &mask);   // registration against the mosaic
//   blender.Export(&bgra, &scale, &origin, &error);         // waits for queued blends first
//
// Asynchronous, queue 0 (video): one job is queued; a frame due while the
// worker is busy replaces the queued one (real time: tracking never waits).
// Asynchronous, queue n > 0 (stills): up to n frames wait, none is dropped (a
// frame due when n wait waits for a place), and Render waits until every
// queued frame is blended: the same mosaic as blending in place.

#include <opencv2/core.hpp>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "vloc/mosaic/geometry.h"
#include "vloc/mosaic/tiled_canvas.h"

namespace vloc::mosaic {

struct BlendResult {
  bool done = false;      // blended (synchronous) or queued (asynchronous)
  double seconds = 0;     // s, blending (0 when queued)
};

class MosaicBlender {
 public:
  MosaicBlender(const CanvasOptions& options, bool async, int queue = 0);
  ~MosaicBlender();
  MosaicBlender(const MosaicBlender&) = delete;
  MosaicBlender& operator=(const MosaicBlender&) = delete;

  // Creates the canvas; before it, Blend and Render do nothing.
  void Start();
  bool started() const { return canvas_ != nullptr; }

  BlendResult Blend(const cv::Mat& frame, const Similarity2& mosaic_from_frame);
  // The canvas as seen by a virtual frame (TiledCanvas::Render): the painted fraction. With a queue, after
  // the queued blends.
  double Render(const Similarity2& mosaic_from_view, cv::Size size, cv::Mat* bgr, cv::Mat* mask) const;
  cv::Mat Preview(int max_side, double* scale, cv::Point2d* origin) const;
  // After the queued blends, the whole canvas as BGRA (TiledCanvas::Export).
  bool Export(cv::Mat* bgra, double* scale, cv::Point2d* origin, std::string* error);
  // Waits until the worker has blended what is queued.
  void Flush() const;
  CanvasStats stats() const;
  // Frames blended so far (asynchronous: by the worker), and the seconds spent blending them.
  int blends() const;
  double seconds() const;

 private:
  struct BlendJob {
    cv::Mat frame;
    Similarity2 mosaic_from_frame;
  };
  void WorkerLoop();

  CanvasOptions options_;
  bool async_ = false;
  int queue_ = 0;
  std::unique_ptr<TiledCanvas> canvas_;
  mutable std::mutex canvas_mutex_;     // guards canvas_ content
  mutable std::mutex job_mutex_;
  mutable std::condition_variable job_cv_;
  std::deque<BlendJob> jobs_;
  bool worker_busy_ = false, stop_worker_ = false;
  int64_t blends_ = 0, dropped_ = 0;    // guarded by job_mutex_
  double seconds_ = 0;                  // guarded by job_mutex_
  std::thread worker_;
};

}  // namespace vloc::mosaic
