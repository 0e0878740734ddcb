#include "vloc/mosaic/tiled_canvas.h"

#include <glog/logging.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/stitching/detail/blenders.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "vloc/common/options.h"

namespace vloc::mosaic {

void CanvasOptions::Visit(OptionsReader& r) {
  r.Optional("metres_per_pixel", &metres_per_pixel, "m/px of the mosaic; 0 = auto", NonNegative());
  r.Optional("resolution_factor", &resolution_factor, "auto: mosaic px per first-frame ground px", InRange(0.25, 32.0));
  r.Optional("tile_size", &tile_size, "px, tile side", InRange(64, 4096));
  r.Optional("max_tiles_in_memory", &max_tiles_in_memory, "full tiles held in RAM", AtLeast(16));
  r.Optional("spill_dir", &spill_dir, "folder for spilled tiles; empty = temporary");
  r.Optional("num_bands", &num_bands, "multi-band blending bands, 0 = paste", InRange(0, 10));
  r.Optional("preview_reduction", &preview_reduction, "thumbnail = 1/x of a tile", AtLeast(1));
  r.Optional("max_export_pixels", &max_export_pixels, "px, larger exports are downscaled", AtLeast(1000000));
  r.Relation("preview_reduction", preview_reduction >= 1 && tile_size % preview_reduction == 0, "must divide tile_size");
}

bool CanvasOptions::Check(std::string* error) const { return CheckOptions(*this, error); }

TiledCanvas::TiledCanvas(const CanvasOptions& options) : options_(options) {
  if (options_.spill_dir.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    std::string pattern = std::string(tmp && *tmp ? tmp : "/tmp") + "/vloc_mosaic_XXXXXX";
    std::vector<char> buf(pattern.begin(), pattern.end());
    buf.push_back('\0');
    if (mkdtemp(buf.data())) {
      spill_dir_ = buf.data();
      own_spill_dir_ = true;
    }
  } else {
    spill_dir_ = options_.spill_dir;
    std::error_code ec;
    std::filesystem::create_directories(spill_dir_, ec);
  }
}

TiledCanvas::~TiledCanvas() {
  std::error_code ec;
  for (const auto& [key, tile] : tiles_)
    if (tile.on_disk) std::filesystem::remove(SpillPath(key), ec);
  if (own_spill_dir_) std::filesystem::remove(spill_dir_, ec);
}

int64_t TiledCanvas::Key(int tx, int ty) {
  return (static_cast<int64_t>(tx) << 32) | static_cast<uint32_t>(ty);
}

std::string TiledCanvas::SpillPath(int64_t key) const {
  const int tx = static_cast<int>(key >> 32), ty = static_cast<int>(static_cast<uint32_t>(key));
  return spill_dir_ + "/tile_" + std::to_string(tx) + "_" + std::to_string(ty) + ".raw";
}

void TiledCanvas::Touch(int64_t key, Tile& tile) {
  if (tile.in_lru) lru_.erase(tile.lru);
  lru_.push_front(key);
  tile.lru = lru_.begin();
  tile.in_lru = true;
}

TiledCanvas::Tile& TiledCanvas::Load(int tx, int ty, bool create) {
  const int64_t key = Key(tx, ty);
  const int ts = options_.tile_size;
  auto it = tiles_.find(key);
  if (it == tiles_.end()) {
    Tile t;
    t.bgr = cv::Mat(ts, ts, CV_8UC3, cv::Scalar::all(0));
    t.mask = cv::Mat(ts, ts, CV_8UC1, cv::Scalar(0));
    const int th = ts / options_.preview_reduction;
    t.thumb = cv::Mat(th, th, CV_8UC3, cv::Scalar::all(0));
    t.thumb_mask = cv::Mat(th, th, CV_8UC1, cv::Scalar(0));
    it = tiles_.emplace(key, std::move(t)).first;
    ++in_memory_;
    ++stats_.tiles_total;
  } else if (it->second.bgr.empty()) {
    Tile& t = it->second;
    t.bgr.create(ts, ts, CV_8UC3);
    t.mask.create(ts, ts, CV_8UC1);
    std::ifstream in(SpillPath(key), std::ios::binary);
    in.read(reinterpret_cast<char*>(t.bgr.data), static_cast<std::streamsize>(t.bgr.total() * 3));
    in.read(reinterpret_cast<char*>(t.mask.data), static_cast<std::streamsize>(t.mask.total()));
    if (!in) {
      LOG(ERROR) << "mosaic tile " << SpillPath(key) << " could not be read back; that tile restarts empty";
      t.bgr.setTo(cv::Scalar::all(0));
      t.mask.setTo(0);
    }
    t.dirty = false;
    ++in_memory_;
    ++stats_.reloads;
  }
  Touch(key, it->second);
  stats_.peak_tiles_in_memory = std::max(stats_.peak_tiles_in_memory, in_memory_);
  return it->second;
}

void TiledCanvas::EvictIfNeeded() {
  while (in_memory_ > options_.max_tiles_in_memory && !lru_.empty()) {
    const int64_t key = lru_.back();
    lru_.pop_back();
    Tile& t = tiles_.at(key);
    t.in_lru = false;
    if (t.bgr.empty()) continue;
    if (t.dirty || !t.on_disk) {
      std::ofstream out(SpillPath(key), std::ios::binary | std::ios::trunc);
      out.write(reinterpret_cast<const char*>(t.bgr.data), static_cast<std::streamsize>(t.bgr.total() * 3));
      out.write(reinterpret_cast<const char*>(t.mask.data), static_cast<std::streamsize>(t.mask.total()));
      if (!out) {
        // Cannot spill: keep the tile (memory grows) rather than lose mosaic content.
        LOG_EVERY_N(ERROR, 100) << "mosaic: cannot write spill file " << SpillPath(key)
                                << "; keeping the tile in memory (set canvas.spill_dir to a writable folder)";
        Touch(key, t);
        return;
      }
      t.on_disk = true;
      t.dirty = false;
      ++stats_.spills;
    }
    t.bgr.release();
    t.mask.release();
    --in_memory_;
  }
}

void TiledCanvas::ReadRegion(const cv::Rect& roi, cv::Mat* bgr, cv::Mat* mask) {
  const int ts = options_.tile_size;
  *bgr = cv::Mat(roi.size(), CV_8UC3, cv::Scalar::all(0));
  *mask = cv::Mat(roi.size(), CV_8UC1, cv::Scalar(0));
  const int tx0 = static_cast<int>(std::floor(double(roi.x) / ts)), tx1 = static_cast<int>(std::floor(double(roi.br().x - 1) / ts));
  const int ty0 = static_cast<int>(std::floor(double(roi.y) / ts)), ty1 = static_cast<int>(std::floor(double(roi.br().y - 1) / ts));
  for (int ty = ty0; ty <= ty1; ++ty) {
    for (int tx = tx0; tx <= tx1; ++tx) {
      if (tiles_.find(Key(tx, ty)) == tiles_.end()) continue;
      Tile& t = Load(tx, ty, false);
      const cv::Rect tile_rect(tx * ts, ty * ts, ts, ts);
      const cv::Rect inter = tile_rect & roi;
      const cv::Rect in_tile = inter - tile_rect.tl();
      const cv::Rect in_roi = inter - roi.tl();
      t.bgr(in_tile).copyTo((*bgr)(in_roi));
      t.mask(in_tile).copyTo((*mask)(in_roi));
    }
    EvictIfNeeded();
  }
  EvictIfNeeded();
}

void TiledCanvas::WriteRegion(const cv::Rect& roi, const cv::Mat& bgr, const cv::Mat& write_mask) {
  const int ts = options_.tile_size;
  const int red = options_.preview_reduction;
  const int tx0 = static_cast<int>(std::floor(double(roi.x) / ts)), tx1 = static_cast<int>(std::floor(double(roi.br().x - 1) / ts));
  const int ty0 = static_cast<int>(std::floor(double(roi.y) / ts)), ty1 = static_cast<int>(std::floor(double(roi.br().y - 1) / ts));
  for (int ty = ty0; ty <= ty1; ++ty) {
    for (int tx = tx0; tx <= tx1; ++tx) {
      const cv::Rect tile_rect(tx * ts, ty * ts, ts, ts);
      const cv::Rect inter = tile_rect & roi;
      const cv::Rect in_roi = inter - roi.tl();
      if (cv::countNonZero(write_mask(in_roi)) == 0) continue;
      Tile& t = Load(tx, ty, true);
      const cv::Rect in_tile = inter - tile_rect.tl();
      bgr(in_roi).copyTo(t.bgr(in_tile), write_mask(in_roi));
      cv::Mat tm = t.mask(in_tile);
      cv::bitwise_or(tm, write_mask(in_roi), tm);
      t.dirty = true;
      // Thumbnail of the changed part (aligned to the reduction grid).
      cv::Rect aligned(in_tile.x / red * red, in_tile.y / red * red, 0, 0);
      aligned.width = std::min(ts, (in_tile.br().x + red - 1) / red * red) - aligned.x;
      aligned.height = std::min(ts, (in_tile.br().y + red - 1) / red * red) - aligned.y;
      const cv::Rect thumb_rect(aligned.x / red, aligned.y / red, aligned.width / red, aligned.height / red);
      cv::resize(t.bgr(aligned), t.thumb(thumb_rect), thumb_rect.size(), 0, 0, cv::INTER_AREA);
      cv::resize(t.mask(aligned), t.thumb_mask(thumb_rect), thumb_rect.size(), 0, 0, cv::INTER_NEAREST);
    }
    EvictIfNeeded();
  }
  EvictIfNeeded();
}

namespace {
cv::Rect WarpedBounds(const Similarity2& s, cv::Size size) {
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const cv::Point2d c : {cv::Point2d(0, 0), cv::Point2d(size.width, 0), cv::Point2d(0, size.height),
                              cv::Point2d(size.width, size.height)}) {
    const cv::Point2d p = s.Apply(c - cv::Point2d(0.5, 0.5));
    x0 = std::min(x0, p.x); y0 = std::min(y0, p.y); x1 = std::max(x1, p.x); y1 = std::max(y1, p.y);
  }
  const int ix0 = static_cast<int>(std::floor(x0)), iy0 = static_cast<int>(std::floor(y0));
  return cv::Rect(ix0, iy0, static_cast<int>(std::ceil(x1)) - ix0 + 1, static_cast<int>(std::ceil(y1)) - iy0 + 1);
}
}  // namespace

bool TiledCanvas::Blend(const cv::Mat& frame_in, const Similarity2& mosaic_from_frame, std::string* why) {
  if (frame_in.empty()) {
    if (why) *why = "empty frame";
    return false;
  }
  cv::Mat frame;
  if (frame_in.channels() == 1) cv::cvtColor(frame_in, frame, cv::COLOR_GRAY2BGR); else frame = frame_in;
  const int margin = options_.num_bands > 0 ? (2 << options_.num_bands) : 2;
  cv::Rect roi = WarpedBounds(mosaic_from_frame, frame.size());
  if (static_cast<double>(roi.width) * roi.height > 64e6) {
    if (why) *why = "frame would cover " + std::to_string(roi.width) + "x" + std::to_string(roi.height) +
                    " mosaic px (resolution too fine for this height?)";
    return false;
  }
  roi = cv::Rect(roi.x - margin, roi.y - margin, roi.width + 2 * margin, roi.height + 2 * margin);
  cv::Matx23d M = mosaic_from_frame.ToMatx();
  M(0, 2) -= roi.x;
  M(1, 2) -= roi.y;
  cv::Mat warped, fmask;
  cv::warpAffine(frame, warped, M, roi.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::warpAffine(cv::Mat(frame.size(), CV_8UC1, cv::Scalar(255)), fmask, M, roi.size(), cv::INTER_NEAREST,
                 cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::erode(fmask, fmask, cv::Mat(), cv::Point(-1, -1), 1);
  cv::Mat old_bgr, old_mask;
  ReadRegion(roi, &old_bgr, &old_mask);
  cv::Mat old_only;
  cv::bitwise_and(old_mask, ~fmask, old_only);
  if (options_.num_bands == 0 || cv::countNonZero(old_only) == 0) {
    WriteRegion(roi, warped, fmask);
  } else {
    cv::detail::MultiBandBlender blender(false, options_.num_bands);
    blender.prepare(cv::Rect(0, 0, roi.width, roi.height));
    cv::Mat old16, new16;
    old_bgr.convertTo(old16, CV_16SC3);
    warped.convertTo(new16, CV_16SC3);
    blender.feed(old16, old_only, cv::Point(0, 0));
    blender.feed(new16, fmask, cv::Point(0, 0));
    cv::Mat result, result_mask;
    blender.blend(result, result_mask);
    cv::Mat result8;
    result.convertTo(result8, CV_8U);
    // Only pixels near or inside the new frame change; write those back.
    cv::Mat write_mask;
    cv::dilate(fmask, write_mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * margin + 1, 2 * margin + 1)));
    cv::bitwise_and(write_mask, result_mask, write_mask);
    WriteRegion(roi, result8, write_mask);
  }
  ++stats_.blends;
  return true;
}

double TiledCanvas::Render(const Similarity2& mosaic_from_view, cv::Size size, cv::Mat* bgr, cv::Mat* mask) {
  const cv::Rect roi = WarpedBounds(mosaic_from_view, size);
  cv::Mat region, region_mask;
  ReadRegion(roi, &region, &region_mask);
  cv::Matx23d M = mosaic_from_view.ToMatx();
  M(0, 2) -= roi.x;
  M(1, 2) -= roi.y;
  cv::warpAffine(region, *bgr, M, size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
  cv::warpAffine(region_mask, *mask, M, size, cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT);
  return static_cast<double>(cv::countNonZero(*mask)) / (static_cast<double>(size.area()) + 1e-9);
}

cv::Rect TiledCanvas::Bounds() const {
  if (tiles_.empty()) return {};
  int tx0 = INT32_MAX, ty0 = INT32_MAX, tx1 = INT32_MIN, ty1 = INT32_MIN;
  for (const auto& [key, t] : tiles_) {
    const int tx = static_cast<int>(key >> 32), ty = static_cast<int>(static_cast<uint32_t>(key));
    tx0 = std::min(tx0, tx); ty0 = std::min(ty0, ty); tx1 = std::max(tx1, tx); ty1 = std::max(ty1, ty);
  }
  const int ts = options_.tile_size;
  return cv::Rect(tx0 * ts, ty0 * ts, (tx1 - tx0 + 1) * ts, (ty1 - ty0 + 1) * ts);
}

cv::Mat TiledCanvas::Preview(int max_side, double* scale, cv::Point2d* origin) const {
  const cv::Rect b = Bounds();
  if (b.empty()) return {};
  const int red = options_.preview_reduction, ts = options_.tile_size, th = ts / red;
  cv::Mat thumbs(b.height / red, b.width / red, CV_8UC3, cv::Scalar::all(0));
  for (const auto& [key, t] : tiles_) {
    const int tx = static_cast<int>(key >> 32), ty = static_cast<int>(static_cast<uint32_t>(key));
    const cv::Rect r((tx * ts - b.x) / red, (ty * ts - b.y) / red, th, th);
    t.thumb.copyTo(thumbs(r));
  }
  double s = 1.0 / red;
  cv::Mat out = thumbs;
  const int side = std::max(thumbs.cols, thumbs.rows);
  if (max_side > 0 && side > max_side) {
    const double f = static_cast<double>(max_side) / side;
    cv::resize(thumbs, out, cv::Size(), f, f, cv::INTER_AREA);
    s *= static_cast<double>(out.cols) / thumbs.cols;
  }
  if (scale) *scale = s;
  if (origin) *origin = cv::Point2d(b.x, b.y);
  return out;
}

bool TiledCanvas::Export(cv::Mat* bgra, double* scale, cv::Point2d* origin, std::string* why) {
  const cv::Rect b = Bounds();
  if (b.empty()) {
    if (why) *why = "the mosaic is empty (no frame placed yet)";
    return false;
  }
  const double pixels = static_cast<double>(b.width) * b.height;
  const double f = pixels > options_.max_export_pixels ? std::sqrt(options_.max_export_pixels / pixels) : 1.0;
  const int ts = options_.tile_size;
  const int out_w = std::max(1, static_cast<int>(std::round(b.width * f)));
  const int out_h = std::max(1, static_cast<int>(std::round(b.height * f)));
  *bgra = cv::Mat(out_h, out_w, CV_8UC4, cv::Scalar::all(0));
  std::vector<int64_t> keys;
  for (const auto& kv : tiles_) keys.push_back(kv.first);
  for (int64_t key : keys) {
    const int tx = static_cast<int>(key >> 32), ty = static_cast<int>(static_cast<uint32_t>(key));
    Tile& t = Load(tx, ty, false);
    cv::Mat tile4;
    std::vector<cv::Mat> ch;
    cv::split(t.bgr, ch);
    ch.push_back(t.mask);
    cv::merge(ch, tile4);
    const int x0 = static_cast<int>(std::round((tx * ts - b.x) * f)), y0 = static_cast<int>(std::round((ty * ts - b.y) * f));
    const int x1 = std::min(out_w, static_cast<int>(std::round(((tx + 1) * ts - b.x) * f)));
    const int y1 = std::min(out_h, static_cast<int>(std::round(((ty + 1) * ts - b.y) * f)));
    if (x1 <= x0 || y1 <= y0) continue;
    if (f < 1.0) {
      cv::resize(tile4, (*bgra)(cv::Rect(x0, y0, x1 - x0, y1 - y0)), cv::Size(x1 - x0, y1 - y0), 0, 0, cv::INTER_AREA);
    } else {
      tile4.copyTo((*bgra)(cv::Rect(x0, y0, ts, ts)));
    }
    EvictIfNeeded();
  }
  // Crop to the painted pixels (tiles are only partly covered at the edges).
  std::vector<cv::Mat> channels;
  cv::split(*bgra, channels);
  const cv::Rect painted = cv::boundingRect(channels[3]);
  const double s = static_cast<double>(out_w) / b.width;
  if (!painted.empty()) *bgra = (*bgra)(painted).clone();
  if (scale) *scale = s;
  if (origin) *origin = cv::Point2d(b.x + painted.x / s, b.y + painted.y / s);
  return true;
}

CanvasStats TiledCanvas::stats() const {
  CanvasStats s = stats_;
  s.tiles_in_memory = in_memory_;
  const double ts = options_.tile_size, th = ts / options_.preview_reduction;
  s.bytes_in_memory = in_memory_ * ts * ts * 4.0 + tiles_.size() * th * th * 4.0;
  return s;
}

}  // namespace vloc::mosaic
