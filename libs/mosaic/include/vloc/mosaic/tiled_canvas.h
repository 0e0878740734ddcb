#pragma once
// The mosaic canvas: fixed-size tiles at one fixed ground resolution, created
// as frames land on them. Memory stays bounded however long the flight: at
// most `max_tiles_in_memory` full-resolution tiles are held, the least
// recently used are spilled to disk (raw files) and reloaded on demand; every
// tile also keeps a small thumbnail for the preview. Frames are blended in
// with multi-band blending (cv::detail::MultiBandBlender) over the tiles they
// touch only.

#include <opencv2/core.hpp>
#include <cstdint>
#include <list>
#include <map>
#include <string>
#include <utility>

#include "vloc/mosaic/geometry.h"

namespace vloc {
class OptionsReader;
}

namespace vloc::mosaic {

struct CanvasOptions {
  double metres_per_pixel = 0.0;     // m/px of the mosaic; 0 = auto: resolution_factor x ground px of the first frame
  double resolution_factor = 2.0;    // auto resolution: one mosaic px = this many first-frame ground px
  int tile_size = 512;               // px, side of a square tile
  int max_tiles_in_memory = 48;      // full-resolution tiles held in RAM (>= 16); older ones spill to disk
  std::string spill_dir;             // folder for spilled tiles; empty = a new folder under $TMPDIR or /tmp
  int num_bands = 4;                 // multi-band blending bands (0 = paste without blending)
  int preview_reduction = 8;         // tile thumbnails are 1/x of the tile side
  int64_t max_export_pixels = 300000000;  // px, a larger export is downscaled to fit

  void Visit(OptionsReader& reader);
  bool Check(std::string* error) const;
};

struct CanvasStats {
  int tiles_total = 0;
  int tiles_in_memory = 0;
  int peak_tiles_in_memory = 0;
  int64_t spills = 0;                // tiles written out to disk
  int64_t reloads = 0;               // tiles read back
  int64_t blends = 0;                // frames blended
  double bytes_in_memory = 0;        // full tiles + thumbnails
};

class TiledCanvas {
 public:
  explicit TiledCanvas(const CanvasOptions& options);
  ~TiledCanvas();
  TiledCanvas(const TiledCanvas&) = delete;
  TiledCanvas& operator=(const TiledCanvas&) = delete;

  // Blends `frame` (BGR or gray) into the canvas at mosaic_from_frame
  // (frame px -> mosaic px). False with a reason when it cannot.
  bool Blend(const cv::Mat& frame, const Similarity2& mosaic_from_frame, std::string* why = nullptr);

  // Renders what the canvas holds as seen by a virtual frame of `size`
  // placed at mosaic_from_view. Returns the painted fraction of the view.
  double Render(const Similarity2& mosaic_from_view, cv::Size size, cv::Mat* bgr, cv::Mat* mask);

  // Painted bounds in mosaic px (tile granular); empty when nothing painted.
  cv::Rect Bounds() const;
  // The whole canvas from thumbnails, scaled to fit max_side. *scale =
  // preview px per mosaic px, *origin = mosaic px of the preview's (0,0).
  cv::Mat Preview(int max_side, double* scale = nullptr, cv::Point2d* origin = nullptr) const;
  // The whole canvas at full resolution (or downscaled to max_export_pixels)
  // as BGRA (alpha = painted). *scale, *origin as for Preview.
  bool Export(cv::Mat* bgra, double* scale, cv::Point2d* origin, std::string* why);

  CanvasStats stats() const;
  const CanvasOptions& options() const { return options_; }

 private:
  struct Tile {
    cv::Mat bgr, mask;            // full resolution, empty when spilled
    cv::Mat thumb, thumb_mask;    // always present
    bool on_disk = false;         // a spill file holds the (last spilled) content
    bool dirty = true;            // memory content differs from the spill file
    std::list<int64_t>::iterator lru;
    bool in_lru = false;
  };
  static int64_t Key(int tx, int ty);
  Tile& Load(int tx, int ty, bool create);
  void Touch(int64_t key, Tile& tile);
  void EvictIfNeeded();
  std::string SpillPath(int64_t key) const;
  void ReadRegion(const cv::Rect& roi, cv::Mat* bgr, cv::Mat* mask);
  void WriteRegion(const cv::Rect& roi, const cv::Mat& bgr, const cv::Mat& write_mask);

  CanvasOptions options_;
  std::string spill_dir_;
  bool own_spill_dir_ = false;
  std::map<int64_t, Tile> tiles_;
  std::list<int64_t> lru_;        // front = most recent
  int in_memory_ = 0;
  CanvasStats stats_;
};

}  // namespace vloc::mosaic
